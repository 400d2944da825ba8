//! Where and how to fly: take-off, land, return, hold, `DO_REPOSITION` (from `COMMAND_LONG` or
//! `COMMAND_INT`), `DO_CHANGE_SPEED`, `CONDITION_YAW`.

use super::vehicle;
use super::{Call, CommandMessage};
use crate::mission;
use crate::{AckTo, GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::FlightMode;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn navigation(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, .. } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_NAV_TAKEOFF => {
                // param7: altitude AMSL (PX4; below home + MIS_TAKEOFF_ALT it is raised to
                // that, as PX4 does); NaN: the take-off altitude parameter.
                if p[6].is_nan() {
                    vehicle(out, to, AutopilotCommand::Takeoff(None));
                } else if p[6].is_finite() {
                    vehicle(out, to, AutopilotCommand::TakeoffAmsl(p[6] as f64));
                } else {
                    self.deny(to, out, &format!("take-off refused: altitude {} m", p[6]));
                }
            }
            MavCmd::MAV_CMD_NAV_LAND => {
                vehicle(out, to, AutopilotCommand::SetMode(FlightMode::Land))
            }
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => match mission::speed_change(p[1]) {
                Ok(change) => vehicle(out, to, AutopilotCommand::ChangeSpeed(change)),
                Err(_) => self.deny(to, out, &format!("change speed: {} m/s refused", p[1])),
            },
            MavCmd::MAV_CMD_CONDITION_YAW => {
                if p[0].is_nan() || p[0].abs() > 360.0 {
                    return self.deny(
                        to,
                        out,
                        &format!("yaw command: angle {}° outside ±360°", p[0]),
                    );
                }
                if !(p[1].is_nan() || p[1] <= 360.0) {
                    return self.deny(
                        to,
                        out,
                        &format!("yaw command: rate {}°/s above 360°/s", p[1]),
                    );
                }
                let rate = (p[1].is_finite() && p[1] > 0.0).then_some(p[1] as f64);
                vehicle(
                    out,
                    to,
                    AutopilotCommand::ConditionYaw {
                        angle_deg: p[0] as f64,
                        rate_deg_s: rate,
                        direction: p[2].signum() as i8 * (p[2] != 0.0) as i8,
                        relative: p[3] != 0.0,
                    },
                );
            }
            MavCmd::MAV_CMD_DO_REPOSITION => {
                // COMMAND_LONG: latitude and longitude in degrees (NaN: keep), altitude AMSL.
                let global =
                    (!p[4].is_nan() || !p[5].is_nan()).then_some((p[4] as f64, p[5] as f64));
                self.reposition(c, global, MavFrame::MAV_FRAME_GLOBAL, to, out);
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                vehicle(out, to, AutopilotCommand::SetMode(FlightMode::Rtl));
            }
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM => {
                vehicle(out, to, AutopilotCommand::SetMode(FlightMode::Loiter));
            }
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }

    /// `DO_REPOSITION`: param1 speed (−1 default), param2 bit 0 "switch to Hold", param4
    /// yaw (NaN keeps; in radians, as PX4 reads it and MAVSDK's `goto_location` sends it,
    /// although the MAVLink spec says degrees), latitude and longitude (deg; absent: keep), z
    /// the altitude in `frame` (NaN: keep).
    pub(super) fn reposition(
        &mut self,
        c: CommandMessage,
        global: Option<(f64, f64)>,
        frame: MavFrame,
        to: AckTo,
        out: &mut Outbox,
    ) {
        let p = c.p;
        if !(p[3].is_nan() || p[3].abs() <= std::f32::consts::TAU) {
            return self.deny(
                to,
                out,
                &format!("reposition: yaw {} rad outside ±2π", p[3]),
            );
        }
        let relative = match frame {
            MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => false,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => true,
            f => return self.deny(to, out, &format!("reposition: frame {f:?} not supported")),
        };
        // NaN keeps the altitude; an infinite one is refused where it is checked.
        let z = p[6] as f64;
        let at = flight_core::mission::MissionPoint {
            lat_lon_deg: global,
            alt: (!z.is_nan()).then_some(if relative {
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
        vehicle(out, to, cmd);
    }
}
