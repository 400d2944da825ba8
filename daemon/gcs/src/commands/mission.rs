//! The mission: `MISSION_START`, `DO_SET_MISSION_CURRENT`, `DO_PAUSE_CONTINUE`.

use super::Call;
use super::vehicle;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::FlightMode;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn mission(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, .. } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_MISSION_START => {
                // param1: the first item (0 and up); the last (param2) is not honoured.
                let first = (p[0].is_finite() && p[0] >= 0.0).then_some(p[0] as u16);
                vehicle(out, to, AutopilotCommand::StartMission(first));
            }
            MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT => {
                if !(p[0].is_finite() && p[0] >= 0.0) {
                    // −1: no change.
                    return out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                }
                vehicle(out, to, AutopilotCommand::SetMissionCurrent(p[0] as u16));
            }
            MavCmd::MAV_CMD_DO_PAUSE_CONTINUE => match p[0] {
                0.0 => vehicle(out, to, AutopilotCommand::SetMode(FlightMode::Loiter)),
                1.0 => vehicle(out, to, AutopilotCommand::SetMode(FlightMode::Mission)),
                x => self.deny(
                    to,
                    out,
                    &format!("pause/continue: param1 {x} is not 0 or 1"),
                ),
            },
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
