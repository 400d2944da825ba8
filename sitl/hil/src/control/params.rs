//! The simulator's parameters, pure: the weather (ArduPilot's SITL names where it has them) and,
//! where the host can pace its world, the clock (`SIM_SPEEDUP`, `SIM_PAUSE`, `SIM_RUN_S`).

use nalgebra::Vector3;
use sitl_core::environment::WindConfig;
use sitl_core::sim::SimAction;

/// One parameter: MAVLink name, unit, range, what it does.
pub struct Meta {
    /// MAVLink name (at most 16 characters).
    pub name: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// What it does.
    pub description: &'static str,
}

const fn meta(
    name: &'static str,
    unit: &'static str,
    min: f64,
    max: f64,
    description: &'static str,
) -> Meta {
    Meta {
        name,
        unit,
        min,
        max,
        description,
    }
}

/// The weather's parameters, then the clock's (offered only by a host that paces its world).
pub const META: [Meta; 12] = [
    meta(
        "SIM_WIND_SPD",
        "m/s",
        0.0,
        50.0,
        "Mean horizontal wind speed",
    ),
    meta(
        "SIM_WIND_DIR",
        "deg",
        0.0,
        360.0,
        "Where the wind comes from (0 north, 90 east)",
    ),
    meta(
        "SIM_WIND_TURB",
        "m/s",
        0.0,
        30.0,
        "Dryden turbulence intensity W20 (0 off; 7.7 light, 15.4 moderate)",
    ),
    meta(
        "SIM_GUST_SPD",
        "m/s",
        0.0,
        30.0,
        "Peak of a 1 - cos gust (0: none); setting it starts one",
    ),
    meta(
        "SIM_GUST_DIR",
        "deg",
        0.0,
        360.0,
        "Where gusts come from (0 north, 90 east)",
    ),
    meta("SIM_GUST_T", "s", 0.1, 30.0, "Length of a gust"),
    meta(
        "SIM_GUST_PER",
        "s",
        0.0,
        600.0,
        "Time between gust starts (0: one gust each time SIM_GUST_SPD is set)",
    ),
    meta(
        "SIM_TUMBLE_S",
        "s",
        0.0,
        600.0,
        "Setting it picks the vehicle up and turns it by hand through every orientation for this long (a magnetometer calibration), then sets it down level; 0 sets it down now",
    ),
    meta(
        "SIM_CAL_HAND",
        "",
        0.0,
        1.0,
        "1: a hand does what the autopilot's calibrations ask (holds the vehicle on each face, turns it); 0: nobody does",
    ),
    meta(
        "SIM_SPEEDUP",
        "",
        0.0,
        10_000.0,
        "Simulated seconds per wall-clock second (ArduPilot's name); 0: as fast as the lockstep allows",
    ),
    meta(
        "SIM_PAUSE",
        "",
        0.0,
        1.0,
        "1: simulated time holds (the autopilot waits for its next sensor frame); 0: it runs",
    ),
    meta(
        "SIM_RUN_S",
        "s",
        0.0,
        86_400.0,
        "While paused: run this many simulated seconds as fast as the lockstep allows, then hold again (PARAM_VALUE 0 says when); reads the seconds left",
    ),
];

/// How many of [`META`] are the weather's.
pub const WEATHER_PARAMS: usize = 9;

/// The index of `name` among the first `offered` parameters.
pub fn index(name: &str, offered: usize) -> Option<usize> {
    META[..offered].iter().position(|m| m.name == name)
}

/// Whether `value` is within parameter `i`'s range; why not if not.
pub fn check(i: usize, value: f64) -> Result<(), String> {
    let m = &META[i];
    if value.is_finite() && (m.min..=m.max).contains(&value) {
        Ok(())
    } else {
        Err(format!(
            "{} must be within [{}, {}] {}, got {value}",
            m.name, m.min, m.max, m.unit
        ))
    }
}

/// The weather parameters and the gusts they schedule: pure, stepped with simulation time.
#[derive(Debug, Clone, PartialEq)]
pub struct Weather {
    values: [f64; WEATHER_PARAMS],
    /// The scenario's vertical wind, kept as the horizontal one changes.
    vertical_m_s: f64,
    next_gust_s: Option<f64>,
}

/// Air moving toward the opposite of `from_deg` at `speed` (NED, horizontal).
fn from_direction(speed: f64, from_deg: f64) -> Vector3<f64> {
    let (s, c) = from_deg.to_radians().sin_cos();
    Vector3::new(-speed * c, -speed * s, 0.0)
}

impl Weather {
    /// The parameters that describe `wind` (a scenario's) and whether the calibration hand
    /// is on.
    pub fn new(wind: &WindConfig, calibration_hand: bool) -> Self {
        let [n, e, d] = wind.mean_ned_m_s;
        let speed = n.hypot(e);
        let from = if speed > 0.0 {
            (-e).atan2(-n).to_degrees().rem_euclid(360.0)
        } else {
            0.0
        };
        Self {
            values: [
                speed,
                from,
                wind.turbulence_w20_m_s,
                0.0,
                0.0,
                2.0,
                0.0,
                0.0,
                f64::from(u8::from(calibration_hand)),
            ],
            vertical_m_s: d,
            next_gust_s: None,
        }
    }

