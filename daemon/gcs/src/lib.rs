//! The ground-station side: what the vehicle says and answers on MAVLink, as a pure state
//! machine ([`GroundStation`]) of the messages received, the latest telemetry and the clock.
//! The sockets that carry it are the daemon's.
//!
//! The vehicle speaks as component 1 of its system id, in MAVLink 2, as a `MAV_AUTOPILOT_PX4`
//! vehicle (flight modes in PX4's `custom_mode` encoding, see [`modes`]). Commands that change
//! the vehicle go to the control loop; their `COMMAND_ACK` follows its answer.

// SET_MODE, REQUEST_DATA_STREAM and PING are deprecated in the spec, and still what MAVProxy
// and older scripts send: honoured on purpose.
#![allow(deprecated)]

mod announcements;
mod calibration;
mod commands;
pub mod component_metadata;
pub mod events;
mod incoming;
mod link_rates;
mod stream_sets;
use stream_sets::DEFAULT_STREAMS;
pub use stream_sets::StreamSet;
pub mod mission;
pub mod modes;
mod notices;
pub mod offboard;
pub mod param_store;
pub mod params;
pub mod requests;
mod shell;
pub mod signing;
pub mod streams;
pub mod telemetry;
#[cfg(any(test, feature = "testing"))]
pub mod testing;

pub use commands::answered_commands;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::{CommanderStatus, Denial, FlightMode, OffboardTarget};
use flight_core::params::FlightParams;
pub use link_rates::LinkId;
use link_rates::LinkRates;
use mavlink::MessageData;
use mavlink::dialects::common::*;
use params::Parameters;
pub use requests::{Delivery, Request};
use telemetry::Telemetry;

/// Our component id (`MAV_COMP_ID_AUTOPILOT1`).
pub const COMPONENT_ID: u8 = 1;

/// `MAV_CMD_COMPONENT_ARM_DISARM` param2 that forces the command.
const FORCE_MAGIC: f32 = 21196.0;

/// Slowest and fastest stream rates a ground station may ask for (Hz); sensor messages may
/// go faster, up to the sensor rate.
const RATE_RANGE_HZ: (f64, f64) = (0.01, 100.0);

/// The fastest stream the link task's fixed poll serves well (Hz); faster ones have it poll on
/// every sensor sample ([`GroundStation::wants_every_sample`]).
const POLLED_STREAMS_HZ: f64 = 50.0;

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
    /// How the answer is given.
    pub reply: Reply,
}

/// How the answer to a command is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reply {
    /// A `COMMAND_ACK`, and a refusal's reason in a `STATUSTEXT`.
    Ack,
    /// No `COMMAND_ACK` (a message that is not a command, e.g. `MISSION_SET_CURRENT`): only a
    /// refusal is said, in a `STATUSTEXT`.
    Quiet,
    /// Printed in the MAVLink shell that typed it.
    Shell,
}

/// Work for the links' task that is not a message: I/O and the process.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HostAction {
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
    /// Messages to send, on every link.
    pub messages: Vec<Outgoing>,
    /// Streamed messages to send on one link each (rates are per link).
    pub streamed: Vec<(LinkId, Outgoing)>,
    /// What is asked of the vehicle, in order, each with its delivery rule; an answered
    /// request's answer comes back to [`GroundStation::answered`].
    pub requests: Vec<Request>,
    /// Other work, in order.
    pub actions: Vec<HostAction>,
    /// A ground station's heartbeat arrived (the link-loss failsafe's clock restarts).
    pub gcs_heartbeat: bool,
    /// Every text told the operator, whole (for the host's flight log; drain it).
    pub said: Vec<(MavSeverity, String)>,
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
        self.said.push((severity, text.to_owned()));
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

/// A command as both `COMMAND_LONG` and `COMMAND_INT` carry it: params 5–7 are floats here
/// (`COMMAND_INT`'s x and y arrive as degrees, its z as it is).
#[derive(Debug, Clone, Copy, PartialEq)]
struct CommandMessage {
    command: MavCmd,
    p: [f32; 7],
}

