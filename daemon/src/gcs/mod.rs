//! The ground-station side: what the vehicle says and answers on MAVLink, as a pure state
//! machine ([`GroundStation`]) of the messages received, the latest telemetry and the clock,
//! and the links that carry it ([`links`]).
//!
//! The vehicle speaks as component 1 of its system id, in MAVLink 2, as a `MAV_AUTOPILOT_PX4`
//! vehicle (flight modes in PX4's `custom_mode` encoding, see [`modes`]). Commands that change
//! the vehicle go to the control loop; their `COMMAND_ACK` follows its answer.

// SET_MODE, REQUEST_DATA_STREAM and PING are deprecated in the spec, and still what MAVProxy
// and older scripts send: honoured on purpose.
#![allow(deprecated)]

mod calibration;
pub mod links;
pub mod mission;
pub mod modes;
pub mod offboard;
pub mod params;
pub mod signing;
pub mod telemetry;

use crate::control_loop::Telemetry;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::{CommanderStatus, FlightMode, LandedState, OffboardTarget, Sticks};
use flight_core::math::geo::LatLonAlt;
use flight_core::params::FlightParams;
use flight_core::safety::failsafe::{Action as FailsafeAction, SafetyEvent};
use mavlink::MavHeader;
use mavlink::MessageData;
use mavlink::dialects::common::*;
use params::Parameters;

/// Our component id (`MAV_COMP_ID_AUTOPILOT1`).
pub const COMPONENT_ID: u8 = 1;

/// `MAV_CMD_COMPONENT_ARM_DISARM` param2 that forces the command.
const FORCE_MAGIC: f32 = 21196.0;

/// Messages sent without being asked, with their default rates (Hz), PX4-like.
const DEFAULT_STREAMS: [(u32, f64); 16] = [
    (HEARTBEAT_DATA::ID, 1.0),
    (SYS_STATUS_DATA::ID, 1.0),
    (EXTENDED_SYS_STATE_DATA::ID, 1.0),
    (GLOBAL_POSITION_INT_DATA::ID, 5.0),
    (LOCAL_POSITION_NED_DATA::ID, 5.0),
    (GPS_RAW_INT_DATA::ID, 2.0),
    (ATTITUDE_DATA::ID, 10.0),
    (ATTITUDE_QUATERNION_DATA::ID, 10.0),
    (VFR_HUD_DATA::ID, 4.0),
    (BATTERY_STATUS_DATA::ID, 1.0),
    (HOME_POSITION_DATA::ID, 0.5),
    (ALTITUDE_DATA::ID, 1.0),
    (SYSTEM_TIME_DATA::ID, 1.0),
    (CURRENT_MODE_DATA::ID, 1.0),
    // The set-points flown, echoed (PX4's normal stream set has them too).
    (ATTITUDE_TARGET_DATA::ID, 2.0),
    (POSITION_TARGET_LOCAL_NED_DATA::ID, 1.0),
];

/// Slowest and fastest stream rates a ground station may ask for (Hz).
const RATE_RANGE_HZ: (f64, f64) = (0.01, 100.0);

/// What the vehicle sends: a message, or a raw payload the dialect cannot express. (Held for
/// a moment in the outbox; the size difference is harmless.)
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Outgoing {
    /// A message.
    Message(MavMessage),
    /// A message id and its payload bytes.
    Raw(u32, Vec<u8>),
}

/// Who to acknowledge a command to, and which command it was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AckTo {
    /// The command.
    pub command: MavCmd,
    /// The requester.
    pub system: u8,
    /// The requester's component.
    pub component: u8,
    /// No `COMMAND_ACK` (a message that is not a command, e.g. `MISSION_SET_CURRENT`): only a
    /// refusal is said, in a `STATUSTEXT`.
    pub quiet: bool,
}

/// Work for the links' task that is not a message: I/O and the process.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    /// The parameter values changed: hand [`GroundStation::parameters`] to the control loop.
    ParamsChanged,
    /// The parameter store changed: save it.
    SaveParams,
    /// `PREFLIGHT_STORAGE` read: load the store again, then [`GroundStation::params_reloaded`].
    ReloadParams(AckTo),
    /// `PREFLIGHT_REBOOT_SHUTDOWN`: stop the control loop and start again (acknowledged).
    Reboot,
    /// `PREFLIGHT_REBOOT_SHUTDOWN`: stop the control loop and exit (acknowledged).
    Shutdown,
}

/// What handling a message produced.
#[derive(Debug, Default)]
pub struct Outbox {
    /// Messages to send.
    pub messages: Vec<Outgoing>,
    /// Commands for the control loop; each answer comes back to [`GroundStation::answered`].
    pub vehicle: Vec<(AutopilotCommand, AckTo)>,
    /// Other work, in order.
    pub actions: Vec<Action>,
    /// The latest stick positions (`MANUAL_CONTROL`), for the control loop; never answered.
    pub sticks: Option<Sticks>,
    /// The latest offboard set-point, for the control loop; never answered.
    pub offboard: Option<OffboardTarget>,
    /// A new mission for the commander (an upload finished, or the mission was cleared).
    pub mission: Option<mission::NewMission>,
    /// A new geofence (an upload finished, or the fence was cleared).
    pub fence: Option<Vec<flight_core::safety::geofence::GeoZone>>,
    /// A ground station's heartbeat arrived (the link-loss failsafe's clock restarts).
    pub gcs_heartbeat: bool,
    /// The `id` of the last text sent in chunks.
    statustext_id: u16,
}

impl Outbox {
    fn send(&mut self, m: MavMessage) {
        self.messages.push(Outgoing::Message(m));
    }

