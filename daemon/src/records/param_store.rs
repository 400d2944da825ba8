//! The parameters a ground station changed, kept across restarts.
//!
//! `params/flight.toml` holds the tuning a user edits by hand; a ground station's `PARAM_SET`
//! lands here instead, in a small TOML file of MAVLink names and values (as PX4 saves only
//! what differs from its defaults), applied over `flight.toml` at start:
//!
//! ```toml
//! # autopilot parameter store (checksummed)
//! MIS_TAKEOFF_ALT = 10.0
//! ATT_ALIGN_N = 400
//! # checksum: crc32 5d3c0a1e
//! ```
//!
//! Nothing is ever left half-written:
//! - the file is written whole and atomically (a temporary file beside it, flushed to disk,
//!   renamed over it, the directory flushed), so a crash leaves the old or the new version;
//! - its last line is a CRC-32 (zlib's) of everything before it, so a file damaged afterwards
//!   (a bad sector, a truncating copy, an edit that forgot the line) is recognised;
//! - before each save the file on disk, if it checks out, becomes the previous good copy
//!   (`NAME.prev`, written the same way; before the first save, an empty store: flight.toml's
//!   values). A damaged file at start is replaced by that copy in
//!   memory and the user told, in the log and to every ground station; with no good copy the
//!   daemon refuses to start, naming the file (flying half of what the user set is worse).
//!
//! A file without the checksum line (written by hand, or by an older version) is taken as it
//! is. A file from another version of the daemon loads with warnings: a name this version does
//! not know is kept (written back untouched, so a downgrade loses nothing); a value this version
//! refuses is dropped and the `flight.toml` value flown. A name the file does not hold is not a
//! fault: it keeps its `flight.toml` value.

use anyhow::{Context, Result};
use flight_core::params::FlightParams;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The stored parameter changes, and the file they live in (none: kept in memory only).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamStore {
    path: Option<PathBuf>,
    /// Parameters set from a ground station: MAVLink name → value.
    set: BTreeMap<String, f64>,
    /// Entries of the file this version does not know, kept as they were.
    unknown: toml::Table,
}

impl Loaded {
    /// The store kept in `path`.
    fn at(mut self, path: &Path) -> Self {
        self.store.path = Some(path.to_path_buf());
        self
    }
}

/// A store read at start: the store, the parameters to fly with, and what to warn about.
#[derive(Debug)]
pub struct Loaded {
    /// The store.
    pub store: ParamStore,
    /// `base` with the stored changes applied.
    pub params: FlightParams,
    /// One line per name this version does not know and per value it refuses, after one for a
    /// damaged file.
    pub warnings: Vec<String>,
    /// The file was damaged: these are the previous good copy's values.
    pub from_previous_copy: bool,
}

impl ParamStore {
    /// A store that is never written.
    pub fn in_memory() -> Self {
        Self::default()
    }