/// The ground-station protocol state.
#[derive(Debug)]
pub struct GroundStation {
    system_id: u8,
    mav_type: MavType,
    /// Each link's streams.
    rates: LinkRates,
    /// The rate the sensor samples arrive at: how fast a sensor message may be streamed.
    sample_rate: link_rates::SampleRate,
    /// The MAVLink shell's session.
    shell: shell::Shell,
    /// The link of the message being handled.
    link: LinkId,
    /// One-off messages asked for (REQUEST_MESSAGE), sent on the next poll.
    requested: Vec<(u32, f32)>,
    /// The general component-metadata file's URI and CRC, when the files are served.
    metadata: Option<(String, u32)>,
    /// The events sent (the events interface).
    events: events::EventLog,
    /// When `CURRENT_EVENT_SEQUENCE` is next due (s).
    events_current_due: f64,
    /// The vehicle's time at the last poll (ms): an event between polls is stamped with it.
    events_now_ms: u32,
    /// Messages that could not be parsed or were not for us.
    pub dropped: u64,
    /// The Unix time when the clock's zero was (µs), for SYSTEM_TIME.
    unix_start_usec: u64,
    /// The parameter table.
    params: Parameters,
    /// The values a reset returns to (`flight.toml` and the command line).
    base_params: FlightParams,
    /// What has been announced of what changed (`announcements.rs`).
    announced: announcements::Announced,
    /// Offboard set-points dropped as malformed or unsupported.
    pub offboard_refused: u64,
    /// The mission, fence and rally plans and their transfers.
    pub missions: mission::Missions,
    /// The sample time (s) of the IMU message last streamed, by link and message.
    imu_sent: Vec<((LinkId, u32), f64)>,
    /// What has been said of the calibrations.
    cal_said: calibration::Said,
    /// A reboot restarts the process: refused for one of several vehicles in it (`--count`).
    reboot_allowed: bool,
    /// The ground stations heard (link, system, component), at most [`MAX_GROUND_STATIONS`]:
    /// one heard for the first time gets every stream of its link at once, so that it need not
    /// wait a second for the first heartbeat and status.
    ground_stations: Vec<(LinkId, u32, u8)>,
}

/// Ground stations remembered for [`GroundStation::ground_stations`]; past them, a new one waits
/// for the streams' own times (a flood of made-up ids cannot buy bursts).
const MAX_GROUND_STATIONS: usize = 64;

impl GroundStation {
    /// A ground station's heartbeat from `from` on the current link: one heard there for the
    /// first time gets the link's streams at once.
    fn heard_ground_station(&mut self, from: &mavlink::MavHeader) {
        let key = (self.link, from.system_id, from.component_id);
        if !self.ground_stations.contains(&key) && self.ground_stations.len() < MAX_GROUND_STATIONS
        {
            self.ground_stations.push(key);
            self.rates.restart(self.link);
        }
    }

    /// The protocol for system `system_id`, a vehicle of `mav_type`.
    pub fn new(system_id: u8, mav_type: MavType) -> Self {
        Self {
            system_id,
            mav_type,
            rates: LinkRates::default(),
            sample_rate: Default::default(),
            shell: Default::default(),
            link: 0,
            requested: Vec::new(),
            metadata: None,
            events: Default::default(),
            events_current_due: 0.0,
            events_now_ms: 0,
            dropped: 0,
            unix_start_usec: 0,
            params: Parameters::default(),
            base_params: FlightParams::default(),
            announced: Default::default(),
            offboard_refused: 0,
            missions: mission::Missions::default(),
            imu_sent: Vec::new(),
            cal_said: Default::default(),
            reboot_allowed: true,
            ground_stations: Vec::new(),
        }
    }

    /// With the Unix time (µs) at which the clock given to [`Self::poll`] was zero, for
    /// `SYSTEM_TIME` (0 until told: the protocol reads no clock).
    pub fn with_unix_start(mut self, unix_usec: u64) -> Self {
        self.unix_start_usec = unix_usec;
        self
    }

