//! The settings of a flight, in one type ([`Settings`]): the defaults, then the `--config` TOML
//! file read into it (every key a field; paths relative to the file's directory), then each flag
//! given on the command line ([`FlightArgs`]) over its field. A missing file, a key the daemon
//! does not know, a value of the wrong type or out of its range stops the daemon with a message
//! naming the file, the key and what is allowed; a flag out of its range, naming the flag.

use crate::cli::FlightArgs;
use airframe::ConfigError;
use airframe::config::Violation;
use anyhow::{Result, bail};
use serde::Deserialize;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

/// The embedded simulator's sensor preset named `name` (`--sensors`).
pub fn sensor_preset(name: &str) -> Result<sitl_core::sensors::SensorPreset> {
    sitl_core::sensors::SensorPreset::from_name(name).ok_or_else(|| {
        anyhow::anyhow!(
            "--sensors must be ideal, typical, noisy, realistic or uncalibrated, got {name:?}"
        )
    })
}
/// `speed`: a real-time factor, or "max".
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum SpeedSetting {
    /// Real-time factor.
    Factor(f64),
    /// "max" (or a factor written as a string).
    Name(String),
}

impl SpeedSetting {
    /// The real-time factor (`None`: as fast as lockstep allows), or why not.
    pub fn factor(&self) -> Result<Option<f64>, String> {
        let factor = match self {
            Self::Name(n) if n == "max" => return Ok(None),
            Self::Name(n) => n
                .parse::<f64>()
                .map_err(|_| format!("{n:?} is neither a factor nor \"max\""))?,
            Self::Factor(f) => *f,
        };
        in_range(factor, &SPEED_RANGE, "× real time").map(Some)
    }
}

/// The settings of a flight. As a `--config` file, each field is a key; a key not given keeps
/// its default (that of the flag of the same meaning, `autopilot --help`).
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Settings {
    /// Sensor source URL (`sim`, `udp://…`, `json://…`, `serial://…`); a flight needs one.
    pub source: Option<String>,
    /// A GPS receiver's serial port URL (`serial://…`), instead of the source's GPS.
    pub gps: Option<String>,
    /// An RC receiver's serial port URL (`serial://…?protocol=crsf|sbus`).
    pub rc: Option<String>,
    /// Instance number.
    pub instance: u16,
    /// Vehicles flown together in the embedded simulator.
    pub count: u16,
    /// Airframe name or file.
    pub airframe: String,
    /// Flight parameters file (none: PARAMS_DIR/flight.toml).
    pub params: Option<PathBuf>,
    /// Directory of airframes/ and flight.toml (none: ./params, else the source tree's).
    pub params_dir: Option<PathBuf>,
    /// Take-off altitude (m); none: wait for a ground station.
    pub takeoff_m: Option<f64>,
    /// Hover time (s).
    pub hover_s: f64,
    /// Embedded simulator speed.
    pub speed: SpeedSetting,
    /// Embedded simulator seed.
    pub seed: u64,
    /// Embedded simulator sensor preset.
    pub sensors: String,
    /// Truth CSV (embedded simulator).
    pub truth_csv: Option<PathBuf>,
    /// Scenario whose world the embedded simulator flies (wind, start, battery, events).
    pub scenario: Option<PathBuf>,
    /// The embedded simulator's own MAVLink endpoint (UDP address; the port offset by the
    /// instance): weather, clock and truth.
    pub sim_control: Option<String>,
    /// The embedded simulator starts paused (its clock set on `sim_control`).
    pub paused: bool,
    /// Flight-data CSV (none: `LOG_DIR/<start time>.csv`).
    pub flight_csv: Option<PathBuf>,
    /// Directory of every run's logs, or `"none"` (none given: `logs`); see [`Self::log_dir`].
    pub log_dir: Option<PathBuf>,
    /// MAVLink telemetry log (none: `LOG_DIR/<start time>.tlog`).
    pub tlog: Option<PathBuf>,
    /// ULog flight log (none: `LOG_DIR/<start time>.ulg`).
    pub ulog: Option<PathBuf>,
    /// The directory MAVLink FTP serves, or `"none"` (none given: the log directory); see
    /// [`Self::ftp_root`].
    pub ftp_root: Option<PathBuf>,
    /// MAVLink FTP may not change files.
    pub ftp_read_only: bool,
    /// Rate of the deadline-paced loop (Hz).
    pub loop_hz: f64,
    /// Spin before each deadline (µs).
    pub loop_spin_us: f64,
    /// CPU the control loop is pinned to.
    pub loop_cpu: Option<usize>,
    /// Interval of the control loop's timing report (s).
    pub loop_stats_s: f64,
    /// Ground-station endpoints (URLs), or `["none"]`.
    pub mavlink: Vec<String>,
    /// File of the parameters changed from a ground station, or `"none"` (none given: one per
    /// instance); see [`Self::param_store`].
    pub param_store: Option<PathBuf>,
    /// File of the MAVLink signing key (64 hexadecimal digits).
    pub signing_key_file: Option<PathBuf>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            source: None,
            gps: None,
            rc: None,
            instance: 0,
            count: 1,
            airframe: "quad_x".into(),
            params: None,
            params_dir: None,
            takeoff_m: None,
            hover_s: 10.0,
            speed: SpeedSetting::Factor(1.0),
            seed: 1,
            sensors: "typical".into(),
            truth_csv: None,
            scenario: None,
            sim_control: None,
            paused: false,
            flight_csv: None,
            log_dir: None,
            tlog: None,
            ulog: None,
            ftp_root: None,
            ftp_read_only: false,
            loop_hz: 1000.0,
            loop_spin_us: 150.0,
            loop_cpu: None,
            loop_stats_s: 10.0,
            mavlink: crate::gcs_links::DEFAULT_ENDPOINTS
                .iter()
                .map(|s| s.to_string())
                .collect(),
            param_store: None,
            signing_key_file: None,
        }
    }
}

