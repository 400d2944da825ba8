//! Mode changes: `DO_SET_MODE` (PX4's custom modes) and `DO_SET_STANDARD_MODE`.

use super::Call;
use super::vehicle;
use crate::modes;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn modes(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, .. } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_DO_SET_MODE => {
                let base = p[0] as u32;
                if base & MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() as u32 == 0 {
                    return self.deny(to, out, "set mode: only PX4 custom modes are supported");
                }
                match modes::from_px4(p[1] as u8, p[2] as u8) {
                    Some(m) => vehicle(out, to, AutopilotCommand::SetMode(m)),
                    None => self.deny(
                        to,
                        out,
                        &format!("set mode: no mode {}/{}", p[1] as u8, p[2] as u8),
                    ),
                }
            }
            MavCmd::MAV_CMD_DO_SET_STANDARD_MODE => match modes::from_standard(p[0] as u32) {
                Some(m) => vehicle(out, to, AutopilotCommand::SetMode(m)),
                None => self.deny(to, out, &format!("no standard mode {}", p[0])),
            },
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