    /// Whether `MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN` may reboot: not for one of several vehicles
    /// flown by one process, whose reboot would restart them all (a shutdown still ends it).
    pub fn with_reboot(mut self, allowed: bool) -> Self {
        self.reboot_allowed = allowed;
        self
    }

    /// Answers `REQUEST_MESSAGE(COMPONENT_METADATA)` with the general metadata file's `uri`
    /// and `crc` (the host serves the files: [`component_metadata::ComponentMetadata`]).
    pub fn with_component_metadata(mut self, uri: &str, crc: u32) -> Self {
        self.metadata = Some((uri.to_owned(), crc));
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
        loaded: Result<param_store::Loaded, param_store::Unreadable>,
        out: &mut Outbox,
    ) {
        match loaded {
            Ok(l) => {
                for w in &l.warnings {
                    out.say(MavSeverity::MAV_SEVERITY_WARNING, w);
                }
                self.params.replace(l.params, l.store);
                out.actions.push(HostAction::ParamsChanged);
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
            }
            Err(e) => {
                out.send(self.ack(to, MavResult::MAV_RESULT_FAILED));
                out.say(MavSeverity::MAV_SEVERITY_ERROR, &e.to_string());
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

    /// The current interval of message `id` (s) on the link of the message being handled (link
    /// 0 between messages), if it is streamed there.
    pub fn interval_s(&self, id: u32) -> Option<f64> {
        self.rates.interval_s(self.link, id)
    }

    /// A link (endpoint) the vehicle streams on, with the default streams from now on; link 0
    /// always is one.
    pub fn add_link(&mut self, link: LinkId) {
        self.rates.add(link);
    }

    /// A link the vehicle streams on, starting with stream set `set`.
    pub fn add_link_with(&mut self, link: LinkId, set: StreamSet) {
        self.rates.add_with(link, set);
    }

    /// Sends what is due at `now_s`: streams, requested messages, and a heartbeat at once when
    /// the armed state, mode or landed state changed.
    pub fn poll(&mut self, now_s: f64, t: &Telemetry, out: &mut Outbox) {
        let unix = self.unix_start_usec + (now_s * 1e6) as u64;
        self.sample_rate.observe(t.link.t_s, t.link.frames);
        self.events_poll(now_s, t, out);
        self.params.poll_list(out);
        self.announce(now_s, t, unix, out);
        for (link, id) in self.rates.due(now_s) {
            if [HIGHRES_IMU_DATA::ID, SCALED_IMU_DATA::ID].contains(&id) {
                // One IMU sample per message, as PX4 sends them on new data: a slot that comes
                // before the next sample (a vehicle slower than the wall clock) is skipped.
                let sent = &mut self.imu_sent;
                match sent.iter_mut().find(|s| s.0 == (link, id)) {
                    Some(s) if s.1 == t.link.t_s => continue,
                    Some(s) => s.1 = t.link.t_s,
                    None => sent.push(((link, id), t.link.t_s)),
                }
            }
            let m = if id == HEARTBEAT_DATA::ID {
                Some(streams::heartbeat(t, self.mav_type))
            } else {
                streams::build(id, t, unix)
            };
            out.streamed.extend(m.map(|m| (link, Outgoing::Message(m))));
        }
        self.shell_poll(now_s, t, out);
        self.follow_target_poll(t, out);
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
            HEARTBEAT_DATA::ID => Some(streams::heartbeat(t, self.mav_type)),
            AUTOPILOT_VERSION_DATA::ID => Some(self.autopilot_version()),
            AVAILABLE_MODES_DATA::ID => streams::available_mode(param as usize),
            MISSION_CURRENT_DATA::ID => t.status().map(|s| self.mission_current(&s)),
            COMPONENT_METADATA_DATA::ID => self.metadata.as_ref().map(|(uri, crc)| {
                MavMessage::COMPONENT_METADATA(COMPONENT_METADATA_DATA {
                    time_boot_ms: (t.link.t_s * 1e3) as u32,
                    file_crc: *crc,
                    uri: uri.as_str().into(),
                })
            }),
            // The legacy form of the same (PX4 still answers it; QGC falls back to it).
            COMPONENT_INFORMATION_DATA::ID => self.metadata.as_ref().map(|(uri, crc)| {
                MavMessage::COMPONENT_INFORMATION(COMPONENT_INFORMATION_DATA {
                    time_boot_ms: (t.link.t_s * 1e3) as u32,
                    general_metadata_file_crc: *crc,
                    peripherals_metadata_file_crc: 0,
                    general_metadata_uri: uri.as_str().into(),
                    peripherals_metadata_uri: "".into(),
                })
            }),
            _ => streams::build(id, t, unix),
        }
    }

    /// Whether message `id` can be streamed at a rate (`SET_MESSAGE_INTERVAL`).
    fn can_stream(id: u32) -> bool {
        DEFAULT_STREAMS.iter().any(|&(i, _)| i == id) || streams::ON_REQUEST.contains(&id)
    }

    /// Whether REQUEST_MESSAGE can give message `id`.
    fn can_send(&self, id: u32) -> bool {
        DEFAULT_STREAMS.iter().any(|&(i, _)| i == id)
            || streams::ON_REQUEST.contains(&id)
            || matches!(
                id,
                AUTOPILOT_VERSION_DATA::ID | AVAILABLE_MODES_DATA::ID | MISSION_CURRENT_DATA::ID
            )
            || (matches!(
                id,
                COMPONENT_METADATA_DATA::ID | COMPONENT_INFORMATION_DATA::ID
            ) && self.metadata.is_some())
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
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
                | if self.metadata.is_some() {
                    // FTP serves files (the metadata among them).
                    MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FTP
                } else {
                    MavProtocolCapability::empty()
                },
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

    /// Refuses the command with `why` said to the operator.
    fn deny(&self, to: AckTo, out: &mut Outbox, why: &str) {
        out.send(self.ack(to, MavResult::MAV_RESULT_DENIED));
        out.say(MavSeverity::MAV_SEVERITY_WARNING, why);
    }

    /// The control loop's answer to an answered request (see [`Delivery::Answered`]): the ack, and
    /// the reason in a `STATUSTEXT` when denied.
    pub fn answered(&mut self, to: AckTo, result: Result<(), Denial>, out: &mut Outbox) {
        match to.reply {
            Reply::Ack => {}
            Reply::Quiet if to.command == MavCmd::MAV_CMD_DO_FOLLOW => {
                return self.follow_fix_answered(result, out);
            }
            Reply::Quiet => {
                if let Err(reason) = result {
                    out.say(MavSeverity::MAV_SEVERITY_WARNING, &reason.to_string());
                }
                return;
            }
            Reply::Shell => return self.shell_answer(to, result),
        }
        match result {
            Ok(()) => out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED)),
            Err(reason) => {
                if let Denial::Arming(why) = &reason {
                    self.arming_denied_event(why, out);
                }
                self.deny(to, out, &reason.to_string())
            }
        }
    }

    /// An offboard set-point for the control loop, or a refusal counted and logged (a stream
    /// gets no answer either way, as in PX4).
    fn offboard(&mut self, target: Result<OffboardTarget, offboard::Refusal>, out: &mut Outbox) {
        match target {
            Ok(t) => out.request(AutopilotCommand::Offboard(t), Delivery::Latest),
            Err(why) => {
                self.offboard_refused += 1;
                tracing::debug!("offboard set-point dropped: {why}");
            }
        }
    }

    /// Whether a message addressed to (`system`, `component`) is ours: system 0 is everyone,
    /// component 0 every component of ours.
    fn for_us(&self, system: u8, component: Option<u8>) -> bool {
        (system == 0 || system == self.system_id)
            && component.is_none_or(|c| c == 0 || c == COMPONENT_ID)
    }
}

#[cfg(test)]
pub(crate) mod tests;
