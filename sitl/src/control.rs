//! The simulator's own MAVLink endpoint (`sitl --control ADDR`): the weather, changed while it
//! flies. ArduPilot's SITL names where it has them — `SIM_WIND_SPD`, `SIM_WIND_DIR` (where the
//! wind comes from), `SIM_WIND_TURB` (here the Dryden intensity W20) — and `1 − cos` gusts
//! (`SIM_GUST_*`); a hand that picks the vehicle up and turns it through every orientation
//! for a magnetometer calibration (`SIM_TUMBLE_S`), and whether a hand does what the autopilot's
//! calibrations ask (`SIM_CAL_HAND`). Any ground station or script speaks to it with the parameter protocol
//! (`PARAM_REQUEST_LIST`, `PARAM_REQUEST_READ`, `PARAM_SET`, each answered with `PARAM_VALUE`);
//! a value out of range or not finite keeps the old one and says why in `STATUSTEXT`. It
//! speaks as system 1, component 25 (the simulator's ids on the HIL link) and sends a heartbeat
//! every second to whoever spoke last.
//!
//! A scenario's own wind events still happen at their times; the last change wins.

use anyhow::{Context, Result};
use hil::{Decoded, Encoder, decode_into};
use mavlink::dialects::common::{
    HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavParamType, MavSeverity, MavState,
    MavType, PARAM_VALUE_DATA, STATUSTEXT_DATA,
};
use nalgebra::Vector3;
use sitl_core::environment::WindConfig;
use sitl_core::sim::SimAction;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// One parameter: MAVLink name, unit, range, what it does.
struct Meta {
    name: &'static str,
    unit: &'static str,
    min: f64,
    max: f64,
    description: &'static str,
}

const META: [Meta; 9] = [
    Meta {
        name: "SIM_WIND_SPD",
        unit: "m/s",
        min: 0.0,
        max: 50.0,
        description: "Mean horizontal wind speed",
    },
    Meta {
        name: "SIM_WIND_DIR",
        unit: "deg",
        min: 0.0,
        max: 360.0,
        description: "Where the wind comes from (0 north, 90 east)",
    },
    Meta {
        name: "SIM_WIND_TURB",
        unit: "m/s",
        min: 0.0,
        max: 30.0,
        description: "Dryden turbulence intensity W20 (0 off; 7.7 light, 15.4 moderate)",
    },
    Meta {
        name: "SIM_GUST_SPD",
        unit: "m/s",
        min: 0.0,
        max: 30.0,
        description: "Peak of a 1 - cos gust (0: none); setting it starts one",
    },
    Meta {
        name: "SIM_GUST_DIR",
        unit: "deg",
        min: 0.0,
        max: 360.0,
        description: "Where gusts come from (0 north, 90 east)",
    },
    Meta {
        name: "SIM_GUST_T",
        unit: "s",
        min: 0.1,
        max: 30.0,
        description: "Length of a gust",
    },
    Meta {
        name: "SIM_GUST_PER",
        unit: "s",
        min: 0.0,
        max: 600.0,
        description: "Time between gust starts (0: one gust each time SIM_GUST_SPD is set)",
    },
    Meta {
        name: "SIM_TUMBLE_S",
        unit: "s",
        min: 0.0,
        max: 600.0,
        description: "Setting it picks the vehicle up and turns it by hand through every orientation for this long (a magnetometer calibration), then sets it down level; 0 sets it down now",
    },
    Meta {
        name: "SIM_CAL_HAND",
        unit: "",
        min: 0.0,
        max: 1.0,
        description: "1: a hand does what the autopilot's calibrations ask (holds the vehicle on each face, turns it); 0: nobody does",
    },
];

/// The weather parameters and the gusts they schedule: pure, stepped with simulation time.
#[derive(Debug, Clone, PartialEq)]
pub struct Weather {
    values: [f64; META.len()],
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

    fn index(name: &str) -> Option<usize> {
        META.iter().position(|m| m.name == name)
    }

    /// The value of `name`, if there is such a parameter.
    pub fn get(&self, name: &str) -> Option<f64> {
        Self::index(name).map(|i| self.values[i])
    }

