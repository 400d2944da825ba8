//! Arming and disarming (`COMPONENT_ARM_DISARM`, param2 21196 forces).

use super::Call;
use super::vehicle;
use crate::FORCE_MAGIC;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn arming(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, .. } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                let force = p[1] == FORCE_MAGIC;
                match p[0] {
                    1.0 => vehicle(out, to, AutopilotCommand::Arm { force }),
                    0.0 => vehicle(out, to, AutopilotCommand::Disarm { force }),
                    x => self.deny(
                        to,
                        out,
                        &format!("arm/disarm: param1 must be 0 or 1, got {x}"),
                    ),
                }
            }
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