    /// Tells the operator `text` in `STATUSTEXT`: one message when it fits its 50 bytes, else
    /// chunks of 50 bytes sharing a non-zero `id`, numbered by `chunk_seq`, the last one
    /// shorter (an empty one if need be: a full chunk says more follows), as the MAVLink spec
    /// asks; QGroundControl shows them reassembled, a ground station that does not reassemble
    /// shows the pieces in order. Longer than 255 chunks is cut.
    pub fn say(&mut self, severity: MavSeverity, text: &str) {
        let bytes = text.as_bytes();
        let id = if bytes.len() <= STATUSTEXT_BYTES {
            0
        } else {
            self.statustext_id = self.statustext_id.wrapping_add(1).max(1);
            self.statustext_id
        };
        for chunk_seq in 0..=u8::MAX {
            let from = usize::from(chunk_seq) * STATUSTEXT_BYTES;
            let chunk = &bytes[from.min(bytes.len())..(from + STATUSTEXT_BYTES).min(bytes.len())];
            let mut field = [0u8; STATUSTEXT_BYTES];
            field[..chunk.len()].copy_from_slice(chunk);
            self.send(MavMessage::STATUSTEXT(STATUSTEXT_DATA {
                severity,
                text: field.into(),
                id,
                chunk_seq,
            }));
            if id == 0 || chunk.len() < STATUSTEXT_BYTES {
                return;
            }
        }
    }
}

/// The bytes a `STATUSTEXT` carries.
const STATUSTEXT_BYTES: usize = 50;

/// One stream: its interval and when it is next due (s of the ground station's clock).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stream {
    id: u32,
    interval_s: f64,
    next_s: f64,
}

/// A command as both `COMMAND_LONG` and `COMMAND_INT` carry it: params 5–7 are floats here
/// (`COMMAND_INT`'s x and y arrive as degrees, its z as it is).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Command {
    command: MavCmd,
    p: [f32; 7],
}

/// The ground-station protocol state.
#[derive(Debug)]
pub struct GroundStation {
    system_id: u8,
    mav_type: MavType,
    streams: Vec<Stream>,
    /// One-off messages asked for (REQUEST_MESSAGE), sent on the next poll.
    requested: Vec<(u32, f32)>,
    /// What the last heartbeat showed: a change sends one at once.
    shown: Option<(bool, FlightMode, LandedState)>,
    home_shown: Option<[f64; 3]>,
    /// Messages that could not be parsed or were not for us.
    pub dropped: u64,
    /// When the clock started, for SYSTEM_TIME.
    unix_start_usec: u64,
    /// The parameter table.
    params: Parameters,
    /// The values a reset returns to (`flight.toml` and the command line).
    base_params: FlightParams,
    /// Manual-control losses already reported.
    manual_losses_shown: u32,
    /// Offboard losses already reported.
    offboard_losses_shown: u32,
    /// Failsafe events already said (the count of the commander's log).
    safety_events_shown: u64,
    /// The failed motor last announced (1-based).
    motor_failed_shown: Option<usize>,
    /// The sensor link's state as last said: frames silent, source restarts.
    sensors_silent_shown: bool,
    source_restarts_shown: u32,
    /// Offboard set-points dropped as malformed or unsupported.
    pub offboard_refused: u64,
    /// The mission, fence and rally plans and their transfers.
    pub missions: mission::Missions,
    /// The mission progress last shown (current item, state, items reached).
    mission_shown: Option<(u16, flight_core::mission::MissionState)>,
    reached_shown: u32,
    /// When MISSION_CURRENT is next due (s).
    mission_current_next_s: f64,
    /// What has been said of the magnetometer calibration.
    mag_cal_shown: calibration::Shown,
    /// A reboot restarts the process: refused for one of several vehicles in it (`--count`).
    reboot_allowed: bool,
}

impl GroundStation {
    /// The protocol for system `system_id`, a vehicle of `mav_type`.
    pub fn new(system_id: u8, mav_type: MavType) -> Self {
        let unix_start_usec = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        Self {
            system_id,
            mav_type,
            streams: DEFAULT_STREAMS
                .iter()
                .map(|&(id, hz)| Stream {
                    id,
                    interval_s: 1.0 / hz,
                    next_s: 0.0,
                })
                .collect(),
            requested: Vec::new(),
            shown: None,
            home_shown: None,
            dropped: 0,
            unix_start_usec,
            params: Parameters::default(),
            base_params: FlightParams::default(),
            manual_losses_shown: 0,
            offboard_losses_shown: 0,
            safety_events_shown: 0,
            motor_failed_shown: None,
            sensors_silent_shown: false,
            source_restarts_shown: 0,
            offboard_refused: 0,
            missions: mission::Missions::default(),
            mission_shown: None,
            reached_shown: 0,
            mission_current_next_s: 0.0,
            mag_cal_shown: Default::default(),
            reboot_allowed: true,
        }
    }

    /// Whether `MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN` may reboot: not for one of several vehicles
    /// flown by one process, whose reboot would restart them all (a shutdown still ends it).
    pub fn with_reboot(mut self, allowed: bool) -> Self {
        self.reboot_allowed = allowed;
        self
    }

    /// With this parameter table; a reset returns to `base`.
    pub fn with_parameters(mut self, params: Parameters, base: FlightParams) -> Self {
        self.params = params;
        self.base_params = base;
        self
    }

    /// The parameter table.
    pub fn parameters(&self) -> &Parameters {
        &self.params
    }

    /// The values a reset returns to.
    pub fn base_parameters(&self) -> &FlightParams {
        &self.base_params
    }

