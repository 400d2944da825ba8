//! The parameter store's file ([`gcs::param_store`]): read at start and on
//! `PREFLIGHT_STORAGE`, written after each change.
//!
//! Nothing is ever left half-written:
//! - the file is written whole and atomically (a temporary file beside it, flushed to disk,
//!   renamed over it, the directory flushed), so a crash leaves the old or the new version;
//! - its last line is a checksum, so a file damaged afterwards is recognised;
//! - before each save the file on disk, if it checks out, becomes the previous good copy
//!   (`NAME.prev`, written the same way; before the first save, an empty store: flight.toml's
//!   values). A damaged file at start is replaced by that copy in
//!   memory and the user told, in the log and to every ground station; with no good copy the
//!   daemon refuses to start, naming the file (flying half of what the user set is worse).

use anyhow::{Context, Result};
use flight_core::params::FlightParams;
use gcs::param_store::{Loaded, ParamStore, checked_text};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Reads the store at `path` (a missing file is an empty store) and applies it to `base`.
/// A damaged file (its checksum wrong, or not TOML) is replaced by the previous good copy,
/// with a warning first among the warnings; with no good copy it is an error that names it.
pub fn load(path: &Path, base: &FlightParams) -> Result<Loaded> {
    let origin = path.display().to_string();
    let Some(bytes) = read_if_present(path)? else {
        return Ok(ParamStore::parse("", &origin, base)?.kept_in(path));
    };
    let damage = match checked_text(bytes) {
        Ok(text) => match ParamStore::parse(&text, &origin, base) {
            Ok(loaded) => return Ok(loaded.kept_in(path)),
            Err(e) => e.to_string(),
        },
        Err(e) => format!("{origin}: {e}"),
    };
    let prev = previous_copy(path);
    let copy = read_if_present(&prev)?
        .and_then(|b| checked_text(b).ok())
        .and_then(|t| ParamStore::parse(&t, &prev.display().to_string(), base).ok());
    match copy {
        Some(mut loaded) => {
            loaded.from_previous_copy = true;
            loaded.warnings.insert(
                0,
                format!(
                    "{damage}: the previous good copy {} is flown instead (saved again at the next change)",
                    prev.display()
                ),
            );
            Ok(loaded.kept_in(path))
        }
        None => Err(anyhow::anyhow!(
            "{damage}; no good previous copy ({}): fix it, or delete it to fly with flight.toml's values",
            prev.display()
        )),
    }
}

/// Writes the store to its file, atomically, after keeping the file on disk as the previous
/// good copy if it checks out; nothing to do without a file.
pub fn save(store: &ParamStore) -> Result<()> {
    let Some(path) = store.path() else {
        return Ok(());
    };
    match read_if_present(path)? {
        // No store yet: the state before is flight.toml's values, an empty store.
        None => write_atomically(&previous_copy(path), &ParamStore::in_memory().to_toml())?,
        Some(bytes) => {
            if let Ok(current) = checked_text(bytes)
                && current.parse::<toml::Table>().is_ok()
            {
                write_atomically(&previous_copy(path), &current)?;
            }
        }
    }
    write_atomically(path, &store.to_toml())
}

/// Creates or truncates `path` for writing; a file it creates gets `mode` (Unix).
fn open_truncated(path: &Path, mode: u32) -> std::io::Result<std::fs::File> {
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut o, mode);
    #[cfg(not(unix))]
    let _ = mode;
    o.open(path)
}

/// The previous good copy of the store at `path`: `NAME.prev` beside it.
pub fn previous_copy(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".prev");
    path.with_file_name(name)
}

/// The file's bytes, or `None` if there is no file.
fn read_if_present(path: &Path) -> Result<Option<Vec<u8>>> {
    match std::fs::read(path) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("reading {}", path.display())),
    }
}

/// Replaces `path` with `text` so that a crash at any moment leaves either the old file or the
/// new one: write a temporary file in the same directory, flush it to the disk, rename it over
/// `path`, and flush the directory entry.
pub fn write_atomically(path: &Path, text: &str) -> Result<()> {
    write_atomically_with(path, text, 0o644)
}

