//! Fixtures shared by this crate's tests and the daemon's (feature `testing`).

use crate::telemetry::{LinkState, Telemetry};
use crate::{AckTo, Delivery, GroundStation, HostAction, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{Autopilot, VehicleState};
use flight_core::commander::{CommanderStatus, FlightMode, LandedState, Sticks};
use flight_core::mission::MissionItem;
use flight_core::safety::geofence::GeoZone;
use mavlink::dialects::common::*;

/// The telemetry of a vehicle at rest on the ground, ready to arm, `armed` or not, in `mode`,
/// with a full battery.
pub fn telemetry(armed: bool, mode: FlightMode) -> Telemetry {
    let status = CommanderStatus {
        armed,
        mode,
        landed: LandedState::OnGround,
        ground_contact: Default::default(),
        home: None,
        failsafe: false,
        failsafe_action: None,
        motor_failed: None,
        spinning: false,
        failsafe_conditions: 0,
        safety_log: Default::default(),
        orbit: None,
        follow: None,
        prearm_ok: true,
        ready: true,
        in_mode_s: 0.0,
        manual_losses: 0,
        offboard_losses: 0,
        mission: Default::default(),
        manual_control: None,
    };
    Telemetry {
        vehicle: Some(VehicleState {
            status,
            estimate: None,
            held_sample: None,
            setpoint: None,
            gps: None,
            battery_v: 16.0,
            battery: Default::default(),
            mag_cal: None,
            imu_cal: None,
            source_restarts: 0,
            rotors: 4,
            max_thrust_n: 0.0,
            rc: None,
        }),
        link: LinkState {
            t_s: 12.0,
            ..LinkState::default()
        },
    }
}

/// A `COMMAND_LONG` of `command` with params `p`, to `target` (system, component).
pub fn command_long(command: MavCmd, p: [f32; 7], target: (u8, u8)) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        param5: p[4],
        param6: p[5],
        param7: p[6],
        command,
        target_system: target.0,
        target_component: target.1,
        confirmation: 0,
    })
}

/// A `COMMAND_INT` of `command` in `frame` to vehicle 1: params 1–4 from `p`, x and y as
/// given, z from `p[6]`.
pub fn command_int(command: MavCmd, p: [f32; 7], x: i32, y: i32, frame: MavFrame) -> MavMessage {
    MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        x,
        y,
        z: p[6],
        command,
        target_system: 1,
        target_component: 1,
        frame,
        current: 0,
        autocontinue: 0,
    })
}

/// Carries out what the protocol put in `out`, as the links' task and the control loop do:
/// its requests to `autopilot` in order (each answered one answered through `gcs`), new
/// parameter values; then empties what was to be sent.
pub fn carry_out(gcs: &mut GroundStation, autopilot: &mut Autopilot, out: &mut Outbox) {
    for r in std::mem::take(&mut out.requests) {
        let result = autopilot.command(r.command);
        if let Delivery::Answered(to) = r.delivery {
            gcs.answered(to, result, out);
        }
    }
    for a in out.actions.drain(..) {
        if a == HostAction::ParamsChanged {
            autopilot.set_params(gcs.parameters().values());
        }
    }
    out.messages.clear();
    out.streamed.clear();
    out.said.clear();
}

/// The commands in `out` that are answered, and whom each answer is for.
pub fn requested(out: &Outbox) -> Vec<(AutopilotCommand, AckTo)> {
    out.answered_requests()
        .map(|(c, to)| (c.clone(), to))
        .collect()
}

/// Takes the answered commands out of `out` (the other requests stay).
pub fn take_requested(out: &mut Outbox) -> Vec<(AutopilotCommand, AckTo)> {
    let taken = requested(out);
    out.requests
        .retain(|r| !matches!(r.delivery, Delivery::Answered(_)));
    taken
}

/// The latest stick positions in `out`.
pub fn sticks(out: &Outbox) -> Option<Sticks> {
    out.requests.iter().find_map(|r| match r.command {
        AutopilotCommand::Sticks(s) => Some(s),
        _ => None,
    })
}

/// The new mission in `out`.
pub fn mission(out: &Outbox) -> Option<Vec<MissionItem>> {
    out.requests.iter().find_map(|r| match &r.command {
        AutopilotCommand::SetMission(m) => Some(m.clone()),
        _ => None,
    })
}

/// The new geofence in `out`.
pub fn fence(out: &Outbox) -> Option<Vec<GeoZone>> {
    out.requests.iter().find_map(|r| match &r.command {
        AutopilotCommand::SetFence(z) => Some(z.clone()),
        _ => None,
    })
}