    /// The store was read again (`PREFLIGHT_STORAGE`): fly `loaded`, or say why not.
    pub fn params_reloaded(
        &mut self,
        to: AckTo,
        loaded: Result<crate::records::param_store::Loaded, String>,
        out: &mut Outbox,
    ) {
        match loaded {
            Ok(l) => {
                for w in &l.warnings {
                    out.say(MavSeverity::MAV_SEVERITY_WARNING, w);
                }
                self.params.replace(l.params, l.store);
                out.actions.push(Action::ParamsChanged);
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
            }
            Err(e) => {
                out.send(self.ack(to, MavResult::MAV_RESULT_FAILED));
                out.say(MavSeverity::MAV_SEVERITY_ERROR, &e);
            }
        }
    }

    /// The MAVLink vehicle type of an airframe with `rotors` rotors.
    pub fn mav_type(rotors: usize) -> MavType {
        match rotors {
            6 => MavType::MAV_TYPE_HEXAROTOR,
            8 => MavType::MAV_TYPE_OCTOROTOR,
            12 => MavType::MAV_TYPE_DODECAROTOR,
            _ => MavType::MAV_TYPE_QUADROTOR,
        }
    }

    /// The current interval of message `id` (s), if it is streamed.
    pub fn interval_s(&self, id: u32) -> Option<f64> {
        self.streams
            .iter()
            .find(|s| s.id == id)
            .map(|s| s.interval_s)
    }

    /// Sends what is due at `now_s`: streams, requested messages, and a heartbeat at once when
    /// the armed state, mode or landed state changed.
    pub fn poll(&mut self, now_s: f64, t: &Telemetry, out: &mut Outbox) {
        let unix = self.unix_start_usec + (now_s * 1e6) as u64;
        let shown = t.status.map(|s| (s.armed, s.mode, s.landed));
        if shown != self.shown {
            self.shown = shown;
            out.send(telemetry::heartbeat(t, self.mav_type));
            for id in [EXTENDED_SYS_STATE_DATA::ID, CURRENT_MODE_DATA::ID] {
                out.messages
                    .extend(telemetry::build(id, t, unix).map(Outgoing::Message));
            }
            if let Some(s) = self.streams.iter_mut().find(|s| s.id == HEARTBEAT_DATA::ID) {
                s.next_s = now_s + s.interval_s;
            }
        }
        let losses = t.status.map_or(0, |s| s.manual_losses);
        if losses > self.manual_losses_shown {
            self.manual_losses_shown = losses;
            out.say(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                "manual control lost: Hold",
            );
        }
        let losses = t.status.map_or(0, |s| s.offboard_losses);
        if losses > self.offboard_losses_shown {
            self.offboard_losses_shown = losses;
            let mode = t.status.map_or("Hold", |s| s.mode.name());
            out.say(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                &format!("offboard set-points lost: {mode}"),
            );
        }
        let motor = t.status.and_then(|s| s.motor_failed);
        if motor != self.motor_failed_shown {
            self.motor_failed_shown = motor;
            if let Some(m) = motor {
                out.say(
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &format!("motor {m} failed: flying on the others"),
                );
            }
        }
        // Said before the frames are back: it is why.
        if t.source_restarts > self.source_restarts_shown {
            self.source_restarts_shown = t.source_restarts;
            out.say(
                MavSeverity::MAV_SEVERITY_WARNING,
                "sensor source restarted: vehicle reset",
            );
        }
        if t.sensors_silent != self.sensors_silent_shown {
            self.sensors_silent_shown = t.sensors_silent;
            if t.sensors_silent {
                out.say(
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &format!(
                        "sensor frames stopped: {}",
                        t.status
                            .map_or("-", |s| if s.armed { s.mode.name() } else { "disarmed" })
                    ),
                );
            } else {
                out.say(MavSeverity::MAV_SEVERITY_NOTICE, "sensor frames back");
            }
        }
        if let Some(log) = t.status.map(|s| s.safety_log) {
            // Each failsafe event once, in the state machine's words, however short-lived.
            let (missed, events) = log.since(self.safety_events_shown);
            if missed > 0 {
                out.say(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!("{missed} failsafe messages missed"),
                );
            }
            for e in events {
                let severity = match e {
                    SafetyEvent::Cleared(_) => MavSeverity::MAV_SEVERITY_NOTICE,
                    SafetyEvent::Triggered(_, FailsafeAction::None | FailsafeAction::Warn) => {
                        MavSeverity::MAV_SEVERITY_WARNING
                    }
                    _ => MavSeverity::MAV_SEVERITY_CRITICAL,
                };
                out.say(severity, &e.to_string());
            }
            self.safety_events_shown = log.count;
        }
        let home = t.status.and_then(|s| s.home).map(|h| [h.0.x, h.0.y, h.0.z]);
        if home.is_some() && home != self.home_shown {
            // HOME_POSITION on every change, as PX4.
            self.home_shown = home;
            out.messages
                .extend(telemetry::build(HOME_POSITION_DATA::ID, t, unix).map(Outgoing::Message));
        }
        self.missions.poll(now_s, out);
        self.report_calibration(t, out);
        if let Some(status) = t.status {
            let m = status.mission;
            // MISSION_ITEM_REACHED once per item, then MISSION_CURRENT (at 1 Hz and on every
            // change) saying where the mission went on.
            for seq in m.reached_since(self.reached_shown) {
                out.send(MavMessage::MISSION_ITEM_REACHED(
                    MISSION_ITEM_REACHED_DATA { seq },
                ));
            }
            self.reached_shown = m.reached_count;
            let shown = (m.current, m.state);
            if self.mission_shown != Some(shown) || now_s >= self.mission_current_next_s {
                self.mission_shown = Some(shown);
                self.mission_current_next_s = now_s + 1.0;
                out.send(self.mission_current(&status));
            }
        }
        for s in &mut self.streams {
            if now_s < s.next_s {
                continue;
            }
            // Keep the phase; after a long gap start afresh rather than burst.
            s.next_s = if now_s - s.next_s > s.interval_s {
                now_s + s.interval_s
            } else {
                s.next_s + s.interval_s
            };
            let m = if s.id == HEARTBEAT_DATA::ID {
                Some(telemetry::heartbeat(t, self.mav_type))
            } else {
                telemetry::build(s.id, t, unix)
            };
            out.messages.extend(m.map(Outgoing::Message));
        }
        for (id, param) in std::mem::take(&mut self.requested) {
            out.messages
                .extend(self.one_off(id, param, t, unix).map(Outgoing::Message));
        }
    }

