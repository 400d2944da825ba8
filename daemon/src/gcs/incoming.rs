//! What the ground station does with each message it receives: mission, parameter and
//! calibration messages go to their parts, streams are set, and commands are answered here or
//! passed to the vehicle.

use super::{
    AckTo, CommandMessage, DEFAULT_STREAMS, FORCE_MAGIC, GroundStation, HostAction, Outbox,
    Outgoing, RATE_RANGE_HZ, Stream, mission, modes, offboard, streams,
};
use crate::control_loop::Telemetry;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::{FlightMode, Sticks};
use flight_core::math::geo::LatLonAlt;
use mavlink::MavHeader;
use mavlink::MessageData;
use mavlink::dialects::common::*;

impl GroundStation {
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
            }
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
        c: CommandMessage,
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
        c: CommandMessage,
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
    fn command(&mut self, c: CommandMessage, to: AckTo, t: &Telemetry, out: &mut Outbox) {
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
                    0.0 => out.actions.push(HostAction::ReloadParams(to)),
                    1.0 => {
                        out.actions.push(HostAction::SaveParams);
                        out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                    }
                    2.0 => {
                        let base = self.base_params.clone();
                        self.params.reset(&base);
                        out.actions.push(HostAction::ParamsChanged);
                        out.actions.push(HostAction::SaveParams);
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
                    1.0 => Some(HostAction::Reboot),
                    2.0 => Some(HostAction::Shutdown),
                    x => {
                        return deny(self, out, &format!("reboot: param1 {x} not supported"));
                    }
                };
                if armed && action.is_some() {
                    return deny(self, out, "reboot: disarm first");
                }
                if action == Some(HostAction::Reboot) && !self.reboot_allowed {
                    return deny(
                        self,
                        out,
                        "reboot: one of several vehicles in one process; restart the process",
                    );
                }
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                if let Some(a) = action {
                    out.actions.push(a);
                    let what = if a == HostAction::Reboot {
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
                let home = streams::build(HOME_POSITION_DATA::ID, t, 0);
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
