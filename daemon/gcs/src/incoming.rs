//! What the ground station does with each message it receives: mission, parameter and
//! calibration messages go to their parts, streams are set, and commands are answered here or
//! passed to the vehicle.

use super::{
    AckTo, CommandMessage, DEFAULT_STREAMS, GroundStation, HostAction, LinkId, Outbox, Outgoing,
    mission, offboard,
};
use crate::telemetry::Telemetry;
use crate::{Delivery, Reply};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::Sticks;
use flight_core::safety::targets::TargetLimits;
use mavlink::MavHeader;
use mavlink::MessageData;
use mavlink::dialects::common::*;

impl GroundStation {
    /// What an uploaded mission item is checked against now: the parameters' limits, and home
    /// once the vehicle has one and a global position.
    fn mission_bounds(&self, t: &Telemetry) -> mission::MissionBounds {
        let origin = t.estimate().as_ref().and_then(|o| o.translation.origin);
        let home = t.status().as_ref().and_then(|s| s.home).map(|h| h.0);
        mission::MissionBounds {
            limits: TargetLimits::new(&self.params.values().safety),
            home: origin.zip(home),
        }
    }

    /// Handles one message from `from` that arrived on `link`, with the latest telemetry at
    /// hand: what it asks of the streams is asked of that link's.
    pub fn on_link_message(
        &mut self,
        link: LinkId,
        from: &MavHeader,
        msg: &MavMessage,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        self.rates.add(link);
        self.link = link;
        self.on_message(from, msg, t, out);
        self.link = 0;
    }