    /// The value of `name`, if it is a weather parameter.
    pub fn get(&self, name: &str) -> Option<f64> {
        index(name, WEATHER_PARAMS).map(|i| self.values[i])
    }

    /// Sets `name` at simulation time `t_s`: the actions to apply now, or why not.
    pub fn set(&mut self, name: &str, value: f64, t_s: f64) -> Result<Vec<SimAction>, String> {
        let i = index(name, WEATHER_PARAMS).ok_or_else(|| format!("no parameter {name}"))?;
        check(i, value)?;
        self.values[i] = value;
        Ok(match name {
            "SIM_WIND_SPD" | "SIM_WIND_DIR" | "SIM_WIND_TURB" => vec![self.wind()],
            "SIM_GUST_SPD" => {
                self.next_gust_s = (value > 0.0).then_some(t_s);
                self.due(t_s)
            }
            "SIM_GUST_PER" => {
                if self.values[3] > 0.0 && value > 0.0 {
                    self.next_gust_s.get_or_insert(t_s);
                }
                Vec::new()
            }
            "SIM_TUMBLE_S" => vec![SimAction::Tumble { duration_s: value }],
            "SIM_CAL_HAND" => vec![SimAction::CalibrationHand(value >= 0.5)],
            _ => Vec::new(),
        })
    }

    /// The mean wind and turbulence the parameters describe.
    fn wind(&self) -> SimAction {
        let mut mean = from_direction(self.values[0], self.values[1]);
        mean.z = self.vertical_m_s;
        SimAction::Wind {
            mean_ned_m_s: mean,
            turbulence_w20_m_s: self.values[2],
        }
    }

    /// The gust due at `t_s`, if one is.
    pub fn due(&mut self, t_s: f64) -> Vec<SimAction> {
        let Some(start) = self.next_gust_s.filter(|s| *s <= t_s + 1e-9) else {
            return Vec::new();
        };
        let (peak, from, length, period) = (
            self.values[3],
            self.values[4],
            self.values[5],
            self.values[6],
        );
        self.next_gust_s = (peak > 0.0 && period > 0.0).then_some(start + period.max(length));
        if peak <= 0.0 {
            return Vec::new();
        }
        vec![SimAction::Gust {
            peak_ned_m_s: from_direction(peak, from),
            duration_s: length,
        }]
    }
}

/// The clock's parameters: how fast simulated time runs, whether it holds, and how far it
/// runs before holding again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pace {
    /// Simulated seconds per wall-clock second; `None`: as fast as the lockstep allows.
    pub speedup: Option<f64>,
    /// Simulated time holds.
    pub paused: bool,
    /// While paused: simulated time runs, unpaced, up to here.
    pub run_until_s: Option<f64>,
}

impl Pace {
    /// Running at `speedup` (`None`: unpaced), paused or not.
    pub fn new(speedup: Option<f64>, paused: bool) -> Self {
        Self {
            speedup,
            paused,
            run_until_s: None,
        }
    }

    /// Whether simulated time holds at `t_s`.
    pub fn holds(&self, t_s: f64) -> bool {
        self.paused && self.run_until_s.is_none_or(|end| t_s >= end - 1e-9)
    }

    /// The pace at `t_s`: `None` runs unpaced (a run while paused, or `SIM_SPEEDUP` 0).
    pub fn speedup_at(&self, t_s: f64) -> Option<f64> {
        if self.paused && !self.holds(t_s) {
            None
        } else {
            self.speedup
        }
    }

    /// The value of clock parameter `name` at `t_s`.
    pub fn get(&self, name: &str, t_s: f64) -> Option<f64> {
        match name {
            "SIM_SPEEDUP" => Some(self.speedup.unwrap_or(0.0)),
            "SIM_PAUSE" => Some(f64::from(u8::from(self.paused))),
            "SIM_RUN_S" => Some(self.run_until_s.map_or(0.0, |end| (end - t_s).max(0.0))),
            _ => None,
        }
    }

    /// Sets clock parameter `name` at `t_s`, or says why not.
    pub fn set(&mut self, name: &str, value: f64, t_s: f64) -> Result<(), String> {
        let i = index(name, META.len())
            .filter(|&i| i >= WEATHER_PARAMS)
            .ok_or_else(|| format!("no parameter {name}"))?;
        check(i, value)?;
        match name {
            "SIM_SPEEDUP" => self.speedup = (value > 0.0).then_some(value),
            "SIM_PAUSE" => {
                self.paused = value >= 0.5;
                self.run_until_s = None;
            }
            _ => {
                if !self.paused {
                    return Err("SIM_RUN_S runs a paused clock: set SIM_PAUSE 1 first".into());
                }
                // To the microsecond: a value sent as REAL32 (0.2 arrives as 0.200000003) ends
                // the stretch where it was meant to, not an exchange later.
                let value = (value * 1e6).round() / 1e6;
                self.run_until_s = (value > 0.0).then_some(t_s + value);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
