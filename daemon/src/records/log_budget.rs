//! How much of its disk the log directory may take (`SDLOG_DIRS_MAX`, `SDLOG_MIN_FREE`, as PX4's
//! logger keeps its SD card): at start-up the oldest runs' logs are removed beyond the runs kept
//! and until the free space is there; in flight a writer stops below the free-space floor
//! ([`keep_free`]), cleanly, as on a full disk.
//!
//! A run is the files of one stem (`2026-11-23_10-15-02.ulg`, `.tlog`, `.csv`, with `_iN` and
//! `-2` as [`super::log_files::run_stem`] names them); only those are ever removed.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The extensions of a run's logs.
const EXTENSIONS: [&str; 3] = ["ulg", "tlog", "csv"];

/// The free space (bytes) the writers leave on their disk: set once at start-up from
/// `SDLOG_MIN_FREE` (every vehicle of a process shares one log directory and one setting).
static KEEP_FREE: AtomicU64 = AtomicU64::new(0);

/// Sets the floor the log writers keep free (bytes; 0: none).
pub fn keep_free(bytes: u64) {
    KEEP_FREE.store(bytes, Ordering::Relaxed);
}

/// The floor the log writers keep free (bytes).
pub fn kept_free() -> u64 {
    KEEP_FREE.load(Ordering::Relaxed)
}

/// The size at which a log file goes on in a new part (bytes; 0: never) and the parts kept
/// (0: all): set once at start-up from `SDLOG_MAX_SIZE` and `SDLOG_ROTATE`.
static ROTATE_BYTES: AtomicU64 = AtomicU64::new(0);
static ROTATE_KEEP: AtomicU64 = AtomicU64::new(0);

/// Sets the size at which a log file goes on in a new part (bytes; 0: never) and how many
/// parts are kept (0: all).
pub fn rotate_at(bytes: u64, keep: u32) {
    ROTATE_BYTES.store(bytes, Ordering::Relaxed);
    ROTATE_KEEP.store(u64::from(keep), Ordering::Relaxed);
}

/// The size at which a log file goes on in a new part (bytes; 0: never) and the parts kept.
pub fn rotation() -> (u64, u32) {
    (
        ROTATE_BYTES.load(Ordering::Relaxed),
        ROTATE_KEEP.load(Ordering::Relaxed) as u32,
    )
}

/// Free space (bytes) for an unprivileged writer on the disk holding `path`; `None` where it
/// cannot be told.
pub fn free_bytes(path: &Path) -> Option<u64> {
    #[cfg(target_os = "linux")]
    {
        let s = nix::sys::statvfs::statvfs(path).ok()?;
        Some((s.blocks_available() as u64).saturating_mul(s.fragment_size() as u64))
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = path;
        None
    }
}

/// The runs in `dir`, oldest first: each stem's files, by the newest file's modification time
/// (then by name).
fn runs(dir: &Path) -> std::io::Result<Vec<Vec<PathBuf>>> {
    let mut by_stem: std::collections::BTreeMap<String, (std::time::SystemTime, Vec<PathBuf>)> =
        Default::default();
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        let (Some(stem), Some(ext)) = (path.file_stem(), path.extension()) else {
            continue;
        };
        let stem = stem.to_string_lossy().into_owned();
        // A later part of a run's file (`NAME.2.ulg`) is the run's.
        let stem = match stem.rsplit_once('.') {
            Some((run, part)) if part.parse::<u32>().is_ok() => run.to_owned(),
            _ => stem,
        };
        if !EXTENSIONS.iter().any(|e| ext == *e) || !is_run_stem(&stem) {
            continue;
        }
        let modified = std::fs::metadata(&path)
            .and_then(|m| m.modified())
            .unwrap_or(std::time::UNIX_EPOCH);
        let run = by_stem
            .entry(stem)
            .or_insert((std::time::UNIX_EPOCH, Vec::new()));
        run.0 = run.0.max(modified);
        run.1.push(path);
    }
    let mut runs: Vec<_> = by_stem.into_iter().collect();
    runs.sort_by(|(a_name, (a_t, _)), (b_name, (b_t, _))| a_t.cmp(b_t).then(a_name.cmp(b_name)));
    Ok(runs.into_iter().map(|(_, (_, files))| files).collect())
}

