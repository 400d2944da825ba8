//! Configuration errors that name the file, the key and the reason, and the helpers that
//! produce them for any TOML file of the project.

use std::fmt;

/// A configuration file (airframe, scenario) that cannot be used.
///
/// Every variant carries the file so that a user with several files open knows which one to fix.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{file}: cannot read: {reason}")]
    Io {
        /// Path of the file as given.
        file: String,
        /// The operating system's reason.
        reason: String,
    },
    /// The TOML did not parse or did not match the schema (unknown key, missing field, wrong type).
    #[error("{file}: {reason}")]
    Parse {
        /// Path of the file as given.
        file: String,
        /// The parser's message, which names the key and the line.
        reason: String,
    },
    /// One or more values parsed but are not acceptable.
    #[error("{file}: {}", Violations(.violations))]
    Invalid {
        /// Path of the file as given.
        file: String,
        /// Every violation found, not just the first.
        violations: Vec<Violation>,
    },
}

/// One rejected value: which key and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// Dotted key path, e.g. `rotors[3].k_t`.
    pub key: String,
    /// Why the value is refused, including the allowed range where there is one.
    pub reason: String,
}

struct Violations<'a>(&'a [Violation]);

impl fmt::Display for Violations<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, v) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "`{}`: {}", v.key, v.reason)?;
        }
        Ok(())
    }
}

/// Collects every violation while validating a parsed file.
#[derive(Debug, Default)]
pub struct Checker {
    /// Violations found so far.
    pub violations: Vec<Violation>,
}

impl Checker {
    /// Records a violation.
    pub fn fail(&mut self, key: impl Into<String>, reason: impl Into<String>) {
        self.violations.push(Violation {
            key: key.into(),
            reason: reason.into(),
        });
    }

    /// A finite value strictly greater than zero.
    pub fn positive(&mut self, key: impl Into<String>, v: f64) {
        if !(v.is_finite() && v > 0.0) {
            self.fail(key, format!("must be a finite number > 0, got {v}"));
        }
    }

    /// A finite value greater than or equal to zero.
    pub fn non_negative(&mut self, key: impl Into<String>, v: f64) {
        if !(v.is_finite() && v >= 0.0) {
            self.fail(key, format!("must be a finite number >= 0, got {v}"));
        }
    }

    /// A finite value inside `[lo, hi]`.
    pub fn within(&mut self, key: impl Into<String>, v: f64, lo: f64, hi: f64) {
        if !(v.is_finite() && v >= lo && v <= hi) {
            self.fail(key, format!("must be within [{lo}, {hi}], got {v}"));
        }
    }

    /// Every component finite.
    pub fn finite(&mut self, key: impl Into<String>, v: &[f64]) {
        if v.iter().any(|x| !x.is_finite()) {
            self.fail(key, "must be finite");
        }
    }

    /// `Ok` when nothing was found, else every violation for `file`.
    pub fn finish(self, file: &str) -> Result<(), ConfigError> {
        if self.violations.is_empty() {
            Ok(())
        } else {
            Err(ConfigError::Invalid {
                file: file.to_owned(),
                violations: self.violations,
            })
        }
    }
}

/// Reads and deserialises a TOML file, naming the file in any error.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &std::path::Path) -> Result<T, ConfigError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Io {
        file: file.clone(),
        reason: e.to_string(),
    })?;
    parse_toml(&text, &file)
}

/// Deserialises TOML text; `file` names its origin in errors.
pub fn parse_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    file: &str,
) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError::Parse {
        file: file.to_owned(),
        reason: e.to_string().trim_end().replace('\n', " | "),
    })
}

/// The parameter directory: `given`, else `./params` when it holds `airframes/`, else the one
/// installed beside the running binary (`<prefix>/bin/autopilot` reads
/// `<prefix>/share/autopilot/params`, as the Python wheel and `make install`-style layouts put
/// it), else the source tree's `params/` (so the binaries run from anywhere in a checkout).
pub fn params_dir(given: Option<&std::path::Path>) -> std::path::PathBuf {
    if let Some(d) = given {
        return d.to_path_buf();
    }
    let local = std::path::PathBuf::from("params");
    if local.join("airframes").is_dir() {
        return local;
    }
    if let Some(installed) = installed_params_dir()
        && installed.join("airframes").is_dir()
    {
        return installed;
    }
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params")
}

/// `<prefix>/share/autopilot/params` for a binary at `<prefix>/bin/`.
fn installed_params_dir() -> Option<std::path::PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let prefix = exe.parent()?.parent()?;
    Some(prefix.join("share").join("autopilot").join("params"))
}
