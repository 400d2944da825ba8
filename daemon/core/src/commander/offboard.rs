//! Offboard: the set-points a companion computer or script streams (position, velocity,
//! acceleration, yaw or yaw rate, or attitude and thrust), with the landed state they imply:
//! take-off when they ask to go up; touchdown and disarm when they rest it on the ground
//! (below a metre, still for a second). A stream that stops is the commander's to handle
//! (`COM_OF_LOSS_T`, `COM_OBL_RC_ACT`).

use super::LandedState;
use super::flight::{Flight, Tick, Touchdown, spooled, wrap_pi};
use super::task::FlightTask;
use crate::control::Setpoint;

/// Following the stream.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Offboard {
    /// The heading held or turned when the set-points give none (rad).
    yaw: Option<f64>,
    touchdown: Touchdown,
}

impl FlightTask for Offboard {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        let (i, home) = (t.i, t.home);
        let Some(target) = t.offboard else {
            // Without a stream the commander has switched away before this update.
            return Setpoint::Position(spooled(home, t.yaw));
        };
        let hover = i.hover_thrust.clamp(0.05, 0.95);
        let up_asked = match &target.setpoint {
            Setpoint::Position(p) => {
                p.pos_ned_m.z < home.z - 0.3
                    || p.vel_ned_m_s.z < -0.1
                    || (p.pos_ned_m.z.is_nan()
                        && p.vel_ned_m_s.z.is_nan()
                        && p.accel_ned_m_s2.z < -0.1)
            }
            Setpoint::Attitude(a) => a.thrust > hover,
        };
        let height = home.z - i.pos_ned_m.z;
        match f.land.state() {
            LandedState::OnGround => {
                self.touchdown.reset();
                if !up_asked {
                    // Kept on the ground until the set-points ask to leave it.
                    return Setpoint::Position(spooled(home, i.yaw_rad));
                }
                f.land.climbing();
            }
            LandedState::Takeoff if height > 1.0 => f.land.airborne(),
            _ => {
                let still = !up_asked && height < 1.0 && i.vel_ned_m_s.norm() < 0.3;
                self.touchdown.check(f, still, i.t_s);
            }
        }
        match target.setpoint {
            Setpoint::Position(mut p) => {
                if !p.yaw_rad.is_finite() {
                    // No yaw: hold the heading, or turn it at the yaw rate given.
                    let yaw = self.yaw.get_or_insert(i.yaw_rad);
                    if let Some(rate) = target.yaw_rate_rad_s.filter(|r| r.is_finite()) {
                        *yaw = wrap_pi(*yaw + rate * t.dt);
                    }
                    p.yaw_rad = *yaw;
                } else {
                    self.yaw = Some(p.yaw_rad);
                }
                Setpoint::Position(p)
            }
            Setpoint::Attitude(mut a) => {
                if !a.thrust.is_finite() {
                    a.thrust = hover;
                }
                self.yaw = None;
                Setpoint::Attitude(a)
            }
        }
    }
}
