//! The parameters a ground station changed, kept across restarts.
//!
//! `params/flight.toml` holds the tuning a user edits by hand; a ground station's `PARAM_SET`
//! lands here instead, in a small TOML file of MAVLink names and values (as PX4 saves only
//! what differs from its defaults), applied over `flight.toml` at start:
//!
//! ```toml
//! MIS_TAKEOFF_ALT = 10.0
//! ATT_ALIGN_N = 400
//! ```
//!
//! The file is written whole and atomically (a temporary file beside it, flushed to disk, then
//! renamed over it), so a crash leaves the old or the new version, never a mix. A file from
//! another version of the daemon loads with warnings: a name this version does not know is
//! kept (written back untouched, so a downgrade loses nothing); a value this version refuses is
//! dropped and the `flight.toml` value flown. A name the file does not hold is not a fault: it
//! keeps its `flight.toml` value.

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

/// A store read at start: the store, the parameters to fly with, and what to warn about.
#[derive(Debug)]
pub struct Loaded {
    /// The store.
    pub store: ParamStore,
    /// `base` with the stored changes applied.
    pub params: FlightParams,
    /// One line per name this version does not know and per value it refuses.
    pub warnings: Vec<String>,
}

impl ParamStore {
    /// A store that is never written.
    pub fn in_memory() -> Self {
        Self::default()
    }

    /// Reads the store at `path` (a missing file is an empty store) and applies it to `base`.
    /// A file that is not TOML is an error that names it: flying with half of what the user
    /// set is worse than not starting.
    pub fn load(path: &Path, base: &FlightParams) -> Result<Loaded> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let mut loaded = Self::parse(&text, &path.display().to_string(), base)?;
        loaded.store.path = Some(path.to_path_buf());
        Ok(loaded)
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
            "# Parameters changed from a ground station, applied over flight.toml at start.\n\
             # Written by autopilot {} (atomically: edit it with the daemon stopped).\n",
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
        text
    }

    /// Writes the store to its file, atomically; nothing to do without a file.
    pub fn save(&self) -> Result<()> {
        match &self.path {
            Some(path) => write_atomically(path, &self.to_toml()),
            None => Ok(()),
        }
    }
}

/// Replaces `path` with `text` so that a crash at any moment leaves either the old file or the
/// new one: write a temporary file in the same directory, flush it to the disk, rename it over
/// `path`, and flush the directory entry.
pub fn write_atomically(path: &Path, text: &str) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .with_context(|| format!("{} is not a file name", path.display()))?;
    let tmp = dir.join(format!(".{}.tmp", name.to_string_lossy()));
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
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
}