    /// `MISSION_CURRENT`: the mission's current item, size and state, and the plans' ids.
    fn mission_current(&self, s: &CommanderStatus) -> MavMessage {
        use flight_core::mission::MissionState as S;
        let m = s.mission;
        MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq: m.current,
            total: if m.total == 0 { u16::MAX } else { m.total },
            mission_state: match m.state {
                S::NoMission => MissionState::MISSION_STATE_NO_MISSION,
                S::NotStarted => MissionState::MISSION_STATE_NOT_STARTED,
                S::Active => MissionState::MISSION_STATE_ACTIVE,
                S::Paused => MissionState::MISSION_STATE_PAUSED,
                S::Complete => MissionState::MISSION_STATE_COMPLETE,
            },
            mission_mode: if s.mode == FlightMode::Mission { 1 } else { 2 },
            mission_id: self
                .missions
                .opaque_id(MavMissionType::MAV_MISSION_TYPE_MISSION),
            fence_id: self
                .missions
                .opaque_id(MavMissionType::MAV_MISSION_TYPE_FENCE),
            rally_points_id: self
                .missions
                .opaque_id(MavMissionType::MAV_MISSION_TYPE_RALLY),
        })
    }

    /// A message sent once on request.
    fn one_off(&self, id: u32, param: f32, t: &Telemetry, unix: u64) -> Option<MavMessage> {
        match id {
            HEARTBEAT_DATA::ID => Some(telemetry::heartbeat(t, self.mav_type)),
            AUTOPILOT_VERSION_DATA::ID => Some(self.autopilot_version()),
            AVAILABLE_MODES_DATA::ID => telemetry::available_mode(param as usize),
            _ => telemetry::build(id, t, unix),
        }
    }

    /// Whether REQUEST_MESSAGE can give message `id`.
    fn can_send(id: u32) -> bool {
        DEFAULT_STREAMS.iter().any(|&(i, _)| i == id)
            || telemetry::ON_REQUEST.contains(&id)
            || matches!(id, AUTOPILOT_VERSION_DATA::ID | AVAILABLE_MODES_DATA::ID)
    }

    /// `AUTOPILOT_VERSION`: what this vehicle speaks, its version and a uid from its system id.
    pub fn autopilot_version(&self) -> MavMessage {
        let v = |s: &str| s.parse::<u32>().unwrap_or(0);
        let version = (v(env!("CARGO_PKG_VERSION_MAJOR")) << 24)
            | (v(env!("CARGO_PKG_VERSION_MINOR")) << 16)
            | (v(env!("CARGO_PKG_VERSION_PATCH")) << 8)
            | 0xFF; // FIRMWARE_VERSION_TYPE_OFFICIAL
        MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
            capabilities: MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
            uid: 0x4155_5450_0000_0000 | self.system_id as u64,
            flight_sw_version: version,
            ..Default::default()
        })
    }

    fn ack(&self, to: AckTo, result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: to.command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: to.system,
            target_component: to.component,
        })
    }

    /// The control loop's answer to a command sent through [`Outbox::vehicle`]: the ack, and
    /// the reason in a `STATUSTEXT` when denied.
    pub fn answered(&mut self, to: AckTo, result: Result<(), String>, out: &mut Outbox) {
        if to.quiet {
            if let Err(reason) = result {
                out.say(MavSeverity::MAV_SEVERITY_WARNING, &reason);
            }
            return;
        }
        match result {
            Ok(()) => out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED)),
            Err(reason) => {
                out.send(self.ack(to, MavResult::MAV_RESULT_DENIED));
                out.say(MavSeverity::MAV_SEVERITY_WARNING, &reason);
            }
        }
    }

    /// Whether a message addressed to (`system`, `component`) is ours: system 0 is everyone,
    /// component 0 every component of ours.
    /// An offboard set-point for the control loop, or a refusal counted and logged (a stream
    /// gets no answer either way, as in PX4).
    fn offboard(&mut self, target: Result<OffboardTarget, offboard::Refusal>, out: &mut Outbox) {
        match target {
            Ok(t) => out.offboard = Some(t),
            Err(why) => {
                self.offboard_refused += 1;
                tracing::debug!("offboard set-point dropped: {why}");
            }
        }
    }

    fn for_us(&self, system: u8, component: Option<u8>) -> bool {
        (system == 0 || system == self.system_id)
            && component.is_none_or(|c| c == 0 || c == COMPONENT_ID)
    }

    /// Handles one message from `from`, with the latest telemetry at hand.
    pub fn on_message(
        &mut self,
        from: &MavHeader,
        msg: &MavMessage,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let requester = |command| AckTo {
            command,
            system: from.system_id as u8,
            component: from.component_id,
            quiet: false,
        };
        if let Some((system, component)) = mission::target(msg) {
            if self.for_us(system, Some(component)) {
                if let MavMessage::MISSION_SET_CURRENT(m) = msg {
                    let to = AckTo {
                        quiet: true,
                        ..requester(MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT)
                    };
                    out.vehicle
                        .push((AutopilotCommand::SetMissionCurrent(m.seq), to));
                } else {
                    self.missions.on_message(from, msg, out);
                }
            } else {
                self.dropped += 1;
            }
            return;
        }
        if let Some(change) = self.on_param_message(msg, out) {
            if change.values {
                out.actions.push(Action::ParamsChanged);
            }
            if change.store {
                out.actions.push(Action::SaveParams);
            }
            return;
        }
        match msg {
            MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS => {
                out.gcs_heartbeat = true;
            }
            MavMessage::COMMAND_LONG(c) => {
                if !self.for_us(c.target_system, Some(c.target_component)) {
                    self.dropped += 1;
                    return;
                }
                let p = [
                    c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                ];
                let cmd = Command {
                    command: c.command,
                    p,
                };
                self.command(cmd, requester(c.command), t, out);
            }
            MavMessage::COMMAND_INT(c) => {
                if !self.for_us(c.target_system, Some(c.target_component)) {
                    self.dropped += 1;
                    return;
                }
                let p = [
                    c.param1,
                    c.param2,
                    c.param3,
                    c.param4,
                    (c.x as f64 * 1e-7) as f32,
                    (c.y as f64 * 1e-7) as f32,
                    c.z,
                ];
                let cmd = Command {
                    command: c.command,
                    p,
                };
                // Latitude and longitude need their 1e-7 precision: the global commands read
                // x and y from the message itself.
                let global = (c.x != 0 || c.y != 0).then_some((c.x, c.y));
                self.command_int(cmd, global, c.frame, requester(c.command), t, out);
            }
            MavMessage::SET_MODE(m) => {
                if !self.for_us(m.target_system, None) {
                    self.dropped += 1;
                    return;
                }
                // The legacy message, acknowledged as MAV_CMD_DO_SET_MODE (as PX4 does).
                let to = requester(MavCmd::MAV_CMD_DO_SET_MODE);
                let p = [
                    m.base_mode.bits() as f32,
                    ((m.custom_mode >> 16) & 0xFF) as f32,
                    (m.custom_mode >> 24) as f32,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ];
                let cmd = Command {
                    command: MavCmd::MAV_CMD_DO_SET_MODE,
                    p,
                };
                self.command(cmd, to, t, out);
            }
            MavMessage::MANUAL_CONTROL(m) if self.for_us(m.target, None) => {
                out.sticks = Some(sticks(m));
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(m)
                if self.for_us(m.target_system, Some(m.target_component)) =>
            {
                self.offboard(offboard::local_ned(m, t), out);
            }
            MavMessage::SET_POSITION_TARGET_GLOBAL_INT(m)
                if self.for_us(m.target_system, Some(m.target_component)) =>
            {
                self.offboard(offboard::global_int(m, t), out);
            }
            MavMessage::SET_ATTITUDE_TARGET(m)
                if self.for_us(m.target_system, Some(m.target_component)) =>
            {
                self.offboard(offboard::attitude(m), out);
            }
            MavMessage::REQUEST_DATA_STREAM(r)
                if self.for_us(r.target_system, Some(r.target_component)) =>
            {
                self.data_stream(r);
            }
            MavMessage::PING(p) if p.target_system == 0 => {
                out.send(MavMessage::PING(PING_DATA {
                    time_usec: p.time_usec,
                    seq: p.seq,
                    target_system: from.system_id as u8,
                    target_component: from.component_id,
                }));
            }
            MavMessage::TIMESYNC(s) if s.tc1 == 0 => {
                let now_ns = (t.t_s * 1e9) as i64;
                out.send(MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: now_ns,
                    ts1: s.ts1,
                    target_system: from.system_id as u8,
                    target_component: from.component_id,
                }));
            }
            MavMessage::FILE_TRANSFER_PROTOCOL(f)
                if self.for_us(f.target_system, Some(f.target_component)) =>
            {
                out.send(ftp_nak(f, from));
            }
            _ => {}
        }
    }

    /// A frame whose payload did not parse: a command with an id this dialect does not know
    /// is still acknowledged, as UNSUPPORTED.
    pub fn on_unparsed(&mut self, raw: &hil::RawMessage, out: &mut Outbox) {
        self.dropped += 1;
        if raw.msg_id != COMMAND_LONG_DATA::ID && raw.msg_id != COMMAND_INT_DATA::ID {
            return;
        }
        // Both carry the command id at byte 28 and the target at 30–31.
        let mut p = [0u8; 35];
        let n = raw.payload.len().min(35);
        p[..n].copy_from_slice(&raw.payload[..n]);
        if !self.for_us(p[30], Some(p[31])) {
            return;
        }
        // COMMAND_ACK: command u16, result u8, progress u8, result_param2 i32,
        // target_system u8, target_component u8.
        let mut ack = [0u8; 10];
        ack[0..2].copy_from_slice(&p[28..30]);
        ack[2] = MavResult::MAV_RESULT_UNSUPPORTED as u8;
        ack[8] = raw.header.system_id as u8;
        ack[9] = raw.header.component_id;
        out.messages
            .push(Outgoing::Raw(COMMAND_ACK_DATA::ID, ack.to_vec()));
    }

    fn data_stream(&mut self, r: &REQUEST_DATA_STREAM_DATA) {
        use MavDataStream::*;
        let ids: &[u32] = match r.req_stream_id {
            MAV_DATA_STREAM_ALL => &[],
            MAV_DATA_STREAM_EXTENDED_STATUS => &[SYS_STATUS_DATA::ID, GPS_RAW_INT_DATA::ID],
            MAV_DATA_STREAM_POSITION => {
                &[GLOBAL_POSITION_INT_DATA::ID, LOCAL_POSITION_NED_DATA::ID]
            }
            MAV_DATA_STREAM_EXTRA1 => &[ATTITUDE_DATA::ID],
            MAV_DATA_STREAM_EXTRA2 => &[VFR_HUD_DATA::ID],
            MAV_DATA_STREAM_EXTRA3 => &[BATTERY_STATUS_DATA::ID, SYSTEM_TIME_DATA::ID],
            _ => return,
        };
        let all: Vec<u32>;
        let ids = if ids.is_empty() {
            all = DEFAULT_STREAMS
                .iter()
                .map(|s| s.0)
                .filter(|&i| i != HEARTBEAT_DATA::ID)
                .collect();
            &all[..]
        } else {
            ids
        };
        for &id in ids {
            let hz = if r.start_stop == 0 {
                None
            } else {
                Some(r.req_message_rate as f64)
            };
            self.set_rate(id, hz.filter(|&h| h > 0.0));
        }
    }

    /// Sets message `id` to `hz` (`None`: off).
    fn set_rate(&mut self, id: u32, hz: Option<f64>) {
        self.streams.retain(|s| s.id != id);
        if let Some(hz) = hz {
            let hz = hz.clamp(RATE_RANGE_HZ.0, RATE_RANGE_HZ.1);
            self.streams.push(Stream {
                id,
                interval_s: 1.0 / hz,
                next_s: 0.0,
            });
        }
    }

    fn command_int(
        &mut self,
        c: Command,
        global: Option<(i32, i32)>,
        frame: MavFrame,
        to: AckTo,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        if c.command == MavCmd::MAV_CMD_DO_REPOSITION {
            return self.reposition(c, global, frame, to, out);
        }
        if c.command == MavCmd::MAV_CMD_DO_SET_HOME && c.p[0] != 1.0 {
            let Some((x, y)) = global else {
                return out.send(self.ack(to, MavResult::MAV_RESULT_DENIED));
            };
            let p = LatLonAlt {
                lat_deg: x as f64 * 1e-7,
                lon_deg: y as f64 * 1e-7,
                alt_m: c.p[6] as f64,
            };
            return out.vehicle.push((AutopilotCommand::SetHomeGlobal(p), to));
        }
        self.command(c, to, t, out);
    }

    /// `DO_REPOSITION`: param1 speed (−1 default), param2 bit 0 "switch to Hold", param4
    /// yaw (NaN keeps; in radians, as PX4 reads it and MAVSDK's `goto_location` sends it,
    /// although the MAVLink spec says degrees), x/y latitude and longitude (absent or `INT32_MAX`: keep), z the
    /// altitude in `frame` (NaN: keep).
    fn reposition(
        &mut self,
        c: Command,
        global: Option<(i32, i32)>,
        frame: MavFrame,
        to: AckTo,
        out: &mut Outbox,
    ) {
        let p = c.p;
        let relative = match frame {
            MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => false,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => true,
            f => {
                out.send(self.ack(to, MavResult::MAV_RESULT_DENIED));
                let why = format!("reposition: frame {f:?} not supported");
                return out.say(MavSeverity::MAV_SEVERITY_WARNING, &why);
            }
        };
        let z = p[6] as f64;
        let at = flight_core::mission::MissionPoint {
            lat_lon_deg: global
                .filter(|&(x, y)| x != i32::MAX && y != i32::MAX)
                .map(|(x, y)| (x as f64 * 1e-7, y as f64 * 1e-7)),
            alt: z.is_finite().then_some(if relative {
                flight_core::mission::MissionAltitude::AboveHome(z)
            } else {
                flight_core::mission::MissionAltitude::Amsl(z)
            }),
        };
        let cmd = AutopilotCommand::Reposition {
            at,
            speed_m_s: (p[0].is_finite() && p[0] > 0.0).then_some(p[0] as f64),
            yaw_rad: p[3].is_finite().then_some(p[3] as f64),
            change_mode: (p[1] as u32) & 1 == 1,
        };
        out.vehicle.push((cmd, to));
    }

    /// A command: answered here, or passed to the vehicle (answered through
    /// [`GroundStation::answered`]).
    fn command(&mut self, c: Command, to: AckTo, t: &Telemetry, out: &mut Outbox) {
        let p = c.p;
        let deny = |this: &Self, out: &mut Outbox, why: &str| {
            out.send(this.ack(to, MavResult::MAV_RESULT_DENIED));
            out.say(MavSeverity::MAV_SEVERITY_WARNING, why);
        };
        let vehicle = |out: &mut Outbox, v| out.vehicle.push((v, to));
        match c.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                let force = p[1] == FORCE_MAGIC;
                match p[0] {
                    1.0 => vehicle(out, AutopilotCommand::Arm { force }),
                    0.0 => vehicle(out, AutopilotCommand::Disarm { force }),
                    x => deny(
                        self,
                        out,
                        &format!("arm/disarm: param1 must be 0 or 1, got {x}"),
                    ),
                }
            }
            MavCmd::MAV_CMD_NAV_TAKEOFF => {
                // param7: altitude AMSL (PX4); NaN: the take-off altitude parameter.
                if p[6].is_finite() {
                    vehicle(out, AutopilotCommand::TakeoffAmsl(p[6] as f64));
                } else {
                    vehicle(out, AutopilotCommand::Takeoff(None));
                }
            }
            MavCmd::MAV_CMD_NAV_LAND => vehicle(out, AutopilotCommand::SetMode(FlightMode::Land)),
            MavCmd::MAV_CMD_MISSION_START => {
                // param1: the first item (0 and up); the last (param2) is not honoured.
                let first = (p[0].is_finite() && p[0] >= 0.0).then_some(p[0] as u16);
                vehicle(out, AutopilotCommand::StartMission(first));
            }
            MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT => {
                if !(p[0].is_finite() && p[0] >= 0.0) {
                    // −1: no change.
                    return out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                }
                vehicle(out, AutopilotCommand::SetMissionCurrent(p[0] as u16));
            }
            MavCmd::MAV_CMD_DO_PAUSE_CONTINUE => match p[0] {
                0.0 => vehicle(out, AutopilotCommand::SetMode(FlightMode::Loiter)),
                1.0 => vehicle(out, AutopilotCommand::SetMode(FlightMode::Mission)),
                x => deny(
                    self,
                    out,
                    &format!("pause/continue: param1 {x} is not 0 or 1"),
                ),
            },
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => match mission::speed_change(p[1]) {
                Ok(change) => vehicle(out, AutopilotCommand::ChangeSpeed(change)),
                Err(_) => deny(self, out, &format!("change speed: {} m/s refused", p[1])),
            },
            MavCmd::MAV_CMD_CONDITION_YAW => {
                if !p[0].is_finite() {
                    return deny(self, out, "yaw command: angle not finite");
                }
                let rate = (p[1].is_finite() && p[1] > 0.0).then_some(p[1] as f64);
                vehicle(
                    out,
                    AutopilotCommand::ConditionYaw {
                        angle_deg: p[0] as f64,
                        rate_deg_s: rate,
                        direction: p[2].signum() as i8 * (p[2] != 0.0) as i8,
                        relative: p[3] != 0.0,
                    },
                );
            }
            MavCmd::MAV_CMD_DO_REPOSITION => {
                // COMMAND_LONG: latitude and longitude in degrees, altitude AMSL.
                let global = (p[4].is_finite() && p[5].is_finite()).then_some((
                    (p[4] as f64 * 1e7).round() as i32,
                    (p[5] as f64 * 1e7).round() as i32,
                ));
                self.reposition(c, global, MavFrame::MAV_FRAME_GLOBAL, to, out);
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                vehicle(out, AutopilotCommand::SetMode(FlightMode::Rtl));
            }
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM => {
                vehicle(out, AutopilotCommand::SetMode(FlightMode::Loiter));
            }
            MavCmd::MAV_CMD_DO_SET_MODE => {
                let base = p[0] as u32;
                if base & MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() as u32 == 0 {
                    return deny(self, out, "set mode: only PX4 custom modes are supported");
                }
                match modes::from_px4(p[1] as u8, p[2] as u8) {
                    Some(m) => vehicle(out, AutopilotCommand::SetMode(m)),
                    None => deny(
                        self,
                        out,
                        &format!("set mode: no mode {}/{}", p[1] as u8, p[2] as u8),
                    ),
                }
            }
            MavCmd::MAV_CMD_DO_SET_STANDARD_MODE => match modes::from_standard(p[0] as u32) {
                Some(m) => vehicle(out, AutopilotCommand::SetMode(m)),
                None => deny(self, out, &format!("no standard mode {}", p[0])),
            },
            MavCmd::MAV_CMD_DO_SET_HOME => {
                if p[0] == 1.0 {
                    vehicle(out, AutopilotCommand::SetHome(None));
                } else if p[4].is_finite() && p[5].is_finite() && p[6].is_finite() {
                    let g = LatLonAlt {
                        lat_deg: p[4] as f64,
                        lon_deg: p[5] as f64,
                        alt_m: p[6] as f64,
                    };
                    vehicle(out, AutopilotCommand::SetHomeGlobal(g));
                } else {
                    deny(
                        self,
                        out,
                        "set home: latitude, longitude and altitude needed",
                    );
                }
            }
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let id = p[0] as u32;
                if !(p[0].is_finite() && Self::can_send(id)) {
                    return deny(
                        self,
                        out,
                        &format!("message interval: cannot stream {}", p[0]),
                    );
                }
                let us = p[1];
                let hz = match us {
                    -1.0 => None,
                    0.0 => DEFAULT_STREAMS.iter().find(|s| s.0 == id).map(|s| s.1),
                    x if x > 0.0 && x.is_finite() => Some(1e6 / x as f64),
                    x => {
                        return deny(self, out, &format!("message interval: bad interval {x}"));
                    }
                };
                self.set_rate(id, hz);
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
            }
            MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL => {
                let id = p[0] as u32;
                let interval_us = match self.interval_s(id) {
                    Some(s) => (s * 1e6) as i32,
                    None if Self::can_send(id) => -1,
                    None => 0,
                };
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                out.send(MavMessage::MESSAGE_INTERVAL(MESSAGE_INTERVAL_DATA {
                    interval_us,
                    message_id: id as u16,
                }));
            }
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                let id = p[0] as u32;
                if !(p[0].is_finite() && Self::can_send(id)) {
                    return deny(self, out, &format!("request message: cannot send {}", p[0]));
                }
                if self.one_off(id, p[1], t, 0).is_none() {
                    // Known, but no data for it yet (no position, no home).
                    out.send(self.ack(to, MavResult::MAV_RESULT_TEMPORARILY_REJECTED));
                    return;
                }
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                self.requested.push((id, p[1]));
            }
            MavCmd::MAV_CMD_INJECT_FAILURE => {
                match flight_core::safety::failure_injection::Injection::decode(p[0], p[1], p[2]) {
                    Ok(i) => vehicle(out, AutopilotCommand::InjectFailure(i)),
                    Err(why) => {
                        out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED));
                        out.say(MavSeverity::MAV_SEVERITY_WARNING, &why.to_string());
                    }
                }
            }
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                out.send(self.autopilot_version());
            }
            MavCmd::MAV_CMD_PREFLIGHT_STORAGE => {
                let armed = t.status.is_some_and(|s| s.armed);
                // MAV_PFS_CMD: 0 read, 1 write, 2 clear (reset to defaults), 6 nothing.
                match p[0] {
                    0.0 | 2.0 if armed => deny(self, out, "parameters: disarm first"),
                    0.0 => out.actions.push(Action::ReloadParams(to)),
                    1.0 => {
                        out.actions.push(Action::SaveParams);
                        out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                    }
                    2.0 => {
                        let base = self.base_params.clone();
                        self.params.reset(&base);
                        out.actions.push(Action::ParamsChanged);
                        out.actions.push(Action::SaveParams);
                        out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                        out.say(
                            MavSeverity::MAV_SEVERITY_INFO,
                            "parameters reset to defaults",
                        );
                    }
                    6.0 => out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED)),
                    x => deny(self, out, &format!("storage: param1 {x} not supported")),
                }
            }
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN => {
                let armed = t.status.is_some_and(|s| s.armed);
                let action = match p[0] {
                    0.0 => None,
                    1.0 => Some(Action::Reboot),
                    2.0 => Some(Action::Shutdown),
                    x => {
                        return deny(self, out, &format!("reboot: param1 {x} not supported"));
                    }
                };
                if armed && action.is_some() {
                    return deny(self, out, "reboot: disarm first");
                }
                if action == Some(Action::Reboot) && !self.reboot_allowed {
                    return deny(
                        self,
                        out,
                        "reboot: one of several vehicles in one process; restart the process",
                    );
                }
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                if let Some(a) = action {
                    out.actions.push(a);
                    let what = if a == Action::Reboot {
                        "rebooting"
                    } else {
                        "shutting down"
                    };
                    out.say(MavSeverity::MAV_SEVERITY_NOTICE, what);
                }
            }
            MavCmd::MAV_CMD_PREFLIGHT_CALIBRATION => {
                // Params 1–7: gyro, magnetometer, ground pressure, radio, accelerometer,
                // airspeed/compass-motor, ESC/baro; all 0 cancels (PX4, MAVSDK). NaN is a
                // reserved param left unset (MAVSDK leaves 6 and 7 so): 0.
                let off = |x: f32| x == 0.0 || x.is_nan();
                if p.iter().all(|&x| off(x)) {
                    vehicle(out, AutopilotCommand::CancelCalibration);
                } else if p[1] == 1.0 && p.iter().enumerate().all(|(i, &x)| i == 1 || off(x)) {
                    vehicle(out, AutopilotCommand::CalibrateMag);
                } else {
                    out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED));
                    out.say(
                        MavSeverity::MAV_SEVERITY_WARNING,
                        "calibration: only the magnetometer (param2 = 1) is calibrated onboard; \
                         the gyro and accelerometer biases are estimated in flight",
                    );
                }
            }
            MavCmd::MAV_CMD_GET_HOME_POSITION => {
                let home = telemetry::build(HOME_POSITION_DATA::ID, t, 0);
                let result = if home.is_some() {
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                };
                out.send(self.ack(to, result));
                out.messages.extend(home.map(Outgoing::Message));
            }
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}

