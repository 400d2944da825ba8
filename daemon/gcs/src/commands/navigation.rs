//! Where and how to fly: take-off, land, return, hold, `DO_REPOSITION` and `DO_ORBIT` (from
//! `COMMAND_LONG` or `COMMAND_INT`), `DO_CHANGE_SPEED`, `CONDITION_YAW`.

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
                // COMMAND_LONG: altitude AMSL.
                self.reposition(c, long_lat_lon(&p), MavFrame::MAV_FRAME_GLOBAL, to, out);
            }
            MavCmd::MAV_CMD_DO_ORBIT => {
                self.orbit(c, long_lat_lon(&p), to, out);
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

    /// `DO_ORBIT`: param1 radius (m, negative counter-clockwise), param2 tangential speed,
    /// param3 `ORBIT_YAW_BEHAVIOUR` (5: unchanged), param4 the angle to fly (rad; 0 forever),
    /// the centre's latitude and longitude (deg) and z its altitude AMSL whatever the frame —
    /// as PX4 reads it, and as MAVSDK's `do_orbit` sends it (in a relative frame). NaN keeps
    /// the orbit flown's value (or starts at the current position and the defaults).
    pub(super) fn orbit(
        &mut self,
        c: CommandMessage,
        global: Option<(f64, f64)>,
        to: AckTo,
        out: &mut Outbox,
    ) {
        let p = c.p;
        let given = |v: f32| (!v.is_nan()).then_some(v as f64);
        let yaw = match p[2] {
            y if y.is_nan() || y == 5.0 => None,
            y => match flight_core::commander::OrbitYaw::from_mavlink(y as u8) {
                Some(b) if y.fract() == 0.0 && y >= 0.0 => Some(b),
                _ => return self.deny(to, out, &format!("orbit: yaw behaviour {y} unknown")),
            },
        };
        if !(p[3].is_nan() || (p[3].is_finite() && p[3] >= 0.0)) {
            return self.deny(to, out, &format!("orbit: angle to fly {} rad", p[3]));
        }
        let (radius, speed) = (given(p[0]), given(p[1]));
        let accel = self.params.values().commander.orbit_accel_m_s2;
        if let (Some(r), Some(v)) = (radius, speed) {
            let bound = flight_core::commander::speed_bound_m_s(accel, r.abs());
            if v > bound && v.is_finite() && r.is_finite() {
                out.say(
                    MavSeverity::MAV_SEVERITY_INFO,
                    &format!("orbit: {v:.1} m/s lowered to {bound:.1} by the radius"),
                );
            }
        }
        let cmd = AutopilotCommand::Orbit {
            center: flight_core::mission::MissionPoint {
                lat_lon_deg: global,
                alt: given(p[6]).map(flight_core::mission::MissionAltitude::Amsl),
            },
            radius_m: radius,
            speed_m_s: speed,
            yaw,
            turns: given(p[3]).map(|rad| rad / std::f64::consts::TAU),
        };
        vehicle(out, to, cmd);
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

/// A `COMMAND_LONG`'s latitude and longitude (param5, param6, degrees); both NaN: keep the
/// current ones.
fn long_lat_lon(p: &[f32; 7]) -> Option<(f64, f64)> {
    (!p[4].is_nan() || !p[5].is_nan()).then_some((p[4] as f64, p[5] as f64))
}
