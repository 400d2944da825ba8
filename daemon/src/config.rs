//! The daemon's settings: a TOML file (`--config`) under the command line. Every key mirrors a
//! flag; a flag given on the command line wins over the file. A missing file, a key the daemon
//! does not know, a value of the wrong type or out of its range stops the daemon with a message
//! naming the file, the key and what is allowed.

use airframe::ConfigError;
use airframe::config::Violation;
use serde::Deserialize;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

/// `speed` in a file: a factor or "max".
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum SpeedSetting {
    /// Real-time factor.
    Factor(f64),
    /// "max" (or a factor written as a string).
    Name(String),
}

/// The daemon's configuration file. Paths are relative to the file's directory.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    /// Sensor source URL (`sim`, `udp://…`, `serial://…`).
    pub source: Option<String>,
    /// Instance number.
    pub instance: Option<u16>,
    /// Vehicles flown together in the embedded simulator.
    pub count: Option<u16>,
    /// Airframe name or file.
    pub airframe: Option<String>,
    /// Flight parameters file.
    pub params: Option<PathBuf>,
    /// Directory of airframes/ and flight.toml.
    pub params_dir: Option<PathBuf>,
    /// Take-off altitude (m).
    pub takeoff_m: Option<f64>,
    /// Hover time (s).
    pub hover_s: Option<f64>,
    /// Embedded simulator speed.
    pub speed: Option<SpeedSetting>,
    /// Embedded simulator seed.
    pub seed: Option<u64>,
    /// Embedded simulator sensor preset.
    pub sensors: Option<String>,
    /// Truth CSV (embedded simulator).
    pub truth_csv: Option<PathBuf>,
    /// Flight-data CSV.
    pub flight_csv: Option<PathBuf>,
    /// Directory of every run's logs, or `"none"`.
    pub log_dir: Option<PathBuf>,
    /// MAVLink telemetry log.
    pub tlog: Option<PathBuf>,
    /// Rate of the deadline-paced loop (Hz).
    pub loop_hz: Option<f64>,
    /// Spin before each deadline (µs).
    pub loop_spin_us: Option<f64>,
    /// CPU the control loop is pinned to.
    pub loop_cpu: Option<usize>,
    /// Interval of the control loop's timing report (s).
    pub loop_stats_s: Option<f64>,
    /// Ground-station endpoints (URLs), or `["none"]`.
    pub mavlink: Option<Vec<String>>,
    /// File of the parameters changed from a ground station, or `"none"`.
    pub param_store: Option<PathBuf>,
    /// File of the MAVLink signing key (64 hexadecimal digits).
    pub signing_key_file: Option<PathBuf>,
}

/// Allowed take-off altitudes (m).
pub const TAKEOFF_RANGE_M: RangeInclusive<f64> = 1.0..=100.0;
/// Allowed hover times (s).
pub const HOVER_RANGE_S: RangeInclusive<f64> = 0.0..=3600.0;
/// Allowed instance numbers.
pub const INSTANCE_RANGE: RangeInclusive<u16> = 0..=250;
/// Allowed numbers of vehicles flown together (instances `instance` … `instance + count − 1`,
/// all within [`INSTANCE_RANGE`]).
pub const COUNT_RANGE: RangeInclusive<u16> = 1..=251;
/// Allowed rates of the deadline-paced loop (Hz).
pub const LOOP_HZ_RANGE: RangeInclusive<f64> = 50.0..=2000.0;
/// Allowed spins before a deadline (µs).
pub const LOOP_SPIN_RANGE_US: RangeInclusive<f64> = 0.0..=1000.0;
/// Accepted intervals of the control loop's timing report (s).
pub const LOOP_STATS_RANGE_S: RangeInclusive<f64> = 0.5..=3600.0;
/// Allowed real-time factors.
pub const SPEED_RANGE: RangeInclusive<f64> = 0.01..=10_000.0;

impl ConfigFile {
    /// Reads and checks `path`; relative paths in it become relative to its directory.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let mut c: Self = airframe::config::read_toml(path)?;
        let file = path.display().to_string();
        let mut violations = Vec::new();
        let mut bad = |key: &str, reason: String| {
            violations.push(Violation {
                key: key.to_owned(),
                reason,
            })
        };
        for (key, value, range, unit) in [
            ("takeoff_m", c.takeoff_m, &TAKEOFF_RANGE_M, "m"),
            ("hover_s", c.hover_s, &HOVER_RANGE_S, "s"),
            ("loop_hz", c.loop_hz, &LOOP_HZ_RANGE, "Hz"),
            ("loop_spin_us", c.loop_spin_us, &LOOP_SPIN_RANGE_US, "µs"),
            ("loop_stats_s", c.loop_stats_s, &LOOP_STATS_RANGE_S, "s"),
        ] {
            if let Some(x) = value
                && let Err(e) = in_range(x, range, unit)
            {
                bad(key, e);
            }
        }
        if let Some(i) = c.instance
            && !INSTANCE_RANGE.contains(&i)
        {
            bad(
                "instance",
                format!(
                    "{i} is out of range [{}, {}]",
                    INSTANCE_RANGE.start(),
                    INSTANCE_RANGE.end()
                ),
            );
        }
        if let Some(n) = c.count
            && !COUNT_RANGE.contains(&n)
        {
            bad(
                "count",
                format!(
                    "{n} is out of range [{}, {}]",
                    COUNT_RANGE.start(),
                    COUNT_RANGE.end()
                ),
            );
        }
        if let Some(s) = &c.speed
            && let Err(e) = parse_speed(s)
        {
            bad("speed", e);
        }
        if let Some(s) = &c.sensors
            && sitl_core::sensors::SensorPreset::from_name(s).is_none()
        {
            bad(
                "sensors",
                format!("{s:?} is not ideal, typical, noisy or realistic"),
            );
        }
        if !violations.is_empty() {
            return Err(ConfigError::Invalid { file, violations });
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let rebase = |p: &mut Option<PathBuf>| {
            if let Some(p) = p.as_mut()
                && p.is_relative()
            {
                *p = dir.join(&*p);
            }
        };
        rebase(&mut c.params);
        rebase(&mut c.params_dir);
        rebase(&mut c.truth_csv);
        rebase(&mut c.flight_csv);
        rebase(&mut c.tlog);
        if c.log_dir.as_deref() != Some(Path::new("none")) {
            rebase(&mut c.log_dir);
        }
        rebase(&mut c.signing_key_file);
        if c.param_store.as_deref() != Some(Path::new("none")) {
            rebase(&mut c.param_store);
        }
        if let Some(a) = c.airframe.as_mut()
            && a.ends_with(".toml")
            && Path::new(a.as_str()).is_relative()
        {
            *a = dir.join(&*a).display().to_string();
        }
        Ok(c)
    }
}

