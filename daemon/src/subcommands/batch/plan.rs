//! What one run of a batch flies: its seed, wind, turbulence and fault, drawn from the batch's
//! seed and the run's number, and the simulated world it makes.

use super::BatchConfig;
use anyhow::{Context, Result};
use nalgebra::Vector3;
use sitl_core::environment::WindConfig;
use sitl_core::rng::Rng;
use sitl_core::sensors::{SensorConfig, SensorHealth, SensorKind, SensorPreset};
use sitl_core::sim::{Event, SimAction, SimConfig};

/// The faults a batch can draw, each at a random moment of the hover.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// No fault.
    None,
    /// One motor's propeller loses part of its thrust (to 50–90 %).
    Motor,
    /// One motor stops.
    MotorOff,
    /// The GPS loses its fix for 5–15 s.
    Gps,
    /// A magnetic disturbance of 0.1–0.3 G, any direction, for 3–10 s.
    Mag,
    /// The barometer goes silent for 2–10 s.
    Baro,
    /// A 1 − cos gust of 3–8 m/s, horizontal, for 1–3 s.
    Gust,
    /// The IMU repeats one reading from then on.
    Imu,
}

impl FaultKind {
    /// Every fault, by its name on the command line and in the CSV.
    pub const ALL: [(&'static str, FaultKind); 8] = [
        ("none", FaultKind::None),
        ("motor", FaultKind::Motor),
        ("motor_off", FaultKind::MotorOff),
        ("gps", FaultKind::Gps),
        ("mag", FaultKind::Mag),
        ("baro", FaultKind::Baro),
        ("gust", FaultKind::Gust),
        ("imu", FaultKind::Imu),
    ];

    /// The fault named `name`.
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, f)| f)
            .with_context(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|(n, _)| *n).collect();
                format!("unknown fault {name:?} (known: {})", names.join(", "))
            })
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|&&(_, f)| f == self)
            .map_or("?", |(n, _)| n)
    }
}

/// One run as drawn: its sensors' seed, its weather and its fault.
#[derive(Debug, Clone, PartialEq)]
pub struct RunPlan {
    /// The run's number in the batch.
    pub run: u32,
    /// Seed of the simulator's random processes (sensor noise, turbulence).
    pub sim_seed: u64,
    /// Mean wind speed (m/s) and the direction it blows from (deg, clockwise from north).
    pub wind_m_s: f64,
    /// Direction the wind blows from (deg).
    pub wind_from_deg: f64,
    /// Turbulence intensity W20 (m/s).
    pub turbulence_m_s: f64,
    /// The fault, when it strikes (s of simulation time), and what exactly it is.
    pub fault: FaultKind,
    /// When the fault strikes (s); none without one.
    pub fault_t_s: Option<f64>,
    /// The fault's particulars, for the CSV (motor, strength, length).
    pub fault_detail: String,
    /// The simulator's events that make the fault.
    pub events: Vec<Event>,
}

impl RunPlan {
    /// Draws run `run` of `cfg` for a vehicle of `rotors` rotors, from the stream `(seed, run)`.
    pub fn draw(cfg: &BatchConfig, run: u32, rotors: usize) -> Self {
        let mut rng = Rng::stream(cfg.seed, u64::from(run));
        let sim_seed = rng.next_u64();
        let wind_m_s = cfg.wind_max_m_s * rng.uniform();
        let wind_from_deg = 360.0 * rng.uniform();
        let turbulence_m_s = cfg.turbulence_max_m_s * rng.uniform();
        let fault =
            cfg.faults[(rng.uniform() * cfg.faults.len() as f64) as usize % cfg.faults.len()];
        // The hover begins after the spool-up (1 s after arming at about 1 s) and the climb
        // (1.5 m/s, 1 m/s²); the fault strikes within it, a second clear of either end.
        let hover_start_s = 3.5 + cfg.takeoff_m / 1.5;
        let t = hover_start_s + 1.0 + (cfg.hover_s - 2.0).max(0.0) * rng.uniform();
        let (detail, events) = fault_events(fault, t, rotors, &mut rng);
        Self {
            run,
            sim_seed,
            wind_m_s,
            wind_from_deg,
            turbulence_m_s,
            fault,
            fault_t_s: (fault != FaultKind::None).then_some(t),
            fault_detail: detail,
            events,
        }
    }