/// [`write_atomically`] for a secret: readable by its owner only (mode 0600).
pub fn write_private(path: &Path, text: &str) -> Result<()> {
    write_atomically_with(path, text, 0o600)
}

fn write_atomically_with(path: &Path, text: &str, mode: u32) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .with_context(|| format!("{} is not a file name", path.display()))?;
    let tmp = dir.join(format!(".{}.tmp", name.to_string_lossy()));
    let write = || -> std::io::Result<()> {
        let mut f = open_truncated(&tmp, mode)?;
        f.write_all(text.as_bytes())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)?;
        // The rename itself reaches the disk with the directory.
        std::fs::File::open(&dir)?.sync_all()
    };
    write().with_context(|| {
        // A failed write (a full disk) leaves no temporary file behind; the old file stands.
        let _ = std::fs::remove_file(&tmp);
        format!("saving {}", path.display())
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use gcs::param_store::CHECKSUMMED;

    #[test]
    fn a_save_that_cannot_be_written_leaves_the_old_file_and_no_temporary_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        std::fs::write(&path, "old").unwrap();
        // A directory where the file should be renamed over: the rename fails after the
        // temporary file was written, as a full disk fails a write.
        let blocked = dir.path().join("blocked");
        std::fs::create_dir(&blocked).unwrap();
        std::fs::write(blocked.join("inside"), "x").unwrap();
        assert!(write_atomically(&blocked, "new").is_err());
        assert!(
            !dir.path().join(".blocked.tmp").exists(),
            "temporary file removed"
        );
        assert!(blocked.is_dir());
        write_atomically(&path, "new").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
    }

    #[test]
    fn stored_values_apply_over_the_base_and_survive_a_save_and_load() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        let base = FlightParams::default();
        let empty = load(&path, &base).unwrap();
        assert_eq!(empty.params, base, "no file: the base");
        assert!(empty.warnings.is_empty());

        let mut store = empty.store;
        let mut params = base.clone();
        for (name, value) in [("MIS_TAKEOFF_ALT", 7.5), ("ATT_ALIGN_N", 400.0)] {
            params.set(name, value).unwrap();
            store.record(name, value);
        }
        save(&store).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("ATT_ALIGN_N = 400\n"),
            "integers stay integers: {text}"
        );
        assert!(text.contains("MIS_TAKEOFF_ALT = 7.5\n"), "{text}");
        assert!(
            !dir.path().join(".store.toml.tmp").exists(),
            "the temporary file is renamed away"
        );

        let again = load(&path, &base).unwrap();
        assert_eq!(again.params, params);
        assert_eq!(
            again.store.names().collect::<Vec<_>>(),
            ["ATT_ALIGN_N", "MIS_TAKEOFF_ALT"]
        );
        assert!(again.warnings.is_empty(), "{:?}", again.warnings);
    }

    /// A store at `dir/store.toml` holding `MIS_TAKEOFF_ALT = alt`, saved.
    fn save_takeoff_alt(path: &Path, alt: f64) {
        let base = FlightParams::default();
        let mut store = load(path, &base).unwrap().store;
        store.record("MIS_TAKEOFF_ALT", alt);
        save(&store).unwrap();
    }

    fn takeoff_alt(loaded: &Loaded) -> f64 {
        loaded.params.commander.takeoff_alt_m
    }

    #[test]
    fn a_saved_store_ends_with_its_checksum_and_keeps_the_one_before_as_the_previous_copy() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        save_takeoff_alt(&path, 4.0);
        let before = load(&previous_copy(&path), &FlightParams::default()).unwrap();
        assert_eq!(
            before.store.names().count(),
            0,
            "before the first save: an empty store"
        );
        let first = std::fs::read_to_string(&path).unwrap();
        assert!(first.starts_with(CHECKSUMMED), "{first}");
        let last = first.lines().last().unwrap();
        let body = &first[..first.len() - last.len() - 1];
        assert_eq!(
            last,
            format!("# checksum: crc32 {:08x}", crc32fast::hash(body.as_bytes()))
        );

        save_takeoff_alt(&path, 6.0);
        assert_eq!(
            std::fs::read_to_string(previous_copy(&path)).unwrap(),
            first
        );
        let loaded = load(&path, &FlightParams::default()).unwrap();
        assert_eq!(takeoff_alt(&loaded), 6.0);
        assert!(!loaded.from_previous_copy && loaded.warnings.is_empty());
    }

    /// A way a file can be damaged.
    type Damage = fn(&str) -> String;

    #[test]
    fn a_damaged_store_is_replaced_by_its_previous_good_copy_and_the_user_told() {
        let base = FlightParams::default();
        let damages: [(&str, Damage); 8] = [
            ("truncated to nothing", |_| String::new()),
            ("blanks only", |_| "\n  \n".to_owned()),
            ("a digit changed", |t| t.replacen("6.0", "9.0", 1)),
            ("cut short at a line", |t| {
                t.lines().take(5).map(|l| format!("{l}\n")).collect()
            }),
            ("cut short mid-line", |t| t[..t.len() - 7].to_owned()),
            ("cut short in the first line", |t| t[..12].to_owned()),
            ("a line appended", |t| format!("{t}MPC_XY_P = 1.0\n")),
            ("not TOML, checksum line gone", |t| {
                t.replace("= 6.0", "= = 6.0").replace("# checksum", "#")
            }),
        ];
        for (what, damage) in damages {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("store.toml");
            save_takeoff_alt(&path, 4.0);
            save_takeoff_alt(&path, 6.0);
            let good = std::fs::read_to_string(&path).unwrap();
            std::fs::write(&path, damage(&good)).unwrap();
            let loaded = load(&path, &base).unwrap();
            assert!(loaded.from_previous_copy, "{what}");
            assert_eq!(
                takeoff_alt(&loaded),
                4.0,
                "{what}: the previous copy's value"
            );
            assert!(
                loaded.warnings[0].contains("store.toml")
                    && loaded.warnings[0].contains("previous good copy"),
                "{what}: {:?}",
                loaded.warnings
            );
            // The next save must not make the damaged file the previous copy.
            let mut store = loaded.store;
            store.record("MIS_TAKEOFF_ALT", 8.0);
            save(&store).unwrap();
            let prev = std::fs::read_to_string(previous_copy(&path)).unwrap();
            assert!(prev.contains("MIS_TAKEOFF_ALT = 4.0"), "{what}: {prev}");
            let again = load(&path, &base).unwrap();
            assert_eq!(takeoff_alt(&again), 8.0, "{what}");
            assert!(!again.from_previous_copy, "{what}");
        }
    }

    #[test]
    fn a_damaged_store_without_a_good_copy_is_an_error_and_a_hand_written_one_is_fine() {
        let base = FlightParams::default();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        save_takeoff_alt(&path, 4.0);
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, text.replace("4.0", "5.0")).unwrap();
        // The first store damaged: the copy before it, flight.toml's values.
        let first = load(&path, &base).unwrap();
        assert!(first.from_previous_copy);
        assert_eq!(takeoff_alt(&first), base.commander.takeoff_alt_m);
        std::fs::write(previous_copy(&path), "damaged too").unwrap();
        let err = format!("{:#}", load(&path, &base).unwrap_err());
        assert!(
            err.contains("store.toml: damaged: checksum") && err.contains("no good previous copy"),
            "{err}"
        );
        // The way the header says to edit it: without the first and the last line.
        let edited: Vec<&str> = text.lines().collect();
        let edited = edited[1..edited.len() - 1].join("\n").replace("4.0", "5.0");
        std::fs::write(&path, edited).unwrap();
        let loaded = load(&path, &base).unwrap();
        assert_eq!(takeoff_alt(&loaded), 5.0);
        assert!(!loaded.from_previous_copy && loaded.warnings.is_empty());
    }

    /// Where [`save_until_killed`] keeps its store (set only in the child process).
    const CHILD_DIR: &str = "AUTOPILOT_TEST_SAVE_UNTIL_KILLED";

    /// A save's number as two parameter values: save `n` stores MIS_TAKEOFF_ALT
    /// 0.5 + (n mod 9000)/100 m and ATT_ALIGN_N 1 + n mod 9000 (a mix of two saves shows).
    fn save_number(loaded: &Loaded) -> Option<u64> {
        let alt = loaded.params.commander.takeoff_alt_m;
        let n = loaded.params.attitude.align_samples as u64 - 1;
        ((alt - 0.5 - n as f64 / 100.0).abs() < 1e-9).then_some(n)
    }

    /// The child of [`a_store_killed_at_random_points_during_1000_saves_is_always_valid`]:
    /// loads the store (as the daemon does at start), then saves numbered versions, printing
    /// `saved N` on standard error after each save returns, until it is killed (standard
    /// output is the test harness's: its `test NAME ... ` stands before the first line there).
    /// Does nothing unless started so.
    #[test]
    #[ignore = "started by the SIGKILL test in a child process"]
    fn save_until_killed() {
        let Some(dir) = std::env::var_os(CHILD_DIR) else {
            return;
        };
        let path = Path::new(&dir).join("store.toml");
        let loaded = load(&path, &FlightParams::default()).unwrap();
        let mut n = save_number(&loaded).map_or(0, |n| n + 1);
        let mut store = loaded.store;
        loop {
            let k = n % 9000;
            store.record("MIS_TAKEOFF_ALT", 0.5 + k as f64 / 100.0);
            store.record("ATT_ALIGN_N", (1 + k) as f64);
            save(&store).unwrap();
            // One write of the whole line: `eprintln!` writes its pieces one by one, and a kill
            // between them leaves the parent half a line.
            let line = format!("saved {k}\n");
            std::io::stderr().write_all(line.as_bytes()).unwrap();
            n += 1;
        }
    }

    #[test]
    fn a_store_killed_at_random_points_during_1000_saves_is_always_valid() {
        use std::io::{BufRead, BufReader};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        let base = FlightParams::default();
        let exe = std::env::current_exe().unwrap();
        let mut rng = 0x2545_f491_4f6c_dd1d_u64; // xorshift64: reproducible "random" points
        let mut next = move |below: u64| {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng % below
        };
        let (mut saves, mut kills, mut last) = (0u64, 0u32, None::<u64>);
        while saves < 1000 {
            let mut child = std::process::Command::new(&exe)
                .args(["records::param_file::tests::save_until_killed", "--exact"])
                .args(["--ignored", "--nocapture", "--test-threads=1"])
                .env(CHILD_DIR, dir.path())
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
            let saved = |line: std::io::Result<String>| {
                let line = line.unwrap();
                line.strip_prefix("saved ")
                    .map(|n| n.parse::<u64>().unwrap())
            };
            // Let it save 0 to 24 times, then kill it 0 to 3 ms into the next save.
            let wait_for = next(25);
            let mut seen = 0;
            while seen < wait_for {
                match lines.next() {
                    Some(l) => {
                        if let Some(n) = saved(l) {
                            last = Some(n);
                            seen += 1;
                        }
                    }
                    None => panic!("the saving child ended by itself"),
                }
            }
            std::thread::sleep(std::time::Duration::from_micros(next(3000)));
            child.kill().unwrap(); // SIGKILL
            child.wait().unwrap();
            for l in lines {
                if let Some(n) = saved(l) {
                    last = Some(n);
                    seen += 1;
                }
            }
            saves += seen;
            kills += 1;

            let loaded = load(&path, &base).unwrap_or_else(|e| panic!("after kill {kills}: {e:#}"));
            assert!(
                !loaded.from_previous_copy && loaded.warnings.is_empty(),
                "after kill {kills}: {:?}",
                loaded.warnings
            );
            // Every save that returned is there; the one cut short is there whole or not at all.
            let found = save_number(&loaded);
            let done = last.map(|n| (n + 1) % 9000);
            assert!(
                found == last
                    || (found.is_some() && found == done)
                    || (last.is_none() && found.is_none()),
                "after kill {kills}: save {found:?} found, {last:?} was the last to return"
            );
            last = found;
            if let Ok(prev) = std::fs::read(previous_copy(&path)) {
                assert!(
                    checked_text(prev).is_ok(),
                    "after kill {kills}: previous copy"
                );
            }
        }
        eprintln!("{saves} saves, {kills} kills: the store was valid after every kill");
    }
}