/// `x` within `range` (unit for the message), or why not.
pub fn in_range(x: f64, range: &RangeInclusive<f64>, unit: &str) -> Result<f64, String> {
    if x.is_finite() && range.contains(&x) {
        Ok(x)
    } else {
        Err(format!(
            "{x} is out of range [{}, {}] {unit}",
            range.start(),
            range.end()
        ))
    }
}

/// A speed setting as a real-time factor (`None`: as fast as lockstep allows).
pub fn parse_speed(s: &SpeedSetting) -> Result<Option<f64>, String> {
    let factor = match s {
        SpeedSetting::Name(n) if n == "max" => return Ok(None),
        SpeedSetting::Name(n) => n
            .parse::<f64>()
            .map_err(|_| format!("{n:?} is neither a factor nor \"max\""))?,
        SpeedSetting::Factor(f) => *f,
    };
    in_range(factor, &SPEED_RANGE, "× real time").map(Some)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn write(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("autopilot-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_good_file_loads_with_paths_beside_it() {
        let p = write(
            "good.toml",
            "source = \"udp://127.0.0.1:4560\"\ntakeoff_m = 8\nspeed = 20\nflight_csv = \"f.csv\"\nairframe = \"hexa_x\"\n",
        );
        let c = ConfigFile::load(&p).unwrap();
        assert_eq!(c.source.as_deref(), Some("udp://127.0.0.1:4560"));
        assert_eq!(c.takeoff_m, Some(8.0));
        assert_eq!(parse_speed(c.speed.as_ref().unwrap()), Ok(Some(20.0)));
        assert_eq!(c.flight_csv, Some(p.parent().unwrap().join("f.csv")));
        assert_eq!(c.airframe.as_deref(), Some("hexa_x"), "a name stays a name");
        let c = ConfigFile::load(&write("max.toml", "speed = \"max\"\n")).unwrap();
        assert_eq!(parse_speed(c.speed.as_ref().unwrap()), Ok(None));
    }

    #[test]
    fn the_shipped_example_loads() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../params/autopilot.toml");
        let c = ConfigFile::load(&p).unwrap();
        assert_eq!(c.source.as_deref(), Some("sim"));
        assert!(
            c.params_dir
                .unwrap()
                .join("airframes/quad_x.toml")
                .is_file()
        );
    }

    #[test]
    fn bad_files_name_the_file_the_key_and_the_range() {
        let missing = std::env::temp_dir().join("autopilot-no-such-config.toml");
        let e = ConfigFile::load(&missing).unwrap_err().to_string();
        assert!(
            e.contains("autopilot-no-such-config.toml") && e.contains("cannot read"),
            "{e}"
        );
        for (name, text, says) in [
            ("unknown.toml", "takeof_m = 5\n", "unknown field `takeof_m`"),
            ("type.toml", "takeoff_m = \"high\"\n", "takeoff_m"),
            (
                "range.toml",
                "takeoff_m = 500\n",
                "`takeoff_m`: 500 is out of range [1, 100] m",
            ),
            (
                "hover.toml",
                "hover_s = -1\n",
                "`hover_s`: -1 is out of range [0, 3600] s",
            ),
            (
                "inst.toml",
                "instance = 300\n",
                "`instance`: 300 is out of range [0, 250]",
            ),
            (
                "speed.toml",
                "speed = \"fast\"\n",
                "`speed`: \"fast\" is neither",
            ),
            ("zero.toml", "speed = 0\n", "`speed`: 0 is out of range"),
            (
                "loop.toml",
                "loop_hz = 5000\n",
                "`loop_hz`: 5000 is out of range [50, 2000] Hz",
            ),
            (
                "spin.toml",
                "loop_spin_us = -3\n",
                "`loop_spin_us`: -3 is out of range [0, 1000] µs",
            ),
            (
                "sensors.toml",
                "sensors = \"perfect\"\n",
                "`sensors`: \"perfect\" is not",
            ),
            ("syntax.toml", "takeoff_m = = 5\n", "syntax.toml"),
        ] {
            let e = ConfigFile::load(&write(name, text))
                .unwrap_err()
                .to_string();
            assert!(e.contains(name), "{name}: names the file: {e}");
            assert!(e.contains(says), "{name}: {e}");
        }
    }
}
