//! Stabilized and Manual (the same on a multicopter, as in PX4): the roll and pitch sticks
//! tilt the vehicle up to `MPC_MAN_TILT_MAX` in the heading's frame, the yaw stick turns it,
//! the throttle stick sets the collective thrust (its centre is hover thrust). The vehicle
//! levels itself when the sticks centre but holds neither altitude nor position. Touchdown
//! and disarm after the throttle has stayed low with the vehicle still for a second.

use super::LandedState;
use super::flight::{Flight, Tick, Touchdown, deadzone, spooled, wrap_pi};
use super::task::FlightTask;
use crate::control::{AttitudeTarget, Setpoint};
use nalgebra::{UnitQuaternion, Vector2, Vector3};

/// The throttle stick at or below this is "low" (arming and touchdown here).
pub(super) const LOW_THROTTLE: f64 = 0.1;

/// The stick-to-attitude mode.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Stabilized {
    /// The heading held while the yaw stick is centred (rad).
    yaw: Option<f64>,
    touchdown: Touchdown,
}

impl FlightTask for Stabilized {
    /// The sticks as an attitude and a thrust, as PX4's `ManualControl` → attitude set-point
    /// for multicopters.
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        let Some(s) = t.sticks else {
            // Without sticks the commander has switched to Hold before this update.
            return Setpoint::Position(spooled(t.home, t.yaw));
        };
        let (p, i) = (f.params, t.i);
        // Throttle curve (PX4's MPC_THR_CURVE 0): zero → MPC_MANTHR_MIN, centre → hover
        // thrust, full → full thrust, linear in between.
        let hover = i.hover_thrust.clamp(0.05, 0.95);
        let min = p.manual_thrust_min.min(hover);
        let thrust = if s.throttle <= 0.5 {
            min + (hover - min) * s.throttle / 0.5
        } else {
            hover + (1.0 - hover) * (s.throttle - 0.5) / 0.5
        };
        let height = t.home.z - i.pos_ned_m.z;
        match f.land.state() {
            LandedState::OnGround => {
                // Lifting off: thrust above hover, or the vehicle has risen.
                if thrust > hover || height > 0.5 {
                    f.land.climbing();
                }
                self.touchdown.reset();
            }
            LandedState::Takeoff if height > 1.0 => f.land.airborne(),
            _ => {
                // Touchdown: throttle held low and the vehicle still for a second.
                let still = s.throttle <= LOW_THROTTLE && i.vel_ned_m_s.norm() < 0.3;
                self.touchdown.check(f, still, i.t_s);
            }
        }
        // The yaw stick commands a turn rate, the heading following the vehicle meanwhile (as
        // PX4's StickYaw: a set-point integrated ahead of a vehicle whose turn rate is limited
        // by MC_YAWRATE_MAX would run away from it); centred, the heading of that moment is
        // held. On the ground the heading follows the vehicle.
        let yaw_rate = deadzone(s.yaw, p.stick_deadzone) * p.manual_yaw_rate_deg_s.to_radians();
        let yaw = match self.yaw {
            Some(y) if yaw_rate == 0.0 && f.land.state() != LandedState::OnGround => y,
            _ => i.yaw_rad,
        };
        let yaw = wrap_pi(yaw);
        self.yaw = (yaw_rate == 0.0).then_some(yaw);
        // Roll and pitch sticks: a tilt vector in the heading's frame (right stick: roll right;
        // forward stick: nose down), its length limited to the largest tilt.
        let max_tilt = p.manual_tilt_deg.to_radians();
        let mut tilt = Vector2::new(s.right, -s.forward) * max_tilt;
        if tilt.norm() > max_tilt {
            tilt *= max_tilt / tilt.norm();
        }
        let q_d = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
            * UnitQuaternion::from_scaled_axis(Vector3::new(tilt.x, tilt.y, 0.0));
        // Ω_d: the heading's turn, seen in the desired body frame.
        let rate = q_d.inverse() * Vector3::new(0.0, 0.0, yaw_rate);
        Setpoint::Attitude(AttitudeTarget {
            q_d: Some(q_d),
            rate_frd_rad_s: if f.land.state() == LandedState::OnGround {
                Vector3::zeros()
            } else {
                rate
            },
            thrust,
        })
    }
}
