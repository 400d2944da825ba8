//! The simulator's own MAVLink endpoint (`sitl --control ADDR`, `autopilot --sim-control
//! ADDR`): the weather, changed while it flies — ArduPilot's SITL names where it has them:
//! `SIM_WIND_SPD`, `SIM_WIND_DIR` (where the wind comes from), `SIM_WIND_TURB` (here the Dryden
//! intensity W20) and `1 − cos` gusts (`SIM_GUST_*`); a hand that picks the vehicle up and turns
//! it through every orientation for a magnetometer calibration (`SIM_TUMBLE_S`), and whether a
//! hand does what the autopilot's calibrations ask (`SIM_CAL_HAND`). Where the host paces its
//! world in lockstep (the embedded simulator), the clock too: `SIM_SPEEDUP`, `SIM_PAUSE` and
//! `SIM_RUN_S` ([`params`]). Any ground station or script speaks to it with the parameter
//! protocol (`PARAM_REQUEST_LIST`, `PARAM_REQUEST_READ`, `PARAM_SET`, each answered with
//! `PARAM_VALUE`); a value out of range or not finite keeps the old one and says why in
//! `STATUSTEXT`. `MAV_CMD_REQUEST_MESSAGE` for `HIL_STATE_QUATERNION` or `LOCAL_POSITION_NED`
//! answers with the truth at that moment (the position from the simulator's home). It speaks as
//! system 1, component 25 (the simulator's ids on the HIL link) and sends a heartbeat every
//! second to whoever spoke last.
//!
//! A scenario's own wind events still happen at their times; the last change wins.

pub mod params;

use crate::{Decoded, Encoder, decode_into};
use mavlink::dialects::common::{
    COMMAND_ACK_DATA, HEARTBEAT_DATA, LOCAL_POSITION_NED_DATA, MavAutopilot, MavCmd, MavMessage,
    MavModeFlag, MavParamType, MavResult, MavSeverity, MavState, MavType, PARAM_VALUE_DATA,
    STATUSTEXT_DATA,
};
use params::{META, Pace, WEATHER_PARAMS, Weather};
use sitl_core::environment::WindConfig;
use sitl_core::sim::{SimAction, Simulator};
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// `HIL_STATE_QUATERNION`'s message id.
const HIL_STATE_QUATERNION_ID: f32 = 115.0;
/// `LOCAL_POSITION_NED`'s message id.
const LOCAL_POSITION_NED_ID: f32 = 32.0;

/// The endpoint: a UDP socket, the weather it sets and, where offered, the clock.
pub struct Control {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    encoder: Encoder,
    weather: Weather,
    pace: Option<Pace>,
    rx: Vec<u8>,
    decoded: Decoded,
    last_heartbeat: Option<Instant>,
}