    /// Sets `name` at simulation time `t_s`: the actions to apply now, or why not.
    pub fn set(&mut self, name: &str, value: f64, t_s: f64) -> Result<Vec<SimAction>, String> {
        let i = Self::index(name).ok_or_else(|| format!("no parameter {name}"))?;
        let m = &META[i];
        if !(value.is_finite() && (m.min..=m.max).contains(&value)) {
            return Err(format!(
                "{name} must be within [{}, {}] {}, got {value}",
                m.min, m.max, m.unit
            ));
        }
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

/// The endpoint: a UDP socket and the weather it sets.
pub struct Control {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    encoder: Encoder,
    weather: Weather,
    rx: Vec<u8>,
    decoded: Decoded,
    last_heartbeat: Option<Instant>,
}

impl Control {
    /// Binds `addr` (non-blocking) with the scenario's `wind` and calibration hand.
    pub fn bind(addr: SocketAddr, wind: &WindConfig, calibration_hand: bool) -> Result<Self> {
        let socket = UdpSocket::bind(addr).with_context(|| format!("binding --control {addr}"))?;
        socket
            .set_nonblocking(true)
            .context("--control: non-blocking")?;
        for m in &META {
            tracing::debug!(
                "{} [{}, {}] {}: {}",
                m.name,
                m.min,
                m.max,
                m.unit,
                m.description
            );
        }
        Ok(Self {
            socket,
            peer: None,
            encoder: hil::sim_encoder(),
            weather: Weather::new(wind, calibration_hand),
            rx: vec![0; 65_536],
            decoded: Decoded::default(),
            last_heartbeat: None,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.socket.local_addr()?)
    }

    /// Answers what arrived and returns the actions due at simulation time `t_s`. Never blocks;
    /// a socket error is logged and the simulation goes on.
    pub fn poll(&mut self, t_s: f64) -> Vec<SimAction> {
        let mut actions = self.weather.due(t_s);
        loop {
            match self.socket.recv_from(&mut self.rx) {
                Ok((n, from)) => {
                    self.peer = Some(from);
                    self.decoded.messages.clear();
                    decode_into(&self.rx[..n], &mut self.decoded);
                    let messages = std::mem::take(&mut self.decoded.messages);
                    for (_, msg) in &messages {
                        actions.extend(self.handle(msg, t_s));
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                Err(e) => {
                    tracing::debug!("--control: {e}");
                    break;
                }
            }
        }
        if self.peer.is_some()
            && self
                .last_heartbeat
                .is_none_or(|t| t.elapsed() >= Duration::from_secs(1))
        {
            self.last_heartbeat = Some(Instant::now());
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_GENERIC,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }));
        }
        actions
    }

    fn handle(&mut self, msg: &MavMessage, t_s: f64) -> Vec<SimAction> {
        let ours = |system: u8, component: u8| {
            (system == 0 || system == hil::SIM_SYSTEM_ID)
                && (component == 0 || component == hil::SIM_COMPONENT_ID)
        };
        match msg {
            MavMessage::PARAM_REQUEST_LIST(r) if ours(r.target_system, r.target_component) => {
                for i in 0..META.len() {
                    self.send_value(i);
                }
                Vec::new()
            }
            MavMessage::PARAM_REQUEST_READ(r) if ours(r.target_system, r.target_component) => {
                let name = r.param_id.to_str().unwrap_or("");
                let i = Weather::index(name).or_else(|| {
                    usize::try_from(r.param_index)
                        .ok()
                        .filter(|&i| i < META.len())
                });
                if let Some(i) = i {
                    self.send_value(i);
                }
                Vec::new()
            }
            MavMessage::PARAM_SET(s) if ours(s.target_system, s.target_component) => {
                let name = s.param_id.to_str().unwrap_or("").to_owned();
                let Some(i) = Weather::index(&name) else {
                    return Vec::new();
                };
                let actions = match self.weather.set(&name, f64::from(s.param_value), t_s) {
                    Ok(a) => {
                        tracing::info!(t_s, "{name} = {}", s.param_value);
                        a
                    }
                    Err(why) => {
                        tracing::warn!("--control: {why}");
                        self.send(&MavMessage::STATUSTEXT(STATUSTEXT_DATA {
                            severity: MavSeverity::MAV_SEVERITY_WARNING,
                            text: why.as_str()[..why.len().min(50)].into(),
                            id: 0,
                            chunk_seq: 0,
                        }));
                        Vec::new()
                    }
                };
                self.send_value(i);
                actions
            }
            _ => Vec::new(),
        }
    }

    fn send_value(&mut self, i: usize) {
        let m = &META[i];
        self.send(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: self.weather.get(m.name).unwrap_or(f64::NAN) as f32,
            param_count: META.len() as u16,
            param_index: i as u16,
            param_id: m.name.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }));
    }