/// The sticks of a `MANUAL_CONTROL` as PX4 reads them: x pitch (forward +), y roll (right +), r
/// yaw, each ±1000; z throttle 0 to 1000 (500: the centre of altitude and position modes). An
/// axis at `INT16_MAX` is "invalid" in the spec: centred.
fn sticks(m: &MANUAL_CONTROL_DATA) -> Sticks {
    // NaN: centred by `clamped`.
    let axis = |v: i16| {
        if v == i16::MAX {
            f64::NAN
        } else {
            v as f64 / 1000.0
        }
    };
    Sticks {
        forward: axis(m.x),
        right: axis(m.y),
        throttle: axis(m.z),
        yaw: axis(m.r),
    }
    .clamped()
}

/// MAVLink FTP: every request is refused (NAK), so that clients fall back to the parameter
/// and mission protocols at once instead of waiting for a time-out.
fn ftp_nak(f: &FILE_TRANSFER_PROTOCOL_DATA, from: &MavHeader) -> MavMessage {
    const NAK: u8 = 129;
    const ERR_FAIL: u8 = 1;
    const ERR_FILE_NOT_FOUND: u8 = 10;
    const OPEN_FILE_RO: u8 = 4;
    let req = &f.payload;
    let mut payload = [0u8; 251];
    payload[0..3].copy_from_slice(&req[0..3]); // seq, session
    payload[0..2].copy_from_slice(
        &u16::from_le_bytes([req[0], req[1]])
            .wrapping_add(1)
            .to_le_bytes(),
    );
    payload[3] = NAK;
    payload[4] = 1; // size
    payload[5] = req[3]; // the request's opcode
    payload[12] = if req[3] == OPEN_FILE_RO {
        ERR_FILE_NOT_FOUND
    } else {
        ERR_FAIL
    };
    MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
        target_network: 0,
        target_system: from.system_id as u8,
        target_component: from.component_id,
        payload,
    })
}

#[cfg(test)]
pub(crate) mod tests;
