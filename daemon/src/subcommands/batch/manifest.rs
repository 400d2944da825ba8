//! A batch's manifest: the JSON file beside its CSV that says which campaign and which shard the
//! rows are, which build flew them, and a checksum of the CSV, so that shards flown anywhere can
//! be checked and merged.

use super::shard::Shard;
use super::summary::BatchSummary;
use super::{BatchConfig, FaultKind};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The manifest's format, first in the file.
pub const FORMAT: &str = "autopilot-batch/1";

/// Everything that decides a campaign's rows: the batch's settings and the exact airframe and
/// parameter files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Campaign {
    /// The campaign's seed.
    pub seed: u64,
    /// Its first run's number.
    pub first: u32,
    /// Its runs, all shards together.
    pub runs: u32,
    /// Take-off height (m).
    pub takeoff_m: f64,
    /// Hover time (s).
    pub hover_s: f64,
    /// Largest mean wind (m/s).
    pub wind_max_m_s: f64,
    /// Largest turbulence intensity W20 (m/s).
    pub turbulence_max_m_s: f64,
    /// The faults drawn from, by name.
    pub faults: Vec<String>,
    /// Sensor preset.
    pub sensors: String,
    /// The airframe's name, and the SHA-256 of its file.
    pub airframe: String,
    /// SHA-256 of the airframe file.
    pub airframe_sha256: String,
    /// SHA-256 of the flight-parameter file.
    pub params_sha256: String,
}

impl Campaign {
    /// The campaign of `cfg` flown with the airframe `airframe` (read from `airframe_path`) and
    /// the parameters of `params_path`.
    pub fn new(
        cfg: &BatchConfig,
        airframe: &str,
        airframe_path: &Path,
        params_path: &Path,
    ) -> Result<Self> {
        let digest = |p: &Path| -> Result<String> {
            Ok(sha256_hex(
                &std::fs::read(p).with_context(|| format!("reading {}", p.display()))?,
            ))
        };
        Ok(Self {
            seed: cfg.seed,
            first: cfg.first,
            runs: cfg.runs,
            takeoff_m: cfg.takeoff_m,
            hover_s: cfg.hover_s,
            wind_max_m_s: cfg.wind_max_m_s,
            turbulence_max_m_s: cfg.turbulence_max_m_s,
            faults: cfg
                .faults
                .iter()
                .map(|f| FaultKind::name(*f).into())
                .collect(),
            sensors: format!("{:?}", cfg.sensors).to_lowercase(),
            airframe: airframe.into(),
            airframe_sha256: digest(airframe_path)?,
            params_sha256: digest(params_path)?,
        })
    }

    /// The settings in which `self` and `other` differ, by name.
    pub fn differences(&self, other: &Campaign) -> Vec<String> {
        let (a, b) = (serde_json::to_value(self), serde_json::to_value(other));
        let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) = (a, b) else {
            return vec!["?".into()];
        };
        a.iter()
            .filter(|(k, v)| b.get(*k) != Some(v))
            .map(|(k, v)| {
                format!(
                    "{k} {v} vs {}",
                    b.get(k).unwrap_or(&serde_json::Value::Null)
                )
            })
            .collect()
    }
}

/// The build that flew a batch.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Version {
    /// The autopilot's version.
    pub autopilot: String,
    /// The git commit it was built from, `-dirty` after it when the tracked files had
    /// changes (`unknown` outside a git checkout, unless the build was given
    /// `AUTOPILOT_GIT_HASH`).
    pub git: String,
}

impl Version {
    /// This binary's.
    pub fn this() -> Self {
        Self {
            autopilot: env!("CARGO_PKG_VERSION").into(),
            git: env!("AUTOPILOT_GIT_HASH").into(),
        }
    }
}

impl Version {
    /// Whether two builds of this version could differ unseen: built from changes not
    /// committed, or from no known commit.
    pub fn is_vague(&self) -> bool {
        self.git == "unknown" || self.git.ends_with("-dirty")
    }
}

impl std::fmt::Display for Version {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.autopilot, self.git)
    }
}

/// The manifest of a batch, a shard of a campaign or a merged campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: String,
    /// The campaign.
    pub campaign: Campaign,
    /// The build.
    pub version: Version,
    /// Which shard ([`Shard::WHOLE`] for a batch flown whole or merged).
    pub shard: Shard,
    /// Rows in the CSV.
    pub runs_done: u32,
    /// The CSV's file name, beside the manifest.
    pub csv: String,
    /// SHA-256 of the CSV's bytes.
    pub csv_sha256: String,
    /// Worker threads (added up over the shards, when merged).
    pub jobs: usize,
    /// Wall time of the batch (s; the shards' added up, when merged).
    pub wall_time_s: f64,
    /// Shards merged into this one; none for a batch flown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub merged_shards: Option<u32>,
    /// The rows' summary.
    pub summary: BatchSummary,
}

impl Manifest {
    /// The manifest of the CSV at `csv`: the same name, `.json`.
    pub fn path_of(csv: &Path) -> PathBuf {
        csv.with_extension("json")
    }

    /// Writes it to `path`, atomically (no reader ever sees half a manifest).
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)? + "\n";
        crate::records::param_file::write_atomically(path, &text)
    }

    /// Reads the manifest at `path`.
    pub fn read(path: &Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let m: Manifest = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a batch manifest", path.display()))?;
        if m.format != FORMAT {
            bail!(
                "{}: format {:?}, this autopilot reads {FORMAT:?}",
                path.display(),
                m.format
            );
        }
        Ok(m)
    }
}

/// The file name of `path`, as a manifest names its CSV.
pub fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// SHA-256 of `bytes` in lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
