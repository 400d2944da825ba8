//! Position and altitude control: where to be → desired attitude and collective thrust.
//!
//! Position: P on position → velocity set-point (speed-limited, slew-limited for smooth
//! set-point changes) → PID on velocity → acceleration set-point (limited) → thrust vector
//! `T = m (a_sp − g)` → desired attitude (body −z along T, heading from the yaw set-point, tilt
//! limited) and collective thrust `T · (−z_b)` on the current body axis, which is Lewis's tilt
//! compensation (4.25)–(4.26) in vector form.
//!
//! Altitude alone (Lewis (4.23)–(4.26)): `F = (m g + F_PID) / K_tilt` with
//! `K_tilt = [0 0 1]·(q ⊗ (0, 0, −1) ⊗ q*)` as a cosine of the tilt, bounded below by the tilt
//! limit so the compensation cannot blow up; integrator clamped and frozen while saturated.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

const G: f64 = crate::GRAVITY_M_S2;

/// Position-loop parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionParams {
    /// Vehicle mass (kg).
    pub mass_kg: f64,
    /// Position gain (1/s), horizontal and vertical.
    pub k_pos: Vector3<f64>,
    /// Velocity proportional gain (1/s).
    pub k_vel: Vector3<f64>,
    /// Velocity integral gain (1/s²).
    pub k_vel_i: Vector3<f64>,
    /// Largest horizontal speed (m/s).
    pub max_speed_h: f64,
    /// Largest climb rate (m/s).
    pub max_speed_up: f64,
    /// Largest descent rate (m/s).
    pub max_speed_down: f64,
    /// Largest horizontal acceleration (m/s²).
    pub max_accel_h: f64,
    /// Largest vertical acceleration (m/s²).
    pub max_accel_v: f64,
    /// Largest tilt (rad).
    pub max_tilt: f64,
    /// Largest collective thrust (N).
    pub max_thrust_n: f64,
    /// Bound on the integral term (m/s²).
    pub i_limit: f64,
    /// Fraction of the outside force's estimate fed forward (0: none, 1: all of it).
    pub k_disturbance_ff: f64,
    /// Time constant of the outside force's estimate (s).
    pub disturbance_tau_s: f64,
}

/// What to fly to. As PX4's trajectory set-points, a NaN component leaves that axis uncontrolled
/// at that level: a NaN position flies the velocity alone; NaN position and velocity fly the
/// acceleration feed-forward alone (horizontally: level, when it is zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionSetpoint {
    /// Position NED (m); NaN per axis: velocity control on that axis.
    pub pos_ned_m: Vector3<f64>,
    /// Velocity feed-forward NED (m/s); NaN per axis (with a NaN position): no velocity control.
    pub vel_ned_m_s: Vector3<f64>,
    /// Acceleration feed-forward NED (m/s²), from a trajectory.
    pub accel_ned_m_s2: Vector3<f64>,
    /// Heading (rad, from north, clockwise).
    pub yaw_rad: f64,
}

/// The position loop's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeSetpoint {
    /// Desired attitude.
    pub q_d: UnitQuaternion<f64>,
    /// Collective thrust (N, up).
    pub thrust_n: f64,
    /// The acceleration set-point it came from, NED (m/s²).
    pub accel_ned_m_s2: Vector3<f64>,
    /// The velocity set-point, NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
}

/// Position → velocity → acceleration → attitude and thrust.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionController {
    /// Parameters.
    pub params: PositionParams,
    integral: Vector3<f64>,
    vel_sp: Option<Vector3<f64>>,
    /// The outside force per mass the thrust answers (NED, m/s²).
    disturbance: Vector3<f64>,
}

/// The attitude whose body −z points along `thrust_dir` (unit, NED) with heading `yaw`.
pub fn attitude_from_thrust(thrust_dir: &Vector3<f64>, yaw: f64) -> UnitQuaternion<f64> {
    let z_b = -thrust_dir;
    let x_c = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    let mut y_b = z_b.cross(&x_c);
    if y_b.norm() < 1e-6 {
        // Thrust horizontal along the heading: any perpendicular will do.
        y_b = Vector3::new(-yaw.sin(), yaw.cos(), 0.0);
    }
    let y_b = y_b.normalize();
    let x_b = y_b.cross(&z_b);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(
        &[x_b, y_b, z_b],
    )))
}