impl Control {
    /// Binds `addr` (non-blocking) with the scenario's `wind` and calibration hand.
    pub fn bind(addr: SocketAddr, wind: &WindConfig, calibration_hand: bool) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        Ok(Self {
            socket,
            peer: None,
            encoder: crate::sim_encoder(),
            weather: Weather::new(wind, calibration_hand),
            pace: None,
            rx: vec![0; 65_536],
            decoded: Decoded::default(),
            last_heartbeat: None,
        })
    }

    /// Offers the clock's parameters too, starting at `pace` (a host that honours [`Self::pace`]).
    pub fn with_clock(mut self, pace: Pace) -> Self {
        self.pace = Some(pace);
        self
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The clock as set, if offered.
    pub fn pace(&self) -> Option<&Pace> {
        self.pace.as_ref()
    }

    /// How many parameters are offered.
    fn offered(&self) -> usize {
        if self.pace.is_some() {
            META.len()
        } else {
            WEATHER_PARAMS
        }
    }

    /// Waits up to `timeout` for a datagram, without reading it (a paused host's idle wait).
    pub fn wait(&mut self, timeout: Duration) {
        let waited = self.socket.set_nonblocking(false).and_then(|()| {
            self.socket
                .set_read_timeout(Some(timeout.max(Duration::from_micros(1))))
        });
        if waited.is_ok() {
            let _ = self.socket.peek_from(&mut self.rx[..1]);
        }
        if let Err(e) = self.socket.set_nonblocking(true) {
            tracing::debug!("simulator control: {e}");
        }
    }

    /// Answers what arrived and returns the actions due now on `sim`. Never blocks; a socket
    /// error is logged and the simulation goes on.
    pub fn poll(&mut self, sim: &Simulator) -> Vec<SimAction> {
        let t_s = sim.time_s();
        let mut actions = self.weather.due(t_s);
        loop {
            match self.socket.recv_from(&mut self.rx) {
                Ok((n, from)) => {
                    self.peer = Some(from);
                    self.decoded.messages.clear();
                    decode_into(&self.rx[..n], &mut self.decoded);
                    let messages = std::mem::take(&mut self.decoded.messages);
                    for (_, msg) in &messages {
                        actions.extend(self.handle(msg, sim));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) => {
                    tracing::debug!("simulator control: {e}");
                    break;
                }
            }
        }
        self.end_a_run(t_s);
        self.heartbeat();
        actions
    }

    /// A paused clock's run that has reached its end holds again, and says so.
    fn end_a_run(&mut self, t_s: f64) {
        let Some(p) = self.pace.as_mut() else { return };
        if p.run_until_s.is_some() && p.holds(t_s) {
            p.run_until_s = None;
            if let Some(i) = params::index("SIM_RUN_S", META.len()) {
                self.send_value(i, t_s);
            }
        }
    }

    fn heartbeat(&mut self) {
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
    }

    fn handle(&mut self, msg: &MavMessage, sim: &Simulator) -> Vec<SimAction> {
        let ours = |system: u8, component: u8| {
            (system == 0 || system == crate::SIM_SYSTEM_ID)
                && (component == 0 || component == crate::SIM_COMPONENT_ID)
        };
        let t_s = sim.time_s();
        match msg {
            MavMessage::PARAM_REQUEST_LIST(r) if ours(r.target_system, r.target_component) => {
                for i in 0..self.offered() {
                    self.send_value(i, t_s);
                }
                Vec::new()
            }
            MavMessage::PARAM_REQUEST_READ(r) if ours(r.target_system, r.target_component) => {
                let name = r.param_id.to_str().unwrap_or("");
                let i = params::index(name, self.offered()).or_else(|| {
                    usize::try_from(r.param_index)
                        .ok()
                        .filter(|&i| i < self.offered())
                });
                if let Some(i) = i {
                    self.send_value(i, t_s);
                }
                Vec::new()
            }
            MavMessage::PARAM_SET(s) if ours(s.target_system, s.target_component) => {
                let name = s.param_id.to_str().unwrap_or("").to_owned();
                self.set(&name, f64::from(s.param_value), t_s)
            }
            MavMessage::COMMAND_LONG(c) if ours(c.target_system, c.target_component) => {
                self.command(c.command, c.param1, sim);
                Vec::new()
            }
            _ => Vec::new(),
        }
    }

    /// `PARAM_SET` of `name`: the actions it starts; the value kept answered, a refusal said.
    fn set(&mut self, name: &str, value: f64, t_s: f64) -> Vec<SimAction> {
        let Some(i) = params::index(name, self.offered()) else {
            return Vec::new();
        };
        let result = match self.pace.as_mut() {
            Some(p) if i >= WEATHER_PARAMS => p.set(name, value, t_s).map(|()| Vec::new()),
            _ => self.weather.set(name, value, t_s),
        };
        let actions = match result {
            Ok(a) => {
                tracing::info!(t_s, "{name} = {value}");
                a
            }
            Err(why) => {
                tracing::warn!("simulator control: {why}");
                self.send(&MavMessage::STATUSTEXT(STATUSTEXT_DATA {
                    severity: MavSeverity::MAV_SEVERITY_WARNING,
                    text: why.as_str()[..why.len().min(50)].into(),
                    id: 0,
                    chunk_seq: 0,
                }));
                Vec::new()
            }
        };
        self.send_value(i, t_s);
        actions
    }

    /// `MAV_CMD_REQUEST_MESSAGE` of the truth; every other command is unsupported.
    fn command(&mut self, command: MavCmd, message_id: f32, sim: &Simulator) {
        let answer = match command {
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                if message_id == HIL_STATE_QUATERNION_ID {
                    Some(crate::hil_state_quaternion(&sim.truth()))
                } else if message_id == LOCAL_POSITION_NED_ID {
                    let truth = sim.truth();
                    let (p, v) = (truth.body.pos_ned_m, truth.body.vel_ned_m_s);
                    Some(MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                        time_boot_ms: (truth.time_usec / 1000) as u32,
                        x: p.x as f32,
                        y: p.y as f32,
                        z: p.z as f32,
                        vx: v.x as f32,
                        vy: v.y as f32,
                        vz: v.z as f32,
                    }))
                } else {
                    None
                }
            }
            _ => None,
        };
        let result = match (&answer, command) {
            (Some(_), _) => MavResult::MAV_RESULT_ACCEPTED,
            (None, MavCmd::MAV_CMD_REQUEST_MESSAGE) => MavResult::MAV_RESULT_DENIED,
            (None, _) => MavResult::MAV_RESULT_UNSUPPORTED,
        };
        self.send(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result,
            ..Default::default()
        }));
        if let Some(m) = answer {
            self.send(&m);
        }
    }

    fn send_value(&mut self, i: usize, t_s: f64) {
        let m = &META[i];
        let value = match self.pace.as_ref() {
            Some(p) if i >= WEATHER_PARAMS => p.get(m.name, t_s),
            _ => self.weather.get(m.name),
        };
        self.send(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: value.unwrap_or(f64::NAN) as f32,
            param_count: self.offered() as u16,
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
            tracing::debug!("simulator control: sending to {peer}: {e}");
        }
    }
}