/// A stem as runs are named: `YYYY-MM-DD_HH-MM-SS`, then `_iN` and `-N` if any.
fn is_run_stem(stem: &str) -> bool {
    let b = stem.as_bytes();
    let pattern = b"0000-00-00_00-00-00";
    b.len() >= pattern.len()
        && b.iter().zip(pattern).all(|(c, p)| match p {
            b'0' => c.is_ascii_digit(),
            _ => c == p,
        })
        && stem[pattern.len()..]
            .split(['_', '-'])
            .all(|part| part.is_empty() || part.trim_start_matches('i').parse::<u32>().is_ok())
}

/// Before a new run's logs in `dir`: removes the oldest runs' logs, beyond `runs_max - 1` (the
/// new run is the last; 0: no limit), then while the disk has less than `min_free` bytes free.
/// Returns the files removed.
pub fn make_room(dir: &Path, runs_max: u32, min_free: u64) -> std::io::Result<Vec<PathBuf>> {
    let mut runs = runs(dir)?;
    let mut removed = Vec::new();
    let mut remove = |run: Vec<PathBuf>| -> std::io::Result<()> {
        for f in run {
            match std::fs::remove_file(&f) {
                Ok(()) => removed.push(f),
                // Another process removing the same old run at its start.
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    };
    if runs_max > 0 {
        let beyond = runs.len().saturating_sub(runs_max as usize - 1);
        for run in runs.drain(..beyond) {
            remove(run)?;
        }
    }
    let mut runs = runs.into_iter();
    while min_free > 0 && free_bytes(dir).is_some_and(|free| free < min_free) {
        let Some(run) = runs.next() else { break };
        remove(run)?;
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn touch(dir: &Path, name: &str, age_s: u64) {
        let path = dir.join(name);
        std::fs::write(&path, b"log").unwrap();
        let t = std::time::SystemTime::now() - std::time::Duration::from_secs(age_s);
        std::fs::File::options()
            .write(true)
            .open(&path)
            .unwrap()
            .set_modified(t)
            .unwrap();
    }

    #[test]
    fn the_oldest_runs_go_beyond_the_runs_kept_and_nothing_else_is_touched() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for (k, age) in [(1, 400), (2, 300), (3, 200), (4, 100)] {
            for ext in EXTENSIONS {
                touch(d, &format!("2026-11-2{k}_10-00-00.{ext}"), age);
            }
        }
        touch(d, "2026-11-25_10-00-00_i2-2.csv", 50);
        // A long run's later parts (SDLOG_MAX_SIZE) are its own.
        touch(d, "2026-11-22_10-00-00.2.csv", 290);
        touch(d, "2026-11-22_10-00-00.3.csv", 280);
        touch(d, "notes.csv", 1000);
        touch(d, "2026-11-21_10-00-00.txt", 1000);
        // Three kept with the new one: the two newest stay.
        let removed = make_room(d, 3, 0).unwrap();
        let mut names: Vec<_> = removed
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names.len(), 11, "{names:?}");
        assert!(
            names.iter().all(|n| n.starts_with("2026-11-2")),
            "{names:?}"
        );
        for kept in [
            "2026-11-24_10-00-00.ulg",
            "2026-11-25_10-00-00_i2-2.csv",
            "notes.csv",
        ] {
            assert!(d.join(kept).exists(), "{kept}");
        }
        assert!(d.join("2026-11-21_10-00-00.txt").exists(), "not a log");
        // No limit, no floor: nothing more.
        assert!(make_room(d, 0, 0).unwrap().is_empty());
    }

    #[test]
    fn below_the_free_space_floor_every_old_run_goes_and_the_rest_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        touch(d, "2026-11-21_10-00-00.ulg", 20);
        touch(d, "2026-11-22_10-00-00.csv", 10);
        touch(d, "mine.txt", 30);
        // A floor no disk has: every run goes, and the search ends.
        let removed = make_room(d, 0, u64::MAX).unwrap();
        assert_eq!(removed.len(), 2);
        assert!(d.join("mine.txt").exists());
        assert!(free_bytes(d).is_some_and(|b| b > 0));
    }

    #[test]
    fn run_stems_are_recognised() {
        for s in [
            "2026-11-23_10-15-02",
            "2026-11-23_10-15-02_i3",
            "2026-11-23_10-15-02-2",
        ] {
            assert!(is_run_stem(s), "{s}");
        }
        for s in [
            "flight",
            "2026-11-23",
            "2026-11-23_10-15-02x",
            "2026-1a-23_10-15-02",
        ] {
            assert!(!is_run_stem(s), "{s}");
        }
    }
}