    /// The simulated world of this run.
    pub(super) fn world(&self, sensors: SensorPreset) -> SimConfig {
        // The wind blows from `wind_from_deg`: the air moves the other way.
        let to = (self.wind_from_deg + 180.0).to_radians();
        SimConfig {
            seed: self.sim_seed,
            sensors: SensorConfig::preset(sensors),
            wind: WindConfig {
                mean_ned_m_s: [self.wind_m_s * to.cos(), self.wind_m_s * to.sin(), 0.0],
                turbulence_w20_m_s: self.turbulence_m_s,
                roughness_m: None,
            },
            ..SimConfig::default()
        }
    }
}

/// The particulars and the simulator's events of `fault` striking at `t` (s) on a vehicle of
/// `rotors` rotors, drawn from `rng`.
fn fault_events(fault: FaultKind, t: f64, rotors: usize, rng: &mut Rng) -> (String, Vec<Event>) {
    let between = |rng: &mut Rng, lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
    let horizontal = |rng: &mut Rng, size: f64| {
        let a = std::f64::consts::TAU * rng.uniform();
        Vector3::new(size * a.cos(), size * a.sin(), 0.0)
    };
    let at = |t_s, action| Event { t_s, action };
    match fault {
        FaultKind::None => (String::new(), Vec::new()),
        FaultKind::Motor => {
            let index = (rng.uniform() * rotors as f64) as usize % rotors;
            let effectiveness = between(rng, 0.5, 0.9);
            (
                format!("motor {} at {:.0} %", index + 1, 100.0 * effectiveness),
                vec![at(
                    t,
                    SimAction::MotorEffectiveness {
                        index,
                        effectiveness,
                    },
                )],
            )
        }
        FaultKind::MotorOff => {
            let index = (rng.uniform() * rotors as f64) as usize % rotors;
            (
                format!("motor {} off", index + 1),
                vec![at(t, SimAction::MotorFail { index })],
            )
        }
        FaultKind::Gps => {
            let d = between(rng, 5.0, 15.0);
            (
                format!("fix lost {d:.1} s"),
                vec![
                    at(t, SimAction::GpsFixLost(true)),
                    at(t + d, SimAction::GpsFixLost(false)),
                ],
            )
        }
        FaultKind::Mag => {
            let size = between(rng, 0.1, 0.3);
            let d = between(rng, 3.0, 10.0);
            let mut field = Vector3::new(rng.normal(), rng.normal(), rng.normal());
            field *= size / field.norm().max(1e-9);
            (
                format!("{size:.2} G for {d:.1} s"),
                vec![
                    at(t, SimAction::MagDisturbance(field)),
                    at(t + d, SimAction::MagDisturbance(Vector3::zeros())),
                ],
            )
        }
        FaultKind::Baro => {
            let d = between(rng, 2.0, 10.0);
            let health = |health| SimAction::Sensor {
                sensor: SensorKind::Baro,
                health,
            };
            (
                format!("silent {d:.1} s"),
                vec![
                    at(t, health(SensorHealth::Off)),
                    at(t + d, health(SensorHealth::Ok)),
                ],
            )
        }
        FaultKind::Gust => {
            let peak = between(rng, 3.0, 8.0);
            let d = between(rng, 1.0, 3.0);
            (
                format!("{peak:.1} m/s over {d:.1} s"),
                vec![at(
                    t,
                    SimAction::Gust {
                        peak_ned_m_s: horizontal(rng, peak),
                        duration_s: d,
                    },
                )],
            )
        }
        FaultKind::Imu => (
            "stuck".into(),
            vec![at(
                t,
                SimAction::Sensor {
                    sensor: SensorKind::Imu,
                    health: SensorHealth::Stuck,
                },
            )],
        ),
    }
}
