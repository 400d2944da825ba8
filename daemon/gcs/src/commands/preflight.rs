//! On the ground: `PREFLIGHT_STORAGE` (parameters), `PREFLIGHT_REBOOT_SHUTDOWN`,
//! `PREFLIGHT_CALIBRATION`.

use super::Call;
use super::vehicle;
use crate::HostAction;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn preflight(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, t } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_PREFLIGHT_STORAGE => {
                let armed = t.status.is_some_and(|s| s.armed);
                // MAV_PFS_CMD: 0 read, 1 write, 2 clear (reset to defaults), 6 nothing.
                match p[0] {
                    0.0 | 2.0 if armed => self.deny(to, out, "parameters: disarm first"),
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
                    x => self.deny(to, out, &format!("storage: param1 {x} not supported")),
                }
            }
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN => {
                let armed = t.status.is_some_and(|s| s.armed);
                let action = match p[0] {
                    0.0 => None,
                    1.0 => Some(HostAction::Reboot),
                    2.0 => Some(HostAction::Shutdown),
                    x => {
                        return self.deny(to, out, &format!("reboot: param1 {x} not supported"));
                    }
                };
                if armed && action.is_some() {
                    return self.deny(to, out, "reboot: disarm first");
                }
                if action == Some(HostAction::Reboot) && !self.reboot_allowed {
                    return self.deny(
                        to,
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
                    vehicle(out, to, AutopilotCommand::CancelCalibration);
                } else if p[1] == 1.0 && p.iter().enumerate().all(|(i, &x)| i == 1 || off(x)) {
                    vehicle(out, to, AutopilotCommand::CalibrateMag);
                } else {
                    out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED));
                    out.say(
                        MavSeverity::MAV_SEVERITY_WARNING,
                        "calibration: only the magnetometer (param2 = 1) is calibrated onboard; \
                         the gyro and accelerometer biases are estimated in flight",
                    );
                }
            }
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