impl PositionController {
    /// A controller at rest.
    pub fn new(params: PositionParams) -> Self {
        Self {
            params,
            integral: Vector3::zeros(),
            vel_sp: None,
            disturbance: Vector3::zeros(),
        }
    }

    /// The outside force per mass (NED, m/s²; `control::disturbance`) the next updates answer
    /// with thrust, `k_disturbance_ff` of it: the acceleration asked for is then the vehicle's.
    pub fn set_disturbance(&mut self, accel_ned_m_s2: Vector3<f64>) {
        self.disturbance = accel_ned_m_s2 * self.params.k_disturbance_ff;
    }

    /// Forgets the integrator and the velocity set-point history (mode change, disarm).
    pub fn reset(&mut self) {
        self.integral = Vector3::zeros();
        self.vel_sp = None;
    }

    /// One step with the estimated position, velocity and attitude.
    pub fn update(
        &mut self,
        sp: &PositionSetpoint,
        pos: &Vector3<f64>,
        vel: &Vector3<f64>,
        q: &UnitQuaternion<f64>,
        dt: f64,
    ) -> AttitudeSetpoint {
        let p = &self.params;
        let zero_nan = |x: f64| if x.is_nan() { 0.0 } else { x };
        // Axes with neither position nor velocity set: acceleration feed-forward alone.
        let free = Vector3::from_fn(|i, _| sp.pos_ned_m[i].is_nan() && sp.vel_ned_m_s[i].is_nan());
        // Position P → velocity set-point, limited.
        let mut v_sp = (sp.pos_ned_m - pos).map(zero_nan).component_mul(&p.k_pos)
            + sp.vel_ned_m_s.map(zero_nan);
        let h = v_sp.xy().norm();
        if h > p.max_speed_h {
            v_sp.x *= p.max_speed_h / h;
            v_sp.y *= p.max_speed_h / h;
        }
        v_sp.z = v_sp.z.clamp(-p.max_speed_up, p.max_speed_down);
        // Smooth set-point changes: the velocity set-point moves at most at the acceleration limits.
        // After a reset the slew starts from the vehicle's own velocity, but never from a descent
        // faster than the largest: a vehicle found falling (its attitude found again after a gap
        // in the samples) is braked by the whole loop, not eased out of the fall at 4 m/s².
        {
            let prev = self
                .vel_sp
                .unwrap_or_else(|| Vector3::new(vel.x, vel.y, vel.z.min(p.max_speed_down)));
            let mut dv = v_sp - prev;
            let dh = dv.xy().norm();
            if dh > p.max_accel_h * dt {
                dv.x *= p.max_accel_h * dt / dh;
                dv.y *= p.max_accel_h * dt / dh;
            }
            dv.z = dv.z.clamp(-p.max_accel_v * dt, p.max_accel_v * dt);
            v_sp = prev + dv;
        }
        for i in 0..3 {
            if free[i] {
                v_sp[i] = vel[i];
                self.integral[i] = 0.0;
            }
        }
        self.vel_sp = Some(v_sp);
        // Velocity PID → acceleration set-point. The acceleration limits bound the manoeuvre (the
        // proportional part and the trajectory's feed-forward), not the integral: it holds what
        // the air does to the vehicle (drag in wind), which only the tilt limit may bound.
        let e = v_sp - vel;
        let mut a_sp = e.component_mul(&p.k_vel) + sp.accel_ned_m_s2.map(zero_nan);
        let h = a_sp.xy().norm();
        let h_limited = h > p.max_accel_h;
        if h_limited {
            a_sp.x *= p.max_accel_h / h;
            a_sp.y *= p.max_accel_h / h;
        }
        // Downward the manoeuvre limit holds; upward only the thrust bounds the answer, as PX4
        // bounds MPC_ACC_UP_MAX in the set-point's trajectory (above) and the velocity loop's
        // output by MPC_THR_MAX alone: a vehicle found falling (its attitude found again after
        // a gap in the samples) brakes with all it has, not at 4 m/s².
        let mut z_limited = a_sp.z > p.max_accel_v;
        a_sp.z = a_sp.z.min(p.max_accel_v);
        a_sp += self.integral;
        // Thrust vector, tilt-limited: keep the vertical component, shorten the horizontal one.
        // The outside force is answered first (the vehicle's acceleration is thrust + it + g).
        let mut t = (a_sp - self.disturbance - Vector3::new(0.0, 0.0, G)) * p.mass_kg;
        t.z = t.z.min(-0.1 * p.mass_kg * G); // always some thrust up
        z_limited |= -t.z > p.max_thrust_n;
        let horizontal = t.xy().norm();
        let max_h = -t.z * p.max_tilt.tan();
        let tilt_limited = horizontal > max_h;
        if tilt_limited {
            t.x *= max_h / horizontal;
            t.y *= max_h / horizontal;
        }
        // Anti-windup: integrate unless the thrust is saturated on that axis (the tilt limit;
        // the downward acceleration limit or the largest thrust). A limited manoeuvre does not stop it: the integral
        // must still learn a push stronger than the manoeuvre limit.
        for i in 0..3 {
            let frozen = free[i] || if i < 2 { tilt_limited } else { z_limited };
            if !frozen {
                self.integral[i] =
                    (self.integral[i] + p.k_vel_i[i] * e[i] * dt).clamp(-p.i_limit, p.i_limit);
            }
        }
        let q_d = attitude_from_thrust(&t.normalize(), sp.yaw_rad);
        // Collective along the current body −z axis: tilt compensation (Lewis (4.25)–(4.26)).
        let body_up = q * Vector3::new(0.0, 0.0, -1.0);
        let thrust_n = t.dot(&body_up).clamp(0.0, p.max_thrust_n);
        AttitudeSetpoint {
            q_d,
            thrust_n,
            accel_ned_m_s2: a_sp,
            vel_ned_m_s: v_sp,
        }
    }
}