    /// Handles one message from `from` (on link 0, or the link [`Self::on_link_message`]
    /// names), with the latest telemetry at hand.
    pub fn on_message(
        &mut self,
        from: &MavHeader,
        msg: &MavMessage,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let requester = |command| acked(from, command);
        if let Some((system, component)) = mission::target(msg) {
            return self.on_mission_message(system, component, from, msg, t, out);
        }
        if let Some(change) = self.on_param_message(msg, out) {
            if change.values {
                out.actions.push(HostAction::ParamsChanged);
            }
            if change.store {
                out.actions.push(HostAction::SaveParams);
            }
            return;
        }
        match msg {
            MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS => {
                out.gcs_heartbeat = true;
                self.heard_ground_station(from);
            }
            MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_) | MavMessage::SET_MODE(_) => {
                self.on_command_message(from, msg, t, out);
            }
            MavMessage::MANUAL_CONTROL(m) if self.for_us(m.target, None) => {
                out.request(AutopilotCommand::Sticks(sticks(m)), Delivery::Latest);
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
            MavMessage::FOLLOW_TARGET(m) => {
                // A stream, no ack: a refusal is said (Follow Target holds meanwhile).
                let to = AckTo {
                    reply: Reply::Quiet,
                    ..requester(MavCmd::MAV_CMD_DO_FOLLOW)
                };
                match follow_target(m) {
                    Some(cmd) => out.request(cmd, Delivery::Answered(to)),
                    None => {
                        self.dropped += 1;
                        tracing::debug!(?m, "FOLLOW_TARGET dropped: not a place");
                    }
                }
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
            MavMessage::REQUEST_EVENT(r)
                if self.for_us(r.target_system, Some(r.target_component)) =>
            {
                self.events_requested(r, from, out);
            }
            MavMessage::TIMESYNC(s) if s.tc1 == 0 => {
                let now_ns = (t.link.t_s * 1e9) as i64;
                out.send(MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: now_ns,
                    ts1: s.ts1,
                    target_system: from.system_id as u8,
                    target_component: from.component_id,
                }));
            }
            _ => {}
        }
    }

    /// A message of the mission protocol (or `MISSION_SET_CURRENT`) for `system`, `component`.
    fn on_mission_message(
        &mut self,
        system: u8,
        component: u8,
        from: &MavHeader,
        msg: &MavMessage,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let requester = |command| acked(from, command);
        if self.for_us(system, Some(component)) {
            if let MavMessage::MISSION_SET_CURRENT(m) = msg {
                let to = AckTo {
                    reply: Reply::Quiet,
                    ..requester(MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT)
                };
                let cmd = AutopilotCommand::SetMissionCurrent(m.seq);
                out.request(cmd, Delivery::Answered(to));
            } else {
                self.missions.bounds = Some(self.mission_bounds(t));
                self.missions.on_message(from, msg, out);
            }
        } else {
            self.dropped += 1;
        }
    }

    /// A command: `COMMAND_LONG`, `COMMAND_INT`, or the legacy `SET_MODE` (acknowledged as
    /// `MAV_CMD_DO_SET_MODE`, as PX4 does).
    fn on_command_message(
        &mut self,
        from: &MavHeader,
        msg: &MavMessage,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let requester = |command| acked(from, command);
        match msg {
            MavMessage::COMMAND_LONG(c) => {
                if !self.for_us(c.target_system, Some(c.target_component)) {
                    self.dropped += 1;
                    return;
                }
                let p = [
                    c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                ];
                let cmd = CommandMessage {
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
                let cmd = CommandMessage {
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
                let cmd = CommandMessage {
                    command: MavCmd::MAV_CMD_DO_SET_MODE,
                    p,
                };
                self.command(cmd, to, t, out);
            }
            _ => {}
        }
    }

    /// A frame whose payload did not parse: a command with an id this dialect does not know
    /// is still acknowledged, as UNSUPPORTED.
    pub fn on_unparsed(&mut self, raw: &mavwire::RawMessage, out: &mut Outbox) {
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
            MAV_DATA_STREAM_RC_CHANNELS => &[RC_CHANNELS_DATA::ID],
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

    /// Sets message `id` to `hz` (`None`: off) on the link of the message being handled, at
    /// most at its [`GroundStation::max_rate_hz`].
    pub(super) fn set_rate(&mut self, id: u32, hz: Option<f64>) {
        let max = self.max_rate_hz(id);
        self.rates.set(self.link, id, hz, max);
    }

    /// The fastest message `id` may be streamed (Hz): a sensor message at the rate the
    /// sensors deliver (once measured), any other at the top of [`crate::RATE_RANGE_HZ`].
    pub fn max_rate_hz(&self, id: u32) -> f64 {
        match self.sample_rate.hz() {
            Some(hz) if crate::link_rates::SENSOR_STREAMS.contains(&id) => hz,
            _ => crate::RATE_RANGE_HZ.1,
        }
    }

    /// Whether a stream is faster than the link task's own poll: it then polls on every
    /// sensor sample.
    pub fn wants_every_sample(&self) -> bool {
        self.rates.fastest_hz() > crate::POLLED_STREAMS_HZ
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

impl GroundStation {
    /// The vehicle's answer to a follow-target fix: a refusal said when its reason changes
    /// (its numbers aside), not at every fix of the stream.
    pub(crate) fn follow_fix_answered(
        &mut self,
        result: Result<(), flight_core::commander::Denial>,
        out: &mut Outbox,
    ) {
        let reason = result.err();
        let shown = &self.announced.follow_refusal;
        let same = match (&reason, shown) {
            (Some(r), Some(s)) => r.same_reason(s),
            (r, s) => r.is_none() && s.is_none(),
        };
        if let Some(r) = reason.as_ref().filter(|_| !same) {
            out.say(MavSeverity::MAV_SEVERITY_WARNING, &r.to_string());
        }
        self.announced.follow_refusal = reason;
    }

    /// In Follow Target, says when the target's fixes stop (the vehicle holds behind its last
    /// place) and when they come back.
    pub(crate) fn follow_target_poll(&mut self, t: &Telemetry, out: &mut Outbox) {
        let stale = t.status().and_then(|s| s.follow).map(|f| f.stale);
        match (stale, self.announced.follow_lost) {
            (Some(true), false) => out.say(
                MavSeverity::MAV_SEVERITY_WARNING,
                "follow target lost: holding behind its last place",
            ),
            (Some(false), true) => out.say(MavSeverity::MAV_SEVERITY_INFO, "follow target found"),
            _ => {}
        }
        self.announced.follow_lost = stale == Some(true);
    }
}

/// A `FOLLOW_TARGET` as a fix for the vehicle: its place (latitude and longitude on the Earth,
/// altitude AMSL, all numbers), and its velocity when `est_capabilities` says it has one (bit 1;
/// MAVSDK sends zeros with only the position bit). `None`: not a place.
fn follow_target(m: &FOLLOW_TARGET_DATA) -> Option<AutopilotCommand> {
    let at = flight_core::math::geo::LatLonAlt {
        lat_deg: m.lat as f64 * 1e-7,
        lon_deg: m.lon as f64 * 1e-7,
        alt_m: m.alt as f64,
    };
    let on_earth = at.lat_deg.abs() <= 90.0 && at.lon_deg.abs() <= 180.0;
    if !(on_earth && at.alt_m.is_finite()) {
        return None;
    }
    let vel = nalgebra::Vector3::new(m.vel[0] as f64, m.vel[1] as f64, m.vel[2] as f64);
    let vel = (m.est_capabilities & 2 != 0 && vel.iter().all(|v| v.is_finite())).then_some(vel);
    Some(AutopilotCommand::FollowTarget {
        at,
        vel_ned_m_s: vel,
    })
}

/// A command of `from`'s, to be answered with a `COMMAND_ACK`.
fn acked(from: &MavHeader, command: MavCmd) -> AckTo {
    AckTo {
        command,
        system: from.system_id as u8,
        component: from.component_id,
        reply: Reply::Ack,
    }
}
