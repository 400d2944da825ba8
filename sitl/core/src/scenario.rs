//! Scenario files: which airframe, where it starts, the weather, the sensors, the seed, how long,
//! timed events (faults, disturbances), and optionally an open-loop actuator script.
//!
//! ```toml
//! airframe = "quad_x"          # a name in params/airframes/, or a path ending in .toml
//! seed = 7
//! duration_s = 20.0
//! rate_hz = 1000.0             # physics rate
//! integrator = "rk4"           # rk4 | exp_map | hypersphere | euler_cromer | second_derivative
//! sensors = "typical"          # ideal | typical | noisy | realistic | uncalibrated
//! calibration_hand = true      # a hand does what the autopilot's calibrations ask
//! [initial]
//! position_ned_m = [0.0, 0.0, 0.0]
//! attitude_euler_deg = [0.0, 0.0, 90.0]   # roll, pitch, yaw
//! [wind]
//! mean_ned_m_s = [3.0, 0.0, 0.0]
//! turbulence_w20_m_s = 7.7
//! roughness_m = 0.03            # optional: a surface layer, the mean wind being that at 10 m
//! [battery]                   # the airframe's pack, changed
//! charge = 0.3                 # at the start (0–1)
//! capacity_mah = 500.0
//! [[events]]
//! t_s = 5.0
//! kind = "motor_fail"
//! motor = 1                    # 1-based, as MAVLink numbers motors
//! [[open_loop]]
//! t_s = 0.0
//! hover_delta = 0.05           # or: throttle = 0.6, or: controls = [..]
//! [[pilot]]                    # an RC transmitter's sticks and switch (pilot.rs)
//! t_s = 8.0
//! throttle = 0.7
//! ```

use crate::airframe::Airframe;
use crate::body::{BodyState, Integrator};
use crate::environment::WindConfig;
use crate::sensors::{EarthField, SensorConfig, SensorKind, SensorPreset};
use crate::sim::{Event, SimConfig};
use ::airframe::config::{Checker, ConfigError, parse_toml, read_toml};
use nalgebra::{UnitQuaternion, Vector3};
use navmath::geo::LatLonAlt;
use serde::Deserialize;
use std::path::{Path, PathBuf};

mod pilot;
pub use pilot::{PilotInput, PilotScript};

mod events;
use events::resolve_event;

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct InitialFile {
    #[serde(default)]
    position_ned_m: [f64; 3],
    #[serde(default)]
    velocity_ned_m_s: [f64; 3],
    #[serde(default)]
    attitude_euler_deg: [f64; 3],
    #[serde(default)]
    rate_frd_rad_s: [f64; 3],
    /// Start with the rotors already at hover speed (for scenarios that start in the air).
    #[serde(default)]
    rotors_at_hover: bool,
}

/// The `[battery]` table: the airframe's pack as charged and, optionally, of another capacity.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct BatteryFile {
    charge: Option<f64>,
    capacity_mah: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum EventFile {
    MotorFail {
        t_s: f64,
        motor: usize,
    },
    MotorThrust {
        t_s: f64,
        motor: usize,
        effectiveness: f64,
    },
    MotorRestore {
        t_s: f64,
        motor: usize,
    },
    SensorOff {
        t_s: f64,
        sensor: SensorKind,
        duration_s: Option<f64>,
    },
    SensorStuck {
        t_s: f64,
        sensor: SensorKind,
        duration_s: Option<f64>,
    },
    GpsFixLoss {
        t_s: f64,
        duration_s: Option<f64>,
    },
    MagDisturbance {
        t_s: f64,
        field_ned_gauss: [f64; 3],
        duration_s: Option<f64>,
    },
    ForcePulse {
        t_s: f64,
        force_ned_n: [f64; 3],
        duration_s: f64,
    },
    TorquePulse {
        t_s: f64,
        torque_frd_n_m: [f64; 3],
        duration_s: f64,
    },
    Gust {
        t_s: f64,
        peak_ned_m_s: [f64; 3],
        duration_s: f64,
    },
    Wind {
        t_s: f64,
        mean_ned_m_s: [f64; 3],
        #[serde(default)]
        turbulence_w20_m_s: f64,
    },
    Tumble {
        t_s: f64,
        duration_s: f64,
    },
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct OpenLoopFile {
    t_s: f64,
    throttle: Option<f64>,
    hover_delta: Option<f64>,
    controls: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    airframe: String,
    #[serde(default = "default_seed")]
    seed: u64,
    duration_s: f64,
    #[serde(default = "default_rate")]
    rate_hz: f64,
    #[serde(default)]
    integrator: Integrator,
    #[serde(default)]
    sensors: SensorPreset,
    #[serde(default = "default_calibration_hand")]
    calibration_hand: bool,
    #[serde(default)]
    home: Option<LatLonAlt>,
    #[serde(default)]
    earth_field: Option<EarthField>,
    #[serde(default)]
    initial: InitialFile,
    #[serde(default)]
    wind: WindConfig,
    #[serde(default)]
    battery: BatteryFile,
    #[serde(default)]
    events: Vec<EventFile>,
    #[serde(default)]
    open_loop: Vec<OpenLoopFile>,
    #[serde(default)]
    pilot: Vec<pilot::PilotFile>,
}

fn default_seed() -> u64 {
    1
}

fn default_calibration_hand() -> bool {
    true
}

fn default_rate() -> f64 {
    1000.0
}

/// One segment of an open-loop actuator script, in force from `t_s` until the next.
#[derive(Debug, Clone, PartialEq)]
pub enum OpenLoopCommand {
    /// The same command on every rotor.
    Throttle(f64),
    /// The hover commands (at the battery voltage of the moment) plus a delta on every rotor.
    HoverDelta(f64),
    /// One command per rotor.
    Controls(Vec<f64>),
}

/// A loaded, validated scenario.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// The airframe to fly.
    pub airframe: Airframe,
    /// Simulation settings.
    pub sim: SimConfig,
    /// Initial rigid-body state.
    pub initial: BodyState,
    /// Start with rotors at hover speed.
    pub rotors_at_hover: bool,
    /// How long to run (s).
    pub duration_s: f64,
    /// Timed events, motor numbers converted to indices.
    pub events: Vec<Event>,
    /// Open-loop script, sorted by time; empty when an autopilot flies.
    pub open_loop: Vec<(f64, OpenLoopCommand)>,
    /// The pilot's script for a simulated RC transmitter.
    pub pilot: PilotScript,
}