/// Lewis's altitude law (4.23)–(4.26), for modes that hold altitude but not position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AltitudeController {
    /// Mass (kg).
    pub mass_kg: f64,
    /// K_Pz (N/m).
    pub k_p: f64,
    /// K_Iz (N/(m·s)).
    pub k_i: f64,
    /// K_Dz (N·s/m).
    pub k_d: f64,
    /// Largest tilt for the compensation (rad).
    pub max_tilt: f64,
    /// Largest collective thrust (N).
    pub max_thrust_n: f64,
    /// Bound on the integral term (N).
    pub i_limit: f64,
    integral: f64,
}

impl AltitudeController {
    /// A controller with zero integral.
    pub fn new(
        mass_kg: f64,
        k_p: f64,
        k_i: f64,
        k_d: f64,
        max_tilt: f64,
        max_thrust_n: f64,
        i_limit: f64,
    ) -> Self {
        Self {
            mass_kg,
            k_p,
            k_i,
            k_d,
            max_tilt,
            max_thrust_n,
            i_limit,
            integral: 0.0,
        }
    }

    /// Collective thrust (N) for altitude `alt` (m, up) with climb rate `climb` toward `alt_sp`.
    pub fn update(
        &mut self,
        alt_sp: f64,
        alt: f64,
        climb: f64,
        q: &UnitQuaternion<f64>,
        dt: f64,
    ) -> f64 {
        let e = alt_sp - alt; // (4.23)
        let f_pid = self.k_p * e + self.integral - self.k_d * climb; // (4.24), derivative on the measurement
        // (4.26): K_tilt = z-component of the body's up axis, i.e. cos(tilt), bounded by the limit.
        let k_tilt = (q * Vector3::new(0.0, 0.0, -1.0))
            .z
            .abs()
            .max(self.max_tilt.cos());
        let raw = (self.mass_kg * G + f_pid) / k_tilt; // (4.25)
        let out = raw.clamp(0.0, self.max_thrust_n);
        if out == raw || (out > raw) == (e > 0.0) {
            self.integral = (self.integral + self.k_i * e * dt).clamp(-self.i_limit, self.i_limit);
        }
        out
    }
}

