//! `INJECT_FAILURE` (PX4's failure injection, behind `SYS_FAILURE_EN`).

use super::Call;
use super::vehicle;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn failure(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, .. } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_INJECT_FAILURE => {
                match flight_core::safety::failure_injection::Injection::decode(p[0], p[1], p[2]) {
                    Ok(i) => vehicle(out, to, AutopilotCommand::InjectFailure(i)),
                    Err(why) => {
                        out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED));
                        out.say(MavSeverity::MAV_SEVERITY_WARNING, &why.to_string());
                    }
                }
            }
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
