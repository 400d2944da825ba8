//! Position (Posctl) and altitude (Altctl) modes, from the sticks of `MANUAL_CONTROL` (PX4's
//! `FlightTaskManualPosition` and `…Altitude`): velocity (Posctl) or tilt (Altctl) from the
//! roll and pitch sticks in the heading's frame, climb rate from the throttle stick around
//! its centre, turn rate from the yaw stick; centred sticks hold. Take-off by raising the
//! throttle; touchdown and disarm after holding it low on the ground.

use super::LandedState;
use super::flight::{Flight, Tick, Touchdown, deadzone, spooled, wrap_pi};
use super::task::FlightTask;
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// A stick position mode.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ManualPosition {
    /// Posctl (the sticks fly velocity) rather than Altctl (they tilt).
    position: bool,
    /// The heading the yaw stick steers (rad).
    yaw: Option<f64>,
    /// The held point (NaN per axis while its stick moves) and heading.
    hold: Option<(Vector3<f64>, f64)>,
    touchdown: Touchdown,
}

impl ManualPosition {
    /// Posctl if `position`, else Altctl.
    pub(super) fn new(position: bool) -> Self {
        Self {
            position,
            yaw: None,
            hold: None,
            touchdown: Touchdown::default(),
        }
    }

    /// The held point and heading.
    pub(super) fn held(&self) -> Option<(Vector3<f64>, f64)> {
        self.hold
    }

    /// Starts holding `at` (where braking stops the vehicle as the mode takes over).
    pub(super) fn hold_at(&mut self, at: (Vector3<f64>, f64)) {
        self.hold = Some(at);
    }

    /// The set-point; `None`: on the ground, stay there.
    fn fly(&mut self, f: &mut Flight, t: &Tick) -> Option<PositionSetpoint> {
        let (p, i, dt) = (f.params, t.i, t.dt);
        let s = t.sticks?;
        let dz = p.stick_deadzone;
        // Throttle around its centre: climb (up to MAN_Z_VEL_UP) or sink (MAN_Z_VEL_DN).
        let climb = deadzone(2.0 * s.throttle - 1.0, dz);
        let vz = if climb > 0.0 {
            -climb * p.manual_climb_m_s
        } else {
            -climb * p.manual_sink_m_s
        };
        if f.land.state() == LandedState::OnGround {
            if climb <= 0.0 {
                self.touchdown.reset();
                return None;
            }
            f.land.climbing();
        }
        let yaw = *self.yaw.get_or_insert(i.yaw_rad);
        let yaw = wrap_pi(yaw + deadzone(s.yaw, dz) * p.manual_yaw_rate_deg_s.to_radians() * dt);
        self.yaw = Some(yaw);
        let height = t.home.z - i.pos_ned_m.z;
        if f.land.state() == LandedState::Takeoff && height > 1.0 {
            f.land.airborne();
        }
        // Touchdown: sinking commanded, and no longer moving down for a second.
        let stopped = climb < 0.0 && i.vel_ned_m_s.z.abs() < 0.15 && height < 1.0;
        if self.touchdown.check(f, stopped, i.t_s) {
            return None;
        }
        // The held point, per axis: forgotten (NaN) while its stick moves; when the stick
        // centres the vehicle brakes (velocity zero) and the point is locked where it has
        // slowed down, as PX4 does, rather than where the stick was let go (which it would
        // overshoot and fly back to).
        let hold = &mut self.hold.get_or_insert((i.pos_ned_m, yaw)).0;
        let (fwd, right) = (deadzone(s.forward, dz), deadzone(s.right, dz));
        let moving_h = self.position && (fwd != 0.0 || right != 0.0);
        if vz != 0.0 {
            hold.z = f64::NAN;
        } else if hold.z.is_nan() && i.vel_ned_m_s.z.abs() < 0.2 {
            hold.z = i.pos_ned_m.z;
        }
        if moving_h {
            hold.x = f64::NAN;
            hold.y = f64::NAN;
        } else if hold.x.is_nan() && i.vel_ned_m_s.xy().norm() < 0.3 {
            hold.x = i.pos_ned_m.x;
            hold.y = i.pos_ned_m.y;
        }
        let hold_pos = *hold;
        let mut pos = Vector3::repeat(f64::NAN);
        let mut vel = Vector3::repeat(f64::NAN);
        let mut accel = Vector3::zeros();
        if vz != 0.0 {
            vel.z = vz;
        } else if hold_pos.z.is_nan() {
            vel.z = 0.0; // braking
        } else {
            pos.z = hold_pos.z;
        }
        // The stick in the frame of the vehicle's heading, to NED (as PX4).
        let (c, sn) = (i.yaw_rad.cos(), i.yaw_rad.sin());
        let north = fwd * c - right * sn;
        let east = fwd * sn + right * c;
        if self.position {
            if moving_h {
                vel.x = north * p.manual_speed_m_s;
                vel.y = east * p.manual_speed_m_s;
            } else if hold_pos.x.is_nan() {
                vel.x = 0.0; // braking
                vel.y = 0.0;
            } else {
                pos.x = hold_pos.x;
                pos.y = hold_pos.y;
            }
        } else {
            // Altitude mode: the stick tilts the vehicle (its horizontal acceleration).
            let a = crate::GRAVITY_M_S2 * p.manual_tilt_deg.to_radians().tan();
            accel.x = north * a;
            accel.y = east * a;
        }
        Some(PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: vel,
            accel_ned_m_s2: accel,
            yaw_rad: yaw,
        })
    }
}

impl FlightTask for ManualPosition {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        // Without sticks the commander has switched to Hold before this update.
        let sp = self.fly(f, t).unwrap_or_else(|| spooled(t.home, t.yaw));
        Setpoint::Position(sp)
    }
}