impl Scenario {
    /// Loads a scenario file; airframe names are looked up in `airframe_dir`.
    pub fn load(path: &Path, airframe_dir: &Path) -> Result<Self, ConfigError> {
        let raw: ScenarioFile = read_toml(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::resolve(raw, &path.display().to_string(), base, airframe_dir)
    }

    /// Parses scenario TOML text; `origin` names it in errors.
    pub fn from_toml_str(
        text: &str,
        origin: &str,
        airframe_dir: &Path,
    ) -> Result<Self, ConfigError> {
        let raw: ScenarioFile = parse_toml(text, origin)?;
        Self::resolve(raw, origin, Path::new("."), airframe_dir)
    }

    /// A scenario with defaults: the airframe landed at home, typical sensors, no wind.
    pub fn basic(airframe: Airframe, duration_s: f64) -> Self {
        Self {
            airframe,
            sim: SimConfig::default(),
            initial: BodyState::default(),
            rotors_at_hover: false,
            duration_s,
            events: Vec::new(),
            open_loop: Vec::new(),
            pilot: PilotScript::default(),
        }
    }

    fn resolve(
        raw: ScenarioFile,
        file: &str,
        base: &Path,
        airframe_dir: &Path,
    ) -> Result<Self, ConfigError> {
        let mut c = Checker::default();
        check_world(&mut c, &raw);
        let home = raw.home.unwrap_or_default();
        let ini = &raw.initial;
        let mut events = Vec::new();
        for (i, e) in raw.events.iter().enumerate() {
            resolve_event(&mut c, i, e, &mut events);
        }
        let open_loop = resolve_open_loop(&mut c, &raw.open_loop);
        let pilot = PilotScript::resolve(&mut c, &raw.pilot);
        c.finish(file)?;

        let airframe_path = resolve_airframe(&raw.airframe, base, airframe_dir);
        let mut airframe = Airframe::load(&airframe_path)?;
        if let Some(cap) = raw.battery.capacity_mah {
            airframe.battery.capacity_mah = cap;
        }
        let mut c = Checker::default();
        check_for_airframe(&mut c, &raw.events, &open_loop, &airframe);
        c.finish(file)?;

        let e = ini.attitude_euler_deg;
        let initial = BodyState {
            pos_ned_m: Vector3::from(ini.position_ned_m),
            vel_ned_m_s: Vector3::from(ini.velocity_ned_m_s),
            q_ned_from_frd: UnitQuaternion::from_euler_angles(
                e[0].to_radians(),
                e[1].to_radians(),
                e[2].to_radians(),
            ),
            rate_frd_rad_s: Vector3::from(ini.rate_frd_rad_s),
        };
        Ok(Self {
            airframe,
            sim: SimConfig {
                dt_s: 1.0 / raw.rate_hz,
                integrator: raw.integrator,
                seed: raw.seed,
                sensors: SensorConfig::preset(raw.sensors),
                earth_field: raw.earth_field.unwrap_or_default(),
                home,
                wind: raw.wind,
                battery_charge: raw.battery.charge.unwrap_or(1.0),
                calibration_hand: raw.calibration_hand,
            },
            initial,
            rotors_at_hover: ini.rotors_at_hover,
            duration_s: raw.duration_s,
            events,
            open_loop,
            pilot,
        })
    }

    /// The open-loop command in force at time `t`, if the script has started.
    pub fn open_loop_at(&self, t: f64) -> Option<&OpenLoopCommand> {
        self.open_loop
            .iter()
            .rev()
            .find(|(start, _)| *start <= t + 1e-9)
            .map(|(_, c)| c)
    }
}

/// An airframe argument: a path if it ends in `.toml` (relative to `base`), else a name in `dir`.
pub fn resolve_airframe(name: &str, base: &Path, dir: &Path) -> PathBuf {
    if name.ends_with(".toml") {
        let p = Path::new(name);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    } else {
        dir.join(format!("{name}.toml"))
    }
}

/// The world's values checked into `c`: duration, rate, home, initial state, wind, battery.
fn check_world(c: &mut Checker, raw: &ScenarioFile) {
    c.positive("duration_s", raw.duration_s);
    c.within("rate_hz", raw.rate_hz, 20.0, 10_000.0);
    let home = raw.home.unwrap_or_default();
    c.within("home.lat_deg", home.lat_deg, -89.0, 89.0);
    c.within("home.lon_deg", home.lon_deg, -180.0, 180.0);
    c.within("home.alt_m", home.alt_m, -400.0, 9000.0);
    let ini = &raw.initial;
    c.finite("initial.position_ned_m", &ini.position_ned_m);
    c.finite("initial.velocity_ned_m_s", &ini.velocity_ned_m_s);
    c.finite("initial.attitude_euler_deg", &ini.attitude_euler_deg);
    c.finite("initial.rate_frd_rad_s", &ini.rate_frd_rad_s);
    if let Some(z0) = raw.wind.roughness_m {
        c.within("wind.roughness_m", z0, 1e-4, 2.0);
    }
    c.finite("wind.mean_ned_m_s", &raw.wind.mean_ned_m_s);
    c.within(
        "wind.turbulence_w20_m_s",
        raw.wind.turbulence_w20_m_s,
        0.0,
        40.0,
    );
    if let Some(q) = raw.battery.charge {
        c.within("battery.charge", q, 0.0, 1.0);
    }
    if let Some(cap) = raw.battery.capacity_mah {
        c.within("battery.capacity_mah", cap, 1.0, 1e6);
    }
}

/// The open-loop script checked into `c`, in time order.
fn resolve_open_loop(c: &mut Checker, steps: &[OpenLoopFile]) -> Vec<(f64, OpenLoopCommand)> {
    let mut open_loop = Vec::new();
    for (i, s) in steps.iter().enumerate() {
        let key = format!("open_loop[{i}]");
        c.non_negative(format!("{key}.t_s"), s.t_s);
        let cmd = match (&s.throttle, &s.hover_delta, &s.controls) {
            (Some(t), None, None) => {
                c.within(format!("{key}.throttle"), *t, 0.0, 1.0);
                OpenLoopCommand::Throttle(*t)
            }
            (None, Some(d), None) => {
                c.within(format!("{key}.hover_delta"), *d, -1.0, 1.0);
                OpenLoopCommand::HoverDelta(*d)
            }
            (None, None, Some(v)) => {
                for (k, x) in v.iter().enumerate() {
                    c.within(format!("{key}.controls[{k}]"), *x, 0.0, 1.0);
                }
                OpenLoopCommand::Controls(v.clone())
            }
            _ => {
                c.fail(
                    &key,
                    "give exactly one of throttle, hover_delta or controls",
                );
                continue;
            }
        };
        open_loop.push((s.t_s, cmd));
    }
    open_loop.sort_by(|a, b| a.0.total_cmp(&b.0));
    open_loop
}

/// What must fit the airframe, checked into `c`: the motors the events name, the controls the
/// script gives.
fn check_for_airframe(
    c: &mut Checker,
    events: &[EventFile],
    open_loop: &[(f64, OpenLoopCommand)],
    airframe: &Airframe,
) {
    let rotors = airframe.rotors.len();
    for (i, e) in events.iter().enumerate() {
        let motor = match e {
            EventFile::MotorFail { motor, .. }
            | EventFile::MotorThrust { motor, .. }
            | EventFile::MotorRestore { motor, .. } => Some(*motor),
            _ => None,
        };
        if let Some(m) = motor
            && (m == 0 || m > rotors)
        {
            {
                c.fail(
                    format!("events[{i}].motor"),
                    format!(
                        "must be within [1, {rotors}] for airframe {}, got {m}",
                        airframe.name
                    ),
                );
            }
        }
    }
    for (i, (_, cmd)) in open_loop.iter().enumerate() {
        if let OpenLoopCommand::Controls(v) = cmd
            && v.len() != rotors
        {
            {
                c.fail(
                    format!("open_loop[{i}].controls"),
                    format!(
                        "needs {rotors} values for airframe {}, got {}",
                        airframe.name,
                        v.len()
                    ),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests;