    /// Reads the store at `path` (a missing file is an empty store) and applies it to `base`.
    /// A damaged file (its checksum wrong, or not TOML) is replaced by the previous good copy,
    /// with a warning first among the warnings; with no good copy it is an error that names it.
    pub fn load(path: &Path, base: &FlightParams) -> Result<Loaded> {
        let origin = path.display().to_string();
        let Some(bytes) = read_if_present(path)? else {
            return Ok(Self::parse("", &origin, base)?.at(path));
        };
        let damage = match checked_text(bytes) {
            Ok(text) => match Self::parse(&text, &origin, base) {
                Ok(loaded) => return Ok(loaded.at(path)),
                Err(e) => format!("{e:#}"),
            },
            Err(e) => format!("{origin}: {e}"),
        };
        let prev = previous_copy(path);
        let copy = read_if_present(&prev)?
            .and_then(|b| checked_text(b).ok())
            .and_then(|t| Self::parse(&t, &prev.display().to_string(), base).ok());
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
                Ok(loaded.at(path))
            }
            None => Err(anyhow::anyhow!(
                "{damage}; no good previous copy ({}): fix it, or delete it to fly with flight.toml's values",
                prev.display()
            )),
        }
    }

    /// [`ParamStore::load`] from text; `origin` names it in messages.
    pub fn parse(text: &str, origin: &str, base: &FlightParams) -> Result<Loaded> {
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            anyhow::anyhow!(
                "{origin}: {} (fix it, or delete it to fly with flight.toml's values)",
                e.to_string().trim_end().replace('\n', " | ")
            )
        })?;
        let mut store = Self::default();
        let mut params = base.clone();
        let mut warnings = Vec::new();
        for (name, value) in table {
            if FlightParams::find(&name).is_none() {
                warnings.push(format!(
                    "{origin}: {name} is not a parameter of this version: kept in the file, not used"
                ));
                store.unknown.insert(name, value);
                continue;
            }
            let number = match value {
                toml::Value::Integer(i) => i as f64,
                toml::Value::Float(f) => f,
                other => {
                    warnings.push(format!(
                        "{origin}: {name} = {other} is not a number: flight.toml's value used"
                    ));
                    continue;
                }
            };
            match params.set(&name, number) {
                Ok(()) => {
                    store.set.insert(name, number);
                }
                Err(e) => warnings.push(format!("{origin}: {e}: flight.toml's value used")),
            }
        }
        Ok(Loaded {
            store,
            params,
            warnings,
            from_previous_copy: false,
        })
    }

    /// The file, if there is one.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The names of the stored parameters.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.set.keys().map(String::as_str)
    }

    /// Records a value a ground station set (already accepted by [`FlightParams::set`]).
    pub fn record(&mut self, name: &str, value: f64) {
        self.set.insert(name.to_owned(), value);
    }

    /// Forgets every stored change (reset to `flight.toml`'s values); names of other versions
    /// are kept.
    pub fn clear(&mut self) {
        self.set.clear();
    }

    /// The file's text: a header, then one `NAME = value` line per stored parameter (integer
    /// parameters as TOML integers), then the names of other versions.
    pub fn to_toml(&self) -> String {
        let mut text = format!(
            "{CHECKSUMMED}\n\
             # Parameters changed from a ground station, applied over flight.toml at start,\n\
             # written by autopilot {}. To edit by hand: stop the daemon, delete the first line\n\
             # and the checksum line at the end (or the edit is taken for damage).\n",
            env!("CARGO_PKG_VERSION")
        );
        let mut table = toml::Table::new();
        for (name, &value) in &self.set {
            let integer = FlightParams::find(name)
                .is_some_and(|(_, _, m)| m.kind == flight_core::params::ParamKind::Int32);
            let v = if integer {
                toml::Value::Integer(value as i64)
            } else {
                toml::Value::Float(value)
            };
            table.insert(name.clone(), v);
        }
        text += &table.to_string();
        if !self.unknown.is_empty() {
            text += "\n# Not parameters of this version (kept for the version that wrote them):\n";
            text += &self.unknown.to_string();
        }
        with_checksum(text)
    }

    /// Writes the store to its file, atomically, after keeping the file on disk as the previous
    /// good copy if it checks out; nothing to do without a file.
    pub fn save(&self) -> Result<()> {
        let Some(path) = &self.path else {
            return Ok(());
        };
        match read_if_present(path)? {
            // No store yet: the state before is flight.toml's values, an empty store.
            None => write_atomically(&previous_copy(path), &Self::default().to_toml())?,
            Some(bytes) => {
                if let Ok(current) = checked_text(bytes)
                    && current.parse::<toml::Table>().is_ok()
                {
                    write_atomically(&previous_copy(path), &current)?;
                }
            }
        }
        write_atomically(path, &self.to_toml())
    }
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

/// The first line of a saved store: it ends with a checksum line (a file cut short loses it).
const CHECKSUMMED: &str = "# autopilot parameter store (checksummed)";
/// The line that ends a saved store.
const CHECKSUM_PREFIX: &str = "# checksum: crc32 ";

/// `text` (ending in a newline) with its checksum line appended.
fn with_checksum(mut text: String) -> String {
    if !text.ends_with('\n') {
        text.push('\n');
    }
    let line = format!("{CHECKSUM_PREFIX}{:08x}\n", crc32(text.as_bytes()));
    text + &line
}