/// Allowed take-off altitudes (m).
pub const TAKEOFF_RANGE_M: RangeInclusive<f64> = 1.0..=100.0;
/// Allowed hover times (s).
pub const HOVER_RANGE_S: RangeInclusive<f64> = 0.0..=604_800.0;
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

impl Settings {
    /// The defaults, then the `--config` file if one is named, then every flag given.
    pub fn resolve(flags: &FlightArgs) -> Result<Self> {
        let mut settings = match &flags.config {
            Some(path) => Self::load(path)?,
            None => Self::default(),
        };
        settings.apply_flags(flags)?;
        Ok(settings)
    }

    /// Reads and checks the settings file `path` (the defaults for the keys it does not give);
    /// relative paths in it become relative to its directory.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let mut s: Self = airframe::config::read_toml(path)?;
        s.check(&path.display().to_string())?;
        s.rebase(path.parent().unwrap_or(Path::new(".")));
        Ok(s)
    }

    /// Every value out of its range, each under its key.
    fn check(&self, file: &str) -> Result<(), ConfigError> {
        let mut violations = Vec::new();
        let mut bad = |key: &str, reason: String| {
            violations.push(Violation {
                key: key.to_owned(),
                reason,
            })
        };
        for (key, value, range, unit) in [
            ("takeoff_m", self.takeoff_m, &TAKEOFF_RANGE_M, "m"),
            ("hover_s", Some(self.hover_s), &HOVER_RANGE_S, "s"),
            ("loop_hz", Some(self.loop_hz), &LOOP_HZ_RANGE, "Hz"),
            (
                "loop_spin_us",
                Some(self.loop_spin_us),
                &LOOP_SPIN_RANGE_US,
                "µs",
            ),
            (
                "loop_stats_s",
                Some(self.loop_stats_s),
                &LOOP_STATS_RANGE_S,
                "s",
            ),
        ] {
            if let Some(x) = value
                && let Err(e) = in_range(x, range, unit)
            {
                bad(key, e);
            }
        }
        for (key, n, range) in [
            ("instance", self.instance, &INSTANCE_RANGE),
            ("count", self.count, &COUNT_RANGE),
        ] {
            if !range.contains(&n) {
                let (lo, hi) = (range.start(), range.end());
                bad(key, format!("{n} is out of range [{lo}, {hi}]"));
            }
        }
        if let Err(e) = self.speed.factor() {
            bad("speed", e);
        }
        if sitl_core::sensors::SensorPreset::from_name(&self.sensors).is_none() {
            let s = &self.sensors;
            bad(
                "sensors",
                format!("{s:?} is not ideal, typical, noisy, realistic or uncalibrated"),
            );
        }
        if violations.is_empty() {
            Ok(())
        } else {
            Err(ConfigError::Invalid {
                file: file.to_owned(),
                violations,
            })
        }
    }

    /// Makes the relative paths of a file relative to its directory `dir` (but a log directory,
    /// flight-data CSV or parameter store `"none"`, and an airframe given by name).
    fn rebase(&mut self, dir: &Path) {
        let rebase = |p: &mut Option<PathBuf>| {
            if let Some(p) = p.as_mut()
                && p.is_relative()
            {
                *p = dir.join(&*p);
            }
        };
        rebase(&mut self.params);
        rebase(&mut self.params_dir);
        rebase(&mut self.truth_csv);
        rebase(&mut self.scenario);
        if self.flight_csv.as_deref() != Some(Path::new("none")) {
            rebase(&mut self.flight_csv);
        }
        rebase(&mut self.tlog);
        rebase(&mut self.ulog);
        if self.ftp_root.as_deref() != Some(Path::new("none")) {
            rebase(&mut self.ftp_root);
        }
        if self.log_dir.as_deref() != Some(Path::new("none")) {
            rebase(&mut self.log_dir);
        }
        rebase(&mut self.signing_key_file);
        if self.param_store.as_deref() != Some(Path::new("none")) {
            rebase(&mut self.param_store);
        }
        if self.airframe.ends_with(".toml") && Path::new(&self.airframe).is_relative() {
            self.airframe = dir.join(&self.airframe).display().to_string();
        }
    }

    /// Sets every field whose flag was given; a number out of its range is refused, naming the
    /// flag.
    fn apply_flags(&mut self, f: &FlightArgs) -> Result<()> {
        if f.sim {
            self.source = Some("sim".to_owned());
        } else if let Some(s) = &f.source {
            self.source = Some(s.clone());
        }
        if self.source.is_none() {
            bail!(
                "no sensor source: give --sim to fly the embedded simulator, or --source udp://127.0.0.1:4560 for a simulator process (or source = ... in a --config file)"
            );
        }
        let number = |x: f64, flag: &str, range, unit| {
            in_range(x, range, unit).map_err(|e| anyhow::anyhow!("--{flag}: {e}"))
        };
        if let Some(x) = f.takeoff {
            self.takeoff_m = Some(number(x, "takeoff", &TAKEOFF_RANGE_M, "m")?);
        }
        if let Some(x) = f.hover {
            self.hover_s = number(x, "hover", &HOVER_RANGE_S, "s")?;
        }
        if let Some(s) = &f.speed {
            let speed = SpeedSetting::Name(s.clone());
            speed
                .factor()
                .map_err(|e| anyhow::anyhow!("--speed: {e}"))?;
            self.speed = speed;
        }
        if let Some(x) = f.loop_hz {
            self.loop_hz = number(x, "loop-hz", &LOOP_HZ_RANGE, "Hz")?;
        }
        if let Some(x) = f.loop_spin_us {
            self.loop_spin_us = number(x, "loop-spin-us", &LOOP_SPIN_RANGE_US, "µs")?;
        }
        if let Some(x) = f.loop_stats_s {
            self.loop_stats_s = number(x, "loop-stats-s", &LOOP_STATS_RANGE_S, "s")?;
        }
        if let Some(g) = &f.gps {
            crate::devices::GpsSpec::parse(g)?;
            self.gps = Some(g.clone());
        }
        if let Some(r) = &f.rc {
            crate::devices::RcSpec::parse(r)?;
            self.rc = Some(r.clone());
        }
        // Checked by the parser: instance and count in their ranges. Checked where used: the
        // sensor preset (an external simulator has none).
        let given = |flag: &Option<PathBuf>, field: &mut Option<PathBuf>| {
            if flag.is_some() {
                field.clone_from(flag);
            }
        };
        given(&f.params, &mut self.params);
        given(&f.params_dir, &mut self.params_dir);
        given(&f.truth_csv, &mut self.truth_csv);
        given(&f.scenario, &mut self.scenario);
        if let Some(a) = &f.sim_control {
            self.sim_control = Some(a.clone());
        }
        self.paused |= f.paused;
        if self.paused && self.sim_control.is_none() {
            bail!("--paused needs --sim-control: its SIM_PAUSE is what starts the clock");
        }
        given(&f.flight_csv, &mut self.flight_csv);
        given(&f.log_dir, &mut self.log_dir);
        given(&f.tlog, &mut self.tlog);
        given(&f.ulog, &mut self.ulog);
        given(&f.ftp_root, &mut self.ftp_root);
        self.ftp_read_only |= f.ftp_read_only;
        given(&f.param_store, &mut self.param_store);
        given(&f.signing_key_file, &mut self.signing_key_file);
        self.instance = f.instance.unwrap_or(self.instance);
        self.count = f.count.unwrap_or(self.count);
        self.seed = f.seed.unwrap_or(self.seed);
        self.loop_cpu = f.loop_cpu.or(self.loop_cpu);
        if let Some(a) = &f.airframe {
            self.airframe.clone_from(a);
        }
        if let Some(s) = &f.sensors {
            self.sensors.clone_from(s);
        }
        if !f.mavlink.is_empty() {
            self.mavlink.clone_from(&f.mavlink);
        }
        let last = usize::from(self.instance) + usize::from(self.count) - 1;
        if last > usize::from(*INSTANCE_RANGE.end()) {
            bail!(
                "--count {} from instance {} goes past the last instance, {}",
                self.count,
                self.instance,
                INSTANCE_RANGE.end()
            );
        }
        Ok(())
    }

    /// The sensor source URL ([`Self::resolve`] refuses settings without one).
    pub fn source(&self) -> &str {
        self.source.as_deref().unwrap_or_default()
    }

    /// The embedded simulator's real-time factor (`None`: as fast as lockstep allows).
    pub fn realtime_factor(&self) -> Result<Option<f64>> {
        // Checked when the file was read or the flag applied.
        self.speed.factor().map_err(anyhow::Error::msg)
    }

    /// The directory of every run's logs (`None`: no logs but those named).
    pub fn log_dir(&self) -> Option<&Path> {
        match self.log_dir.as_deref() {
            Some(p) if p == Path::new("none") => None,
            Some(p) => Some(p),
            None => Some(Path::new("logs")),
        }
    }

    /// The directory MAVLink FTP serves: the one given, else the log directory (none: FTP
    /// refuses every request).
    pub fn ftp_root(&self) -> Option<&Path> {
        match self.ftp_root.as_deref() {
            Some(p) if p == Path::new("none") => None,
            Some(p) => Some(p),
            None => self.log_dir(),
        }
    }

    /// Instance `instance`'s parameter store (none: in memory only).
    pub fn param_store(&self, instance: u16) -> Option<PathBuf> {
        match self.param_store.as_deref() {
            Some(p) if p == Path::new("none") => None,
            Some(p) => Some(p.to_path_buf()),
            None => Some(PathBuf::from(format!("autopilot-params-{instance}.toml"))),
        }
    }

    /// The one parameter-store file named for every instance, if one is (not `none`).
    pub fn named_param_store(&self) -> Option<&Path> {
        self.param_store
            .as_deref()
            .filter(|p| *p != Path::new("none"))
    }

    /// The directory of airframes/ and flight.toml.
    pub fn params_dir(&self) -> PathBuf {
        airframe::config::params_dir(self.params_dir.as_deref())
    }

    /// The flight parameters file.
    pub fn params_path(&self) -> PathBuf {
        params_path(self.params.as_deref(), &self.params_dir())
    }

    /// The airframe file.
    pub fn airframe_path(&self) -> PathBuf {
        airframe_path(&self.airframe, &self.params_dir())
    }
}

/// The airframe file of `airframe`: itself when it names a `.toml` file, else
/// `params_dir/airframes/<airframe>.toml`.
pub fn airframe_path(airframe: &str, params_dir: &Path) -> PathBuf {
    if airframe.ends_with(".toml") {
        PathBuf::from(airframe)
    } else {
        params_dir
            .join("airframes")
            .join(format!("{airframe}.toml"))
    }
}

/// The flight parameters file: `params` if given, else `params_dir/flight.toml`.
pub fn params_path(params: Option<&Path>, params_dir: &Path) -> PathBuf {
    params.map_or_else(|| params_dir.join("flight.toml"), Path::to_path_buf)
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

#[cfg(test)]
mod tests;