    fn send(&mut self, msg: &MavMessage) {
        let Some(peer) = self.peer else { return };
        let mut out = Vec::new();
        self.encoder.push(&mut out, msg);
        if let Err(e) = self.socket.send_to(&out, peer) {
            tracing::debug!("--control: sending to {peer}: {e}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wind_of(actions: &[SimAction]) -> (Vector3<f64>, f64) {
        match actions {
            [
                SimAction::Wind {
                    mean_ned_m_s,
                    turbulence_w20_m_s,
                },
            ] => (*mean_ned_m_s, *turbulence_w20_m_s),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn wind_parameters_read_the_scenario_and_set_where_the_wind_comes_from() {
        let w = Weather::new(
            &WindConfig {
                mean_ned_m_s: [0.0, -5.0, 0.5],
                turbulence_w20_m_s: 7.7,
                roughness_m: None,
            },
            true,
        );
        // Air moving west comes from the east.
        assert!((w.get("SIM_WIND_SPD").unwrap() - 5.0).abs() < 1e-12);
        assert!((w.get("SIM_WIND_DIR").unwrap() - 90.0).abs() < 1e-9);
        assert_eq!(w.get("SIM_WIND_TURB"), Some(7.7));
        let mut w = w;
        let (mean, turb) = wind_of(&w.set("SIM_WIND_DIR", 180.0, 3.0).unwrap());
        assert!((mean - Vector3::new(5.0, 0.0, 0.5)).norm() < 1e-9, "{mean}");
        assert_eq!(turb, 7.7);
        let (mean, _) = wind_of(&w.set("SIM_WIND_SPD", 10.0, 3.0).unwrap());
        assert!(
            (mean - Vector3::new(10.0, 0.0, 0.5)).norm() < 1e-9,
            "{mean}"
        );
        let (_, turb) = wind_of(&w.set("SIM_WIND_TURB", 0.0, 3.0).unwrap());
        assert_eq!(turb, 0.0);
    }

    #[test]
    fn bad_values_keep_the_old_one() {
        let mut w = Weather::new(&WindConfig::default(), true);
        for (name, v) in [
            ("SIM_WIND_SPD", -1.0),
            ("SIM_WIND_SPD", f64::NAN),
            ("SIM_WIND_DIR", 361.0),
            ("SIM_GUST_T", 0.0),
        ] {
            let e = w.set(name, v, 0.0).unwrap_err();
            assert!(e.starts_with(name) && e.contains("must be within"), "{e}");
        }
        assert!(w.set("SIM_NOPE", 1.0, 0.0).is_err());
        assert_eq!(w, Weather::new(&WindConfig::default(), true));
    }

    #[test]
    fn a_gust_starts_when_set_and_repeats_with_a_period() {
        let mut w = Weather::new(&WindConfig::default(), true);
        w.set("SIM_GUST_DIR", 270.0, 0.0).unwrap();
        w.set("SIM_GUST_T", 3.0, 0.0).unwrap();
        let a = w.set("SIM_GUST_SPD", 6.0, 10.0).unwrap();
        match a.as_slice() {
            [
                SimAction::Gust {
                    peak_ned_m_s,
                    duration_s,
                },
            ] => {
                // From the west: toward the east.
                assert!((peak_ned_m_s - Vector3::new(0.0, 6.0, 0.0)).norm() < 1e-9);
                assert_eq!(*duration_s, 3.0);
            }
            other => panic!("{other:?}"),
        }
        // Once only without a period.
        assert!(w.due(100.0).is_empty());
        w.set("SIM_GUST_PER", 20.0, 100.0).unwrap();
        assert_eq!(w.due(100.0).len(), 1);
        assert!(w.due(119.9).is_empty());
        assert_eq!(w.due(120.0).len(), 1);
        assert_eq!(w.due(140.0).len(), 1);
        w.set("SIM_GUST_SPD", 0.0, 141.0).unwrap();
        assert!(w.due(1000.0).is_empty());
    }
}