/// A store's text if its checksum line agrees with the text before it. A text that does not
/// begin with [`CHECKSUMMED`] (written by hand or by an older version) needs none. `Err` says
/// what is wrong.
fn checked_text(bytes: Vec<u8>) -> std::result::Result<String, String> {
    let text = String::from_utf8(bytes).map_err(|_| "damaged: not UTF-8 text".to_owned())?;
    verify(&text)?;
    Ok(text)
}

/// [`checked_text`]'s check.
fn verify(text: &str) -> std::result::Result<(), String> {
    let body_end = text.trim_end_matches('\n').rfind('\n').map_or(0, |i| i + 1);
    let last = text[body_end..].trim_end();
    let Some(sum) = last.strip_prefix(CHECKSUM_PREFIX) else {
        // Ours (its first line, or a file cut short inside it), or a checksum line not last.
        let ours =
            text.starts_with(CHECKSUMMED) || (!text.is_empty() && CHECKSUMMED.starts_with(text));
        return if ours || text.contains(CHECKSUM_PREFIX) {
            Err("damaged: its checksum line is not its last (cut short, or appended to?)".into())
        } else {
            Ok(())
        };
    };
    let expected =
        u32::from_str_radix(sum, 16).map_err(|_| format!("checksum {sum:?} unreadable"))?;
    let actual = crc32(&text.as_bytes()[..body_end]);
    if actual == expected {
        Ok(())
    } else {
        Err(format!(
            "damaged: checksum {actual:08x} where the file says {expected:08x} (edited by hand? delete the checksum line to accept an edit)"
        ))
    }
}