crate::params::param_group! {
    /// Position, velocity and altitude loops.
    PositionGroup, "position", POSITION_META {
        /// Horizontal position gain.
        k_pos_xy: f64 = 0.95, "MPC_XY_P", "1/s", [0.0, 5.0], "Horizontal position gain";
        /// Vertical position gain.
        k_pos_z: f64 = 1.0, "MPC_Z_P", "1/s", [0.0, 5.0], "Vertical position gain";
        /// Horizontal velocity gain.
        k_vel_xy: f64 = 1.8, "MPC_XY_VEL_P_ACC", "1/s", [0.0, 10.0], "Horizontal velocity proportional gain";
        /// Horizontal velocity integral gain.
        k_vel_i_xy: f64 = 0.4, "MPC_XY_VEL_I_ACC", "1/s^2", [0.0, 10.0], "Horizontal velocity integral gain";
        /// Vertical velocity gain.
        k_vel_z: f64 = 4.0, "MPC_Z_VEL_P_ACC", "1/s", [0.0, 20.0], "Vertical velocity proportional gain";
        /// Vertical velocity integral gain.
        k_vel_i_z: f64 = 2.0, "MPC_Z_VEL_I_ACC", "1/s^2", [0.0, 20.0], "Vertical velocity integral gain";
        /// Horizontal speed limit.
        max_speed_h: f64 = 5.0, "MPC_XY_VEL_MAX", "m/s", [0.5, 30.0], "Largest horizontal speed";
        /// Climb rate limit.
        max_speed_up: f64 = 3.0, "MPC_Z_VEL_MAX_UP", "m/s", [0.3, 10.0], "Largest climb rate";
        /// Descent rate limit.
        max_speed_down: f64 = 1.0, "MPC_Z_VEL_MAX_DN", "m/s", [0.3, 10.0], "Largest descent rate";
        /// Horizontal acceleration limit.
        max_accel_h: f64 = 4.0, "MPC_ACC_HOR_MAX", "m/s^2", [0.5, 15.0], "Largest horizontal acceleration";
        /// Vertical acceleration limit.
        max_accel_v: f64 = 4.0, "MPC_ACC_UP_MAX", "m/s^2", [0.5, 15.0], "Largest vertical acceleration";
        /// Tilt limit.
        max_tilt_deg: f64 = 35.0, "MPC_TILTMAX_AIR", "deg", [5.0, 80.0], "Largest tilt in position and altitude modes";
        /// Integral bound.
        i_limit: f64 = 5.0, "MPC_I_MAX", "m/s^2", [0.0, 10.0], "Bound on the velocity integral";
        /// Outside-force feed-forward.
        k_disturbance_ff: f64 = 1.0, "MPC_DIST_FF", "", [0.0, 1.0], "Fraction of the outside force the thrust answers at once: the wind's share of what the accelerometer reads, and the drag of the set-point's velocity (0: the velocity integral alone)";
        /// Outside-force estimate's time constant.
        disturbance_tau_s: f64 = 0.05, "MPC_DIST_TAU", "s", [0.02, 5.0], "Time constant of the outside force (wind) estimate from the accelerometer";
        /// Rate of the position loop.
        loop_hz: f64 = 50.0, "MPC_LOOP_HZ", "Hz", [10.0, 1000.0], "Rate of the position and velocity loop (the attitude and rate loops run on every sensor sample)";
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> PositionParams {
        PositionParams {
            mass_kg: 1.5,
            k_pos: Vector3::new(1.0, 1.0, 1.0),
            k_vel: Vector3::new(3.0, 3.0, 4.0),
            k_vel_i: Vector3::new(0.5, 0.5, 1.0),
            max_speed_h: 5.0,
            max_speed_up: 3.0,
            max_speed_down: 1.5,
            max_accel_h: 4.0,
            max_accel_v: 4.0,
            max_tilt: 35f64.to_radians(),
            max_thrust_n: 40.0,
            i_limit: 3.0,
            k_disturbance_ff: 1.0,
            disturbance_tau_s: 0.3,
        }
    }

    /// Hold `pos`, heading north.
    fn hold_at(pos: Vector3<f64>) -> PositionSetpoint {
        PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: 0.0,
        }
    }

    #[test]
    fn attitude_from_thrust_points_body_down_axis_against_thrust() {
        let yaw = 0.7;
        let dir = Vector3::new(0.2, -0.1, -1.0).normalize();
        let q = attitude_from_thrust(&dir, yaw);
        assert!((q * Vector3::new(0.0, 0.0, -1.0) - dir).norm() < 1e-12);
        let level = attitude_from_thrust(&Vector3::new(0.0, 0.0, -1.0), yaw);
        assert!((level.euler_angles().2 - yaw).abs() < 1e-12);
    }

    #[test]
    fn hover_at_the_set_point_needs_exactly_the_weight() {
        let mut c = PositionController::new(params());
        let sp = hold_at(Vector3::new(0.0, 0.0, -5.0));
        let out = c.update(
            &sp,
            &sp.pos_ned_m,
            &Vector3::zeros(),
            &UnitQuaternion::identity(),
            0.01,
        );
        assert!((out.thrust_n - 1.5 * G).abs() < 1e-9);
        assert!(out.q_d.angle() < 1e-12);
    }

    #[test]
    fn far_set_points_are_limited_in_speed_tilt_and_slew() {
        let mut c = PositionController::new(params());
        let sp = hold_at(Vector3::new(100.0, 0.0, 0.0));
        let first = c.update(
            &sp,
            &Vector3::zeros(),
            &Vector3::zeros(),
            &UnitQuaternion::identity(),
            0.01,
        );
        assert!(
            first.vel_ned_m_s.x <= 4.0 * 0.01 + 1e-12,
            "slew-limited start: {}",
            first.vel_ned_m_s.x
        );
        let mut out = first;
        for _ in 0..500 {
            out = c.update(
                &sp,
                &Vector3::zeros(),
                &Vector3::zeros(),
                &UnitQuaternion::identity(),
                0.01,
            );
        }
        assert!((out.vel_ned_m_s.x - 5.0).abs() < 1e-9, "speed limit");
        let tilt = (out.q_d * Vector3::new(0.0, 0.0, -1.0)).angle(&Vector3::new(0.0, 0.0, -1.0));
        assert!(
            tilt <= 35f64.to_radians() + 1e-9,
            "tilt limit: {}",
            tilt.to_degrees()
        );
        // Going north means pitching nose down.
        assert!(out.q_d.euler_angles().1 < 0.0);
    }

    /// Drag in a strong wind needs more than `MPC_ACC_HOR_MAX`: the integral learns all of it
    /// (the vehicle, pushed at 5 m/s² with a 4 m/s² manoeuvre limit, comes to rest on its
    /// set-point), and only the tilt limit bounds it.
    #[test]
    fn a_push_beyond_the_acceleration_limit_is_held_by_the_integral() {
        let params = || PositionParams {
            i_limit: 7.0,
            ..params()
        };
        let mut c = PositionController::new(params());
        let sp = hold_at(Vector3::new(0.0, 0.0, -5.0));
        let push = Vector3::new(0.0, -5.0, 0.0); // m/s², toward the west
        let (dt, mut pos, mut vel) = (0.01, sp.pos_ned_m, Vector3::zeros());
        let mut out = None;
        for _ in 0..6000 {
            let o = c.update(&sp, &pos, &vel, &UnitQuaternion::identity(), dt);
            // Point mass: the commanded horizontal acceleration plus the push.
            vel += (Vector3::new(o.accel_ned_m_s2.x, o.accel_ned_m_s2.y, 0.0) + push) * dt;
            pos += vel * dt;
            out = Some(o);
        }
        let out = out.unwrap();
        assert!((pos - sp.pos_ned_m).norm() < 0.01, "held at {pos:?}");
        assert!(
            (out.accel_ned_m_s2.y - 5.0).abs() < 0.01,
            "{:?}",
            out.accel_ned_m_s2
        );
        // Beyond the tilt limit the push wins, and the integral stops growing.
        let mut c = PositionController::new(params());
        let (mut pos, mut vel) = (sp.pos_ned_m, Vector3::zeros());
        for _ in 0..3000 {
            let o = c.update(&sp, &pos, &vel, &UnitQuaternion::identity(), dt);
            let t = o.q_d * Vector3::new(0.0, 0.0, -1.0);
            let tilt = t.angle(&Vector3::new(0.0, 0.0, -1.0));
            assert!(tilt <= 35f64.to_radians() + 1e-9);
            vel.y += (o.accel_ned_m_s2.y.min(35f64.to_radians().tan() * G) - 9.0) * dt;
            pos += vel * dt;
        }
        let most = 35f64.to_radians().tan() * G;
        assert!(c.integral.y <= most, "integral bounded: {}", c.integral.y);
        assert!((pos - sp.pos_ned_m).norm() > 10.0, "pushed away");
    }

    #[test]
    fn nan_axes_fly_level_and_track_the_vertical_speed() {
        let mut c = PositionController::new(params());
        // Wound up toward the north-east first, far from the set-point, moving fast.
        let sp = PositionSetpoint {
            pos_ned_m: Vector3::new(30.0, 30.0, -5.0),
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: 0.3,
        };
        let (pos, vel) = (Vector3::new(0.0, 0.0, -5.0), Vector3::new(3.0, -2.0, 0.0));
        for _ in 0..300 {
            c.update(&sp, &pos, &vel, &UnitQuaternion::identity(), 0.01);
        }
        // Level and descend: horizontal position and velocity uncontrolled, 0.7 m/s down.
        let descend = PositionSetpoint {
            pos_ned_m: Vector3::new(f64::NAN, f64::NAN, f64::NAN),
            vel_ned_m_s: Vector3::new(f64::NAN, f64::NAN, 0.7),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: 0.3,
        };
        let mut out = c.update(&descend, &pos, &vel, &UnitQuaternion::identity(), 0.01);
        let up = Vector3::new(0.0, 0.0, -1.0);
        assert!(
            (out.q_d * up).angle(&up) < 1e-12,
            "level at once, whatever the position error, velocity or integral"
        );
        assert!(
            (out.q_d.euler_angles().2 - 0.3).abs() < 1e-12,
            "heading kept"
        );
        for _ in 0..300 {
            out = c.update(&descend, &pos, &vel, &UnitQuaternion::identity(), 0.01);
        }
        assert!((out.vel_ned_m_s.z - 0.7).abs() < 1e-9, "descent speed set");
        assert!(out.accel_ned_m_s2.z > 0.0, "accelerating down from rest");
        assert!(out.accel_ned_m_s2.xy().norm() < 1e-12);
    }

    #[test]
    fn an_axis_with_nothing_set_flies_level_not_nan() {
        // Ground contact frees the horizontal axes: position, velocity and acceleration NaN.
        let mut c = PositionController::new(params());
        let free = PositionSetpoint {
            pos_ned_m: Vector3::new(f64::NAN, f64::NAN, 0.5),
            vel_ned_m_s: Vector3::new(f64::NAN, f64::NAN, 0.0),
            accel_ned_m_s2: Vector3::new(f64::NAN, f64::NAN, 0.0),
            yaw_rad: 0.3,
        };
        let vel = Vector3::new(1.0, -2.0, 0.0);
        let out = c.update(
            &free,
            &Vector3::zeros(),
            &vel,
            &UnitQuaternion::identity(),
            0.02,
        );
        assert!(out.thrust_n.is_finite() && out.thrust_n > 0.0, "{out:?}");
        assert!(out.accel_ned_m_s2.iter().all(|a| a.is_finite()), "{out:?}");
        let up = Vector3::new(0.0, 0.0, -1.0);
        assert!((out.q_d * up).angle(&up) < 1e-12, "level: {out:?}");
    }

    #[test]
    fn lewis_altitude_law_compensates_tilt_within_its_limit() {
        let mut a = AltitudeController::new(1.5, 4.0, 1.0, 3.0, 35f64.to_radians(), 40.0, 5.0);
        let level = a.update(10.0, 10.0, 0.0, &UnitQuaternion::identity(), 0.01);
        assert!((level - 1.5 * G).abs() < 1e-9);
        let tilted = a.update(
            10.0,
            10.0,
            0.0,
            &UnitQuaternion::from_euler_angles(0.5, 0.0, 0.0),
            0.01,
        );
        assert!((tilted - 1.5 * G / 0.5f64.cos()).abs() < 1e-9);
        let upside = a.update(
            10.0,
            10.0,
            0.0,
            &UnitQuaternion::from_euler_angles(1.5, 0.0, 0.0),
            0.01,
        );
        assert!(
            (upside - 1.5 * G / 35f64.to_radians().cos()).abs() < 1e-9,
            "bounded compensation"
        );
    }
}
