//! `autopilot batch merge`: joins shards of a campaign, flown anywhere, into the CSV and manifest
//! that the campaign flown whole on one machine writes: the same rows, byte for byte, in run
//! order. Refuses shards of two campaigns or two builds, a CSV that is not what its manifest
//! says, and a run found twice or not at all, naming them.

use super::CSV_HEADER;
use super::manifest::{self, Manifest};
use super::shard::Shard;
use super::summary::BatchSummary;
use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A shard as read: its manifest, where that was, and its rows.
struct ShardFile {
    manifest: Manifest,
    path: PathBuf,
    rows: Vec<csv::StringRecord>,
}

/// A manifest to read, and whether it was found in a directory (where a merged campaign's
/// manifest is passed over rather than taken as a shard).
struct Named {
    path: PathBuf,
    in_directory: bool,
}

/// The manifests named by `inputs`, each once: a manifest, a CSV (its manifest beside it), or a
/// directory (every manifest in it but `output`'s). A CSV without its manifest is a shard that
/// did not finish: refused, by name.
fn manifests(inputs: &[PathBuf], output: Option<&Path>) -> Result<Vec<Named>> {
    let own = output.map(Manifest::path_of);
    let unfinished = |csv: &Path| {
        anyhow::anyhow!(
            "{}: no manifest {} beside it (a shard writes its manifest when it ends: this one \
             did not finish)",
            csv.display(),
            Manifest::path_of(csv).display()
        )
    };
    let mut found: Vec<Named> = Vec::new();
    let mut add = |path: PathBuf, in_directory: bool| {
        let real = path.canonicalize().unwrap_or_else(|_| path.clone());
        if !found
            .iter()
            .any(|n| n.path.canonicalize().is_ok_and(|p| p == real))
        {
            found.push(Named { path, in_directory });
        }
    };
    for input in inputs {
        if input.is_dir() {
            let mut inside: Vec<PathBuf> = std::fs::read_dir(input)
                .with_context(|| format!("reading {}", input.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .collect();
            inside.sort();
            let is = |p: &Path, ext: &str| p.extension().is_some_and(|e| e == ext);
            if let Some(csv) = inside
                .iter()
                .find(|p| is(p, "csv") && !Manifest::path_of(p).exists())
            {
                return Err(unfinished(csv));
            }
            let before = inside.len();
            for m in inside.into_iter().filter(|p| is(p, "json")) {
                if !own.as_deref().is_some_and(|own| same_file(&m, own)) {
                    add(m, true);
                }
            }
            if before == 0 {
                bail!("{}: no shard manifests (*.json) in it", input.display());
            }
        } else if input.extension().is_some_and(|e| e == "json") {
            add(input.clone(), false);
        } else if Manifest::path_of(input).exists() {
            add(Manifest::path_of(input), false);
        } else {
            return Err(unfinished(input));
        }
    }
    if found.is_empty() {
        bail!("nothing to merge: give shard manifests, CSVs or their directory");
    }
    Ok(found)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Reads the shard whose manifest is at `path` and checks its CSV against it.
fn read_shard(path: &Path) -> Result<ShardFile> {
    let manifest = Manifest::read(path)?;
    let csv_path = path.with_file_name(&manifest.csv);
    let bytes =
        std::fs::read(&csv_path).with_context(|| format!("reading {}", csv_path.display()))?;
    if manifest::sha256_hex(&bytes) != manifest.csv_sha256 {
        let complete = bytes
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            .saturating_sub(1);
        let what = if !bytes.ends_with(b"\n") {
            "cut short: its last line is not whole"
        } else if complete < manifest.runs_done as usize {
            "cut short: rows are missing at its end"
        } else {
            "changed since the shard wrote it (its checksum differs)"
        };
        bail!(
            "{}: {complete} whole rows, {} bytes, where its manifest {} says {} rows: {what}",
            csv_path.display(),
            bytes.len(),
            path.display(),
            manifest.runs_done,
        );
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(bytes.as_slice());
    let header = reader
        .headers()
        .with_context(|| format!("{}: no header", csv_path.display()))?;
    if header.iter().collect::<Vec<_>>() != CSV_HEADER.split(',').collect::<Vec<_>>() {
        bail!(
            "{}: not a batch CSV of this version (its header differs)",
            csv_path.display()
        );
    }
    let mut rows = Vec::new();
    for (i, row) in reader.records().enumerate() {
        rows.push(row.with_context(|| format!("{}: row {}", csv_path.display(), i + 1))?);
    }
    Ok(ShardFile {
        manifest,
        path: path.to_path_buf(),
        rows,
    })
}

/// Runs `runs` as short ranges: `3, 10-12, 17`, at most `max` of them then `…`.
fn ranges(runs: &[u32], max: usize) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < runs.len() {
        let mut j = i;
        while j + 1 < runs.len() && runs[j + 1] == runs[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            runs[i].to_string()
        } else {
            format!("{}-{}", runs[i], runs[j])
        });
        i = j + 1;
    }
    if parts.len() > max {
        parts.truncate(max);
        parts.push("…".into());
    }
    parts.join(", ")
}

/// Refuses shards of two campaigns, or flown by two builds.
fn same_campaign(shards: &[ShardFile]) -> Result<()> {
    let Some(first) = shards.first() else {
        return Ok(());
    };
    for s in &shards[1..] {
        let differ = first.manifest.campaign.differences(&s.manifest.campaign);
        if !differ.is_empty() {
            bail!(
                "{} and {} are shards of two campaigns: {}",
                first.path.display(),
                s.path.display(),
                differ.join("; ")
            );
        }
        if s.manifest.version != first.manifest.version {
            bail!(
                "{} was flown by autopilot {} and {} by {}: shards of two builds may differ",
                first.path.display(),
                first.manifest.version,
                s.path.display(),
                s.manifest.version
            );
        }
    }
    Ok(())
}

/// Every row of the shards by its run number (and the shard it came from); a run outside its
/// shard or the campaign, or given twice, refused.
fn rows_by_run(
    shards: &[ShardFile],
    first_run: u32,
    end: u32,
) -> Result<BTreeMap<u32, (usize, &csv::StringRecord)>> {
    let run_column = super::column("run");
    let mut by_run: BTreeMap<u32, (usize, &csv::StringRecord)> = BTreeMap::new();
    let mut twice = Vec::new();
    for (f, s) in shards.iter().enumerate() {
        for row in &s.rows {
            let run: u32 = row
                .get(run_column)
                .and_then(|r| r.parse().ok())
                .with_context(|| format!("{}: a row without a run number", s.path.display()))?;
            if !s.manifest.shard.holds(first_run, run) || run >= end {
                bail!(
                    "{}: run {run} is not one of shard {}'s",
                    s.path.display(),
                    s.manifest.shard
                );
            }
            if let Some((g, _)) = by_run.insert(run, (f, row)) {
                twice.push(format!(
                    "run {run} is in {} and in {}",
                    shards[g].path.display(),
                    s.path.display()
                ));
            }
        }
    }
    if !twice.is_empty() {
        let n = twice.len();
        twice.truncate(3);
        bail!(
            "{n} runs given twice: {}{}",
            twice.join("; "),
            if n > 3 { "; …" } else { "" }
        );
    }
    Ok(by_run)
}

/// Merges the shards named by `inputs` into the CSV `output` (a file, or a directory for
/// `batch-SEED.csv`; that name here by default) and its manifest, and prints the summary a
/// batch prints.
pub fn merge(inputs: &[PathBuf], output: Option<&Path>) -> Result<()> {
    let mut shards = Vec::new();
    for named in manifests(inputs, output)? {
        let shard = read_shard(&named.path)?;
        if named.in_directory && shard.manifest.merged_shards.is_some() {
            tracing::info!(manifest = %named.path.display(), "passed over: a merged campaign");
            continue;
        }
        shards.push(shard);
    }
    let Some(first) = shards.first() else {
        bail!("nothing to merge: the directories given hold merged campaigns only");
    };
    same_campaign(&shards)?;
    let campaign = &first.manifest.campaign;
    let Some(end) = campaign.first.checked_add(campaign.runs) else {
        bail!(
            "{}: its runs pass run number {}",
            first.path.display(),
            u32::MAX
        );
    };
    let output = super::output_path(output, &super::default_name(campaign.seed, Shard::WHOLE))?;
    let output = output.as_path();
    let by_run = rows_by_run(&shards, campaign.first, end)?;
    let missing: Vec<u32> = Shard::WHOLE
        .runs(campaign.first, campaign.runs)
        .filter(|r| !by_run.contains_key(r))
        .collect();
    if !missing.is_empty() {
        bail!(
            "{} of the campaign's {} runs are missing: {}{}",
            missing.len(),
            campaign.runs,
            ranges(&missing, 12),
            absent_shards(&shards, &missing, campaign.first)
        );
    }

    let rows: Vec<&csv::StringRecord> = by_run.values().map(|(_, r)| *r).collect();
    let mut csv = csv::Writer::from_writer(Vec::new());
    csv.write_record(CSV_HEADER.split(','))?;
    for row in &rows {
        csv.write_record(*row)?;
    }
    let bytes = csv.into_inner().context("the merged CSV")?;
    let text = String::from_utf8(bytes).context("the merged CSV")?;
    crate::records::param_file::write_atomically(output, &text)?;
    let summary = BatchSummary::of(rows.iter().copied());
    let merged = Manifest {
        format: manifest::FORMAT.into(),
        campaign: campaign.clone(),
        version: first.manifest.version.clone(),
        shard: Shard::WHOLE,
        runs_done: rows.len() as u32,
        csv: manifest::file_name(output),
        csv_sha256: manifest::sha256_hex(text.as_bytes()),
        jobs: shards.iter().map(|s| s.manifest.jobs).sum(),
        wall_time_s: shards.iter().map(|s| s.manifest.wall_time_s).sum(),
        merged_shards: Some(shards.len() as u32),
        summary,
    };
    let manifest_path = Manifest::path_of(output);
    merged.write(&manifest_path)?;
    if merged.version.is_vague() {
        tracing::warn!(
            "the shards were flown by autopilot {}: built from changes not committed (or no \
             known commit), so two different builds would not be told apart",
            merged.version
        );
    }
    merged.summary.print_faults();
    println!(
        "batch merged: {} shards={} csv={} manifest={}",
        merged.summary.total,
        shards.len(),
        output.display(),
        manifest_path.display()
    );
    Ok(())
}

/// Which shards hold the `missing` runs, when all the shards given cut the campaign alike.
fn absent_shards(shards: &[ShardFile], missing: &[u32], first: u32) -> String {
    let count = shards[0].manifest.shard.count;
    if count == 1 || shards.iter().any(|s| s.manifest.shard.count != count) {
        return String::new();
    }
    let mut absent: Vec<u32> = missing.iter().map(|r| (r - first) % count).collect();
    absent.sort_unstable();
    absent.dedup();
    let names: Vec<String> = absent.iter().map(|k| format!("{k}/{count}")).collect();
    format!(" (shard {} not given)", names.join(", "))
}

#[cfg(test)]
mod tests {
    use super::ranges;

    #[test]
    fn missing_runs_read_as_ranges() {
        assert_eq!(ranges(&[3, 10, 11, 12, 17], 5), "3, 10-12, 17");
        assert_eq!(ranges(&[1, 3, 5, 7], 2), "1, 3, …");
        assert_eq!(ranges(&[], 2), "");
    }
}