/// CRC-32 as zlib and PNG compute it (`crc32fast`): `python3 -c "import zlib;
/// print(hex(zlib.crc32(open(f, 'rb').read())))"` on the text before the checksum line gives the
/// same number.
fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
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
    write().with_context(|| format!("saving {}", path.display()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn stored_values_apply_over_the_base_and_survive_a_save_and_load() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        let base = FlightParams::default();
        let empty = ParamStore::load(&path, &base).unwrap();
        assert_eq!(empty.params, base, "no file: the base");
        assert!(empty.warnings.is_empty());

        let mut store = empty.store;
        let mut params = base.clone();
        for (name, value) in [("MIS_TAKEOFF_ALT", 7.5), ("ATT_ALIGN_N", 400.0)] {
            params.set(name, value).unwrap();
            store.record(name, value);
        }
        store.save().unwrap();
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

        let again = ParamStore::load(&path, &base).unwrap();
        assert_eq!(again.params, params);
        assert_eq!(
            again.store.names().collect::<Vec<_>>(),
            ["ATT_ALIGN_N", "MIS_TAKEOFF_ALT"]
        );
        assert!(again.warnings.is_empty(), "{:?}", again.warnings);
    }

    #[test]
    fn a_file_of_another_version_loads_with_warnings_and_keeps_what_it_does_not_know() {
        let base = FlightParams::default();
        let text = "MIS_TAKEOFF_ALT = 4\nNEW_IN_V9 = 3.0\nMPC_XY_P = 99.0\nMPC_Z_P = \"high\"\n";
        let l = ParamStore::parse(text, "old.toml", &base).unwrap();
        assert_eq!(
            l.params.commander.takeoff_alt_m, 4.0,
            "an integer for a float is fine"
        );
        assert_eq!(l.params.position.k_pos_xy, base.position.k_pos_xy);
        assert_eq!(l.params.position.k_pos_z, base.position.k_pos_z);
        let w = l.warnings.join("\n");
        assert!(
            w.contains("old.toml: NEW_IN_V9 is not a parameter of this version"),
            "{w}"
        );
        assert!(w.contains("MPC_XY_P: 99 is outside [0, 5]"), "{w}");
        assert!(w.contains("MPC_Z_P = \"high\" is not a number"), "{w}");
        assert_eq!(l.warnings.len(), 3);
        let written = l.store.to_toml();
        assert!(
            written.contains("NEW_IN_V9 = 3.0"),
            "kept for its version: {written}"
        );
        assert!(
            !written.contains("MPC_XY_P"),
            "a refused value is not kept: {written}"
        );
        let mut cleared = l.store.clone();
        cleared.clear();
        assert_eq!(cleared.names().count(), 0);
        assert!(cleared.to_toml().contains("NEW_IN_V9"));
    }

    #[test]
    fn a_damaged_file_is_an_error_that_names_it() {
        let err = ParamStore::parse(
            "MIS_TAKEOFF_ALT = = 3\n",
            "p.toml",
            &FlightParams::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.starts_with("p.toml:") && err.contains("delete it"),
            "{err}"
        );
    }

    #[test]
    fn the_checksum_is_zlibs_crc32() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    /// A store at `dir/store.toml` holding `MIS_TAKEOFF_ALT = alt`, saved.
    fn save_takeoff_alt(path: &Path, alt: f64) {
        let base = FlightParams::default();
        let mut store = ParamStore::load(path, &base).unwrap().store;
        store.record("MIS_TAKEOFF_ALT", alt);
        store.save().unwrap();
    }

    fn takeoff_alt(loaded: &Loaded) -> f64 {
        loaded.params.commander.takeoff_alt_m
    }

    #[test]
    fn a_saved_store_ends_with_its_checksum_and_keeps_the_one_before_as_the_previous_copy() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("store.toml");
        save_takeoff_alt(&path, 4.0);
        let before = ParamStore::load(&previous_copy(&path), &FlightParams::default()).unwrap();
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
            format!("# checksum: crc32 {:08x}", crc32(body.as_bytes()))
        );

        save_takeoff_alt(&path, 6.0);
        assert_eq!(
            std::fs::read_to_string(previous_copy(&path)).unwrap(),
            first
        );
        let loaded = ParamStore::load(&path, &FlightParams::default()).unwrap();
        assert_eq!(takeoff_alt(&loaded), 6.0);
        assert!(!loaded.from_previous_copy && loaded.warnings.is_empty());
    }

    /// A way a file can be damaged.
    type Damage = fn(&str) -> String;

    #[test]
    fn a_damaged_store_is_replaced_by_its_previous_good_copy_and_the_user_told() {
        let base = FlightParams::default();
        let damages: [(&str, Damage); 6] = [
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
            let loaded = ParamStore::load(&path, &base).unwrap();
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
            store.save().unwrap();
            let prev = std::fs::read_to_string(previous_copy(&path)).unwrap();
            assert!(prev.contains("MIS_TAKEOFF_ALT = 4.0"), "{what}: {prev}");
            let again = ParamStore::load(&path, &base).unwrap();
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
        let first = ParamStore::load(&path, &base).unwrap();
        assert!(first.from_previous_copy);
        assert_eq!(takeoff_alt(&first), base.commander.takeoff_alt_m);
        std::fs::write(previous_copy(&path), "damaged too").unwrap();
        let err = format!("{:#}", ParamStore::load(&path, &base).unwrap_err());
        assert!(
            err.contains("store.toml: damaged: checksum") && err.contains("no good previous copy"),
            "{err}"
        );
        // The way the header says to edit it: without the first and the last line.
        let edited: Vec<&str> = text.lines().collect();
        let edited = edited[1..edited.len() - 1].join("\n").replace("4.0", "5.0");
        std::fs::write(&path, edited).unwrap();
        let loaded = ParamStore::load(&path, &base).unwrap();
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
    /// `saved N` after each save returns, until it is killed. Does nothing unless started so.
    #[test]
    #[ignore = "started by the SIGKILL test in a child process"]
    fn save_until_killed() {
        let Some(dir) = std::env::var_os(CHILD_DIR) else {
            return;
        };
        let path = Path::new(&dir).join("store.toml");
        let loaded = ParamStore::load(&path, &FlightParams::default()).unwrap();
        let mut n = save_number(&loaded).map_or(0, |n| n + 1);
        let mut store = loaded.store;
        loop {
            let k = n % 9000;
            store.record("MIS_TAKEOFF_ALT", 0.5 + k as f64 / 100.0);
            store.record("ATT_ALIGN_N", (1 + k) as f64);
            store.save().unwrap();
            println!("saved {k}");
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
                .args(["records::param_store::tests::save_until_killed", "--exact"])
                .args(["--ignored", "--nocapture", "--test-threads=1"])
                .env(CHILD_DIR, dir.path())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::null())
                .spawn()
                .unwrap();
            let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
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

            let loaded = ParamStore::load(&path, &base)
                .unwrap_or_else(|e| panic!("after kill {kills}: {e:#}"));
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
