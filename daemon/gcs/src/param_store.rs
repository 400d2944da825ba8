//! The parameters a ground station changed, as the store keeps them: the changes, the text of
//! the file they are saved in, and its checksum. Reading and writing the file (atomically, with
//! a previous good copy) is the binary's `records::param_file`.
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
//! Its last line is a CRC-32 (zlib's) of everything before it, so a file damaged after it was
//! written (a bad sector, a truncating copy, an edit that forgot the line) is recognised
//! ([`checked_text`]). A file without the checksum line (written by hand, or by an older
//! version) is taken as it is. A file from another version of the daemon loads with warnings: a
//! name this version does not know is kept (written back untouched, so a downgrade loses
//! nothing); a value this version refuses is dropped and the `flight.toml` value flown. A name
//! the file does not hold is not a fault: it keeps its `flight.toml` value.

use flight_core::params::FlightParams;
use std::collections::BTreeMap;
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
    pub fn kept_in(mut self, path: &Path) -> Self {
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

    /// The store in `text` applied to `base`; `origin` names it in messages. A value this
    /// version refuses, or a name it does not know, is a warning; text that is not TOML is an
    /// error.
    pub fn parse(text: &str, origin: &str, base: &FlightParams) -> Result<Loaded, NotToml> {
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| NotToml {
            origin: origin.to_owned(),
            detail: e.to_string().trim_end().replace('\n', " | "),
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
            // The workspace's version, which every crate of it shares.
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
}

/// The first line of a saved store: it ends with a checksum line (a file cut short loses it).
pub const CHECKSUMMED: &str = "# autopilot parameter store (checksummed)";
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
/// begin with [`CHECKSUMMED`] (written by hand or by an older version) needs none; an empty
/// one is damage (a missing file, not an empty one, is an empty store).
pub fn checked_text(bytes: Vec<u8>) -> Result<String, Damage> {
    let text = String::from_utf8(bytes).map_err(|_| Damage::NotUtf8)?;
    verify(&text)?;
    Ok(text)
}

/// [`checked_text`]'s check.
fn verify(text: &str) -> Result<(), Damage> {
    // A saved store always holds its first line: an empty file was cut short.
    if text.trim().is_empty() {
        return Err(Damage::Empty(text.len()));
    }
    let body_end = text.trim_end_matches('\n').rfind('\n').map_or(0, |i| i + 1);
    let last = text[body_end..].trim_end();
    let Some(sum) = last.strip_prefix(CHECKSUM_PREFIX) else {
        // Ours (its first line, or a file cut short inside it), or a checksum line not last.
        let ours = text.starts_with(CHECKSUMMED) || CHECKSUMMED.starts_with(text);
        return if ours || text.contains(CHECKSUM_PREFIX) {
            Err(Damage::ChecksumNotLast)
        } else {
            Ok(())
        };
    };
    let expected =
        u32::from_str_radix(sum, 16).map_err(|_| Damage::ChecksumUnreadable(sum.to_owned()))?;
    let actual = crc32(&text.as_bytes()[..body_end]);
    if actual == expected {
        Ok(())
    } else {
        Err(Damage::ChecksumWrong { actual, expected })
    }
}

/// CRC-32 as zlib and PNG compute it (`crc32fast`): `python3 -c "import zlib;
/// print(hex(zlib.crc32(open(f, 'rb').read())))"` on the text before the checksum line gives the
/// same number.
fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

/// Text that is not TOML: the store cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{origin}: {detail} (fix it, or delete it to fly with flight.toml's values)")]
pub struct NotToml {
    /// The file (or other source) named in the message.
    pub origin: String,
    /// What the TOML parser said, on one line.
    pub detail: String,
}

/// The store's file could not be read again: the reason, as the daemon's file layer says it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct Unreadable(pub String);

/// What is wrong with a saved store's text ([`checked_text`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Damage {
    /// Nothing but blanks (a file truncated to nothing): every saved value would be lost.
    #[error("damaged: empty ({0} bytes)")]
    Empty(usize),
    /// The bytes are not UTF-8.
    #[error("damaged: not UTF-8 text")]
    NotUtf8,
    /// Ours, but the checksum line is missing or not last.
    #[error("damaged: its checksum line is not its last (cut short, or appended to?)")]
    ChecksumNotLast,
    /// The checksum line holds no hexadecimal number.
    #[error("checksum {0:?} unreadable")]
    ChecksumUnreadable(String),
    /// The checksum disagrees with the text.
    #[error(
        "damaged: checksum {actual:08x} where the file says {expected:08x} (edited by hand? delete the checksum line to accept an edit)"
    )]
    ChecksumWrong {
        /// The text's CRC-32.
        actual: u32,
        /// The file's checksum line.
        expected: u32,
    },
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

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
}
