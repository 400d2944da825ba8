//! On the ground: `PREFLIGHT_STORAGE` (parameters), `PREFLIGHT_REBOOT_SHUTDOWN`,
//! `PREFLIGHT_CALIBRATION`.

use super::Call;
use super::vehicle;
use crate::HostAction;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::sensors::imu_calibrator::ImuCalKind;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn preflight(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, t } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_PREFLIGHT_STORAGE => {
                let armed = t.status().is_some_and(|s| s.armed);
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
                let armed = t.status().is_some_and(|s| s.armed);
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
            MavCmd::MAV_CMD_PREFLIGHT_CALIBRATION => match calibration(&p) {
                Ok(c) => vehicle(out, to, c),
                Err(why) => {
                    out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED));
                    out.say(MavSeverity::MAV_SEVERITY_WARNING, &why.to_string());
                }
            },
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}

/// A `MAV_CMD_PREFLIGHT_CALIBRATION` this autopilot does not carry out.
#[derive(Debug, thiserror::Error)]
enum NotOnboard {
    #[error(
        "calibration: param{param} = {value} is not calibrated onboard (gyro: param1 1, \
         magnetometer: param2 1, radio: param4 1, accelerometer: param5 1, level horizon: \
         param5 2)"
    )]
    Calibration { param: usize, value: f32 },
    #[error("calibration: one at a time (more than one param set)")]
    MoreThanOne,
}

/// The calibration `MAV_CMD_PREFLIGHT_CALIBRATION`'s params ask for, as PX4 reads them: param1
/// 1 the gyro, param2 1 the magnetometer, param4 1 the radio (the ground station's, RC input
/// off meanwhile), param5 1 the accelerometer, param5 2 the level horizon; every param 0
/// cancels or ends. One at a time. NaN is a reserved param left unset (MAVSDK
/// leaves 6 and 7 so): 0.
fn calibration(p: &[f32; 7]) -> Result<AutopilotCommand, NotOnboard> {
    let set: Vec<(usize, f32)> = p
        .iter()
        .enumerate()
        .filter(|(_, x)| **x != 0.0 && !x.is_nan())
        .map(|(i, &x)| (i + 1, x))
        .collect();
    match set.as_slice() {
        [] => Ok(AutopilotCommand::CancelCalibration),
        [(1, 1.0)] => Ok(AutopilotCommand::CalibrateImu(ImuCalKind::Gyro)),
        [(2, 1.0)] => Ok(AutopilotCommand::CalibrateMag),
        [(4, 1.0)] => Ok(AutopilotCommand::CalibrateRadio),
        [(5, 1.0)] => Ok(AutopilotCommand::CalibrateImu(ImuCalKind::Accel)),
        [(5, 2.0)] => Ok(AutopilotCommand::CalibrateImu(ImuCalKind::Level)),
        [(param, value)] => Err(NotOnboard::Calibration {
            param: *param,
            value: *value,
        }),
        _ => Err(NotOnboard::MoreThanOne),
    }
}
