//! Fixtures shared by this crate's tests and the daemon's (feature `testing`).

use crate::telemetry::Telemetry;
use crate::{GroundStation, HostAction, Outbox};
use flight_core::autopilot::Autopilot;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::{CommanderStatus, FlightMode, LandedState};
use mavlink::dialects::common::*;

/// The telemetry of a vehicle at rest on the ground, ready to arm, `armed` or not, in `mode`,
/// with a full battery.
pub fn telemetry(armed: bool, mode: FlightMode) -> Telemetry {
    Telemetry {
        t_s: 12.0,
        status: Some(CommanderStatus {
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
        }),
        battery_v: 16.0,
        ..Telemetry::default()
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
/// commands to `autopilot` (each answered through `gcs`), sticks, offboard set-points, a new
/// mission or fence, new parameter values; then empties what was to be sent.
pub fn carry_out(gcs: &mut GroundStation, autopilot: &mut Autopilot, out: &mut Outbox) {
    for (c, to) in std::mem::take(&mut out.vehicle) {
        let r = autopilot.command(c);
        gcs.answered(to, r, out);
    }
    if let Some(s) = out.sticks.take() {
        let _ = autopilot.command(AutopilotCommand::Sticks(s));
    }
    if let Some(t) = out.offboard.take() {
        let _ = autopilot.command(AutopilotCommand::Offboard(t));
    }
    if let Some(m) = out.mission.take() {
        let _ = autopilot.command(AutopilotCommand::SetMission(m));
    }
    if let Some(z) = out.fence.take() {
        let _ = autopilot.command(AutopilotCommand::SetFence(z));
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
