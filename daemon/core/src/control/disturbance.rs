//! The air's push on the vehicle, from the accelerometer, and the wind it means.
//!
//! A multirotor's thrust acts along its body −z axis, so whatever the accelerometer reads in
//! the body's x–y plane is an outside force: the air's drag on frame and rotors, a gust, a tether.
//! With the attitude estimate the specific force `f` (body) turns into NED, `R f = d + τ b₃`, where
//! `b₃ = R (0, 0, −1)` is the thrust direction, `τ` the thrust per mass and `d` the outside force
//! per mass, taken horizontal (wind is): the vertical row gives `τ`, the horizontal rows `d`, with
//! no thrust model at all. Low-passed, `d` is fed forward by the position loop (the thrust asked
//! for is `m (a_sp − d − g)`), so a steady wind costs no steady offset and no wait for an
//! integrator; its leftover is the integrator's. A tilt error of the estimate does not enter `d`
//! (the thrust direction and `f` turn together).
//!
//! What is fed forward is the wind's share of `d`: `d` less the drag the vehicle's own velocity
//! would make in still air (`still_air_drag`). That drag damps every motion the loops make, and
//! they were tuned with it; answering it too, through a low-pass, would take the damping away
//! and put a lag in its place.
//!
//! The wind: the drag model of the airframe (linear and quadratic per body axis, as the
//! simulator's) turned around for the air-relative velocity `v_a` that makes `m d`, and
//! `wind = v − v_a`, in the heading's frame (the body's x–y axes at a small tilt).

use airframe::DragSpec;
use nalgebra::{UnitQuaternion, Vector2, Vector3};

/// The outside force's estimate, per mass, horizontal (NED, m/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisturbanceObserver {
    /// Low-pass time constant (s).
    pub tau_s: f64,
    accel_ned_m_s2: Vector3<f64>,
    /// Running variance of the raw estimate about the low-passed one, per axis ((m/s²)²).
    var_m2_s4: Vector2<f64>,
    /// The low-pass's last gain: the estimate's own variance is the raw one's times k/(2−k).
    gain: f64,
    primed: bool,
}

/// The wind as the drag model reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindEstimate {
    /// Wind velocity, NED (m/s): where the air moves to (a north wind is negative north).
    pub wind_ned_m_s: Vector3<f64>,
    /// Variance of the horizontal wind estimate from the accelerometer's noise, the larger of
    /// the two axes ((m/s)²).
    pub var_horiz_m2_s2: f64,
    /// The outside force per mass it came from, NED (m/s²).
    pub accel_ned_m_s2: Vector3<f64>,
}

impl DisturbanceObserver {
    /// An observer at rest (no outside force known).
    pub fn new(tau_s: f64) -> Self {
        Self {
            tau_s,
            accel_ned_m_s2: Vector3::zeros(),
            var_m2_s4: Vector2::zeros(),
            gain: 0.0,
            primed: false,
        }
    }

    /// Forgets the estimate (disarmed).
    pub fn reset(&mut self) {
        *self = Self::new(self.tau_s);
    }

    /// Whether it has learned anything since the last reset.
    pub fn primed(&self) -> bool {
        self.primed
    }

    /// Folds in one sample: the attitude `q` (body FRD → NED) and the specific force `f_frd`
    /// (m/s²) over `dt` (s).
    pub fn update(&mut self, q: &UnitQuaternion<f64>, f_frd: &Vector3<f64>, dt: f64) {
        let f = q * f_frd;
        let b3 = q * Vector3::new(0.0, 0.0, -1.0);
        if b3.z > -0.3 {
            return; // thrust nowhere near up: no vertical row to solve with
        }
        let tau = f.z / b3.z;
        let raw = Vector3::new(f.x - tau * b3.x, f.y - tau * b3.y, 0.0);
        if !raw.iter().all(|x| x.is_finite()) {
            return;
        }
        if !self.primed {
            self.accel_ned_m_s2 = raw;
            self.primed = true;
            return;
        }
        let k = (dt / self.tau_s.max(dt)).clamp(0.0, 1.0);
        self.gain = k;
        let e = raw - self.accel_ned_m_s2;
        self.accel_ned_m_s2 += e * k;
        for i in 0..2 {
            self.var_m2_s4[i] += k * (e[i] * e[i] - self.var_m2_s4[i]);
        }
    }

    /// The outside force per mass, NED (m/s²; zero vertically).
    pub fn accel_ned_m_s2(&self) -> Vector3<f64> {
        self.accel_ned_m_s2
    }

    /// The wind that makes this force on a vehicle of `mass_kg` with `drag`, flying at `vel_ned`
    /// (m/s) on heading `yaw` (rad); `None` without a drag model or an estimate.
    pub fn wind(
        &self,
        vel_ned: &Vector3<f64>,
        yaw: f64,
        mass_kg: f64,
        drag: &DragSpec,
    ) -> Option<WindEstimate> {
        if !self.primed {
            return None;
        }
        let (s, c) = yaw.sin_cos();
        // NED → heading frame (x forward, y right), and back.
        let to_body = |v: Vector2<f64>| Vector2::new(c * v.x + s * v.y, -s * v.x + c * v.y);
        let to_ned = |v: Vector2<f64>| Vector2::new(c * v.x - s * v.y, s * v.x + c * v.y);
        let force = to_body(self.accel_ned_m_s2.xy() * mass_kg);
        // The low-passed estimate's variance: a first-order low-pass of gain k passes
        // k/(2−k) of white noise's.
        let passed = self.gain / (2.0 - self.gain).max(1.0);
        let var = self.var_m2_s4 * mass_kg * mass_kg * passed;
        let mut air = Vector2::zeros();
        let mut var_air = 0.0f64;
        for i in 0..2 {
            let (lin, quad) = (drag.linear_n_s_m[i], drag.quadratic_n_s2_m2[i]);
            // Drag opposes the air-relative velocity: F = −(lin v + quad |v| v).
            let speed = drag_speed(force[i].abs(), lin, quad)?;
            air[i] = -force[i].signum() * speed;
            let slope = lin + 2.0 * quad * speed; // dF/dv
            var_air = var_air.max(var.max() / (slope * slope));
        }
        let wind = vel_ned.xy() - to_ned(air);
        Some(WindEstimate {
            wind_ned_m_s: Vector3::new(wind.x, wind.y, 0.0),
            var_horiz_m2_s2: var_air,
            accel_ned_m_s2: self.accel_ned_m_s2,
        })
    }
}

/// The drag per mass (NED, m/s², horizontal) that `drag` makes on a vehicle of `mass_kg` moving
/// at `vel_ned` (m/s) through still air on heading `yaw` (rad): `−(lin v + quad |v| v)` per
/// heading-frame axis, as the simulator's per body axis at a small tilt.
pub fn still_air_drag(
    vel_ned: &Vector3<f64>,
    yaw: f64,
    mass_kg: f64,
    drag: &DragSpec,
) -> Vector3<f64> {
    let (s, c) = yaw.sin_cos();
    let v = Vector2::new(
        c * vel_ned.x + s * vel_ned.y,
        -s * vel_ned.x + c * vel_ned.y,
    );
    let f = Vector2::from_fn(|i, _| {
        -(drag.linear_n_s_m[i] * v[i] + drag.quadratic_n_s2_m2[i] * v[i].abs() * v[i])
    });
    Vector3::new(c * f.x - s * f.y, s * f.x + c * f.y, 0.0) / mass_kg
}

/// The speed (m/s) at which `lin v + quad v²` makes `force` (N); `None` for no drag at all.
fn drag_speed(force: f64, lin: f64, quad: f64) -> Option<f64> {
    if quad > 1e-9 {
        Some((-lin + (lin * lin + 4.0 * quad * force).sqrt()) / (2.0 * quad))
    } else if lin > 1e-9 {
        Some(force / lin)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: f64 = crate::GRAVITY_M_S2;

    fn quad_x_drag() -> DragSpec {
        DragSpec {
            linear_n_s_m: [0.25, 0.25, 0.10],
            quadratic_n_s2_m2: [0.03, 0.03, 0.06],
            rotational_n_m_s_rad: [0.0; 3],
            aero_torque_m3: [0.0; 3],
        }
    }

    /// The specific force (body) of a vehicle at attitude `q` with thrust `thrust_n` and an
    /// outside horizontal force `push` (N, NED), mass `m`.
    fn specific_force(
        q: &UnitQuaternion<f64>,
        thrust_n: f64,
        push: Vector3<f64>,
        m: f64,
    ) -> Vector3<f64> {
        Vector3::new(0.0, 0.0, -thrust_n / m) + q.inverse_transform_vector(&(push / m))
    }

    #[test]
    fn a_horizontal_push_is_read_whatever_the_attitude_and_thrust() {
        let m = 1.5;
        let push = Vector3::new(-5.5, 2.0, 0.0);
        for (roll, pitch, yaw, thrust) in [
            (0.0, 0.0, 0.0, 14.7),
            (0.2, -0.3, 1.0, 18.0),
            (-0.35, 0.1, -2.5, 9.0),
        ] {
            let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
            let mut o = DisturbanceObserver::new(0.2);
            o.update(&q, &specific_force(&q, thrust, push, m), 0.004);
            let d = o.accel_ned_m_s2();
            assert!((d - push / m).norm() < 1e-9, "{d} against {}", push / m);
        }
    }

    #[test]
    fn no_push_reads_zero_when_the_estimate_is_tilted_wrong() {
        // Hovering level in still air; the estimate 3° off in roll: f turns with b3, d stays 0.
        let truth = UnitQuaternion::identity();
        let f = specific_force(&truth, 1.5 * G, Vector3::zeros(), 1.5);
        let wrong = UnitQuaternion::from_euler_angles(3f64.to_radians(), 0.0, 0.4);
        let mut o = DisturbanceObserver::new(0.2);
        o.update(&wrong, &f, 0.004);
        assert!(o.accel_ned_m_s2().norm() < 1e-12);
    }

    /// The drag (N, NED, horizontal) at air-relative velocity `air_ned` on heading `yaw`, per
    /// heading-frame axis as the simulator's per body axis.
    fn drag_ned(air_ned: Vector2<f64>, yaw: f64, d: &DragSpec) -> Vector3<f64> {
        let (s, c) = yaw.sin_cos();
        let b = Vector2::new(
            c * air_ned.x + s * air_ned.y,
            -s * air_ned.x + c * air_ned.y,
        );
        let f = Vector2::from_fn(|i, _| {
            -(d.linear_n_s_m[i] * b[i] + d.quadratic_n_s2_m2[i] * b[i].abs() * b[i])
        });
        Vector3::new(c * f.x - s * f.y, s * f.x + c * f.y, 0.0)
    }

    #[test]
    fn the_drag_model_turned_around_gives_the_wind() {
        let drag = quad_x_drag();
        let m = 1.5;
        // Holding still, heading 30°, leaning into a 10 m/s wind from the north (air moving
        // south): the vehicle's air-relative velocity is 10 m/s north.
        let yaw = 30f64.to_radians();
        let push = drag_ned(Vector2::new(10.0, 0.0), yaw, &drag);
        let q = UnitQuaternion::from_euler_angles(0.1, -0.3, yaw);
        let mut o = DisturbanceObserver::new(0.2);
        o.update(&q, &specific_force(&q, 16.0, push, m), 0.004);
        let w = o.wind(&Vector3::zeros(), yaw, m, &drag).unwrap();
        assert!(
            (w.wind_ned_m_s - Vector3::new(-10.0, 0.0, 0.0)).norm() < 1e-9,
            "{}",
            w.wind_ned_m_s
        );
        // Flying north-east at 4 m/s in still air: the drag of that, and no wind.
        let vel = Vector3::new(4.0, 3.0, 0.0) * 0.8;
        let push = drag_ned(vel.xy(), 0.0, &drag);
        let q = UnitQuaternion::from_euler_angles(0.05, -0.1, 0.0);
        let mut o = DisturbanceObserver::new(0.2);
        o.update(&q, &specific_force(&q, 15.0, push, m), 0.004);
        let w = o.wind(&vel, 0.0, m, &drag).unwrap();
        assert!(w.wind_ned_m_s.norm() < 1e-9, "{}", w.wind_ned_m_s);
    }

    #[test]
    fn in_still_air_the_winds_share_is_nothing_whatever_the_vehicles_own_speed() {
        // The push the accelerometer reads is the drag of the vehicle's own motion alone: the
        // share fed forward (what is left after `still_air_drag`) is zero, so the loops keep
        // the damping they were tuned with.
        let drag = quad_x_drag();
        let m = 1.5;
        for (vel, yaw) in [
            (Vector2::new(4.0, 3.0), 0.0),
            (Vector2::new(-2.0, 5.0), 1.2),
            (Vector2::new(0.3, -0.1), -2.0),
        ] {
            let push = drag_ned(vel, yaw, &drag) / m;
            let own = still_air_drag(&Vector3::new(vel.x, vel.y, 0.0), yaw, m, &drag);
            assert!((push - own).norm() < 1e-12, "{push} against {own}");
        }
    }

    #[test]
    fn it_low_passes_and_its_variance_says_how_noisy_the_push_is() {
        let q = UnitQuaternion::identity();
        let mut o = DisturbanceObserver::new(0.5);
        assert!(
            o.wind(&Vector3::zeros(), 0.0, 1.5, &quad_x_drag())
                .is_none()
        );
        let dt = 0.004;
        let mut quiet = 0.0;
        for k in 0..2000 {
            let noise = if k % 2 == 0 { 0.5 } else { -0.5 };
            let f = Vector3::new(-2.0 + noise, 0.0, -G);
            o.update(&q, &f, dt);
            if k == 999 {
                quiet = o.var_m2_s4.x;
            }
        }
        assert!(
            (o.accel_ned_m_s2().x + 2.0).abs() < 0.01,
            "{}",
            o.accel_ned_m_s2()
        );
        assert!((quiet - 0.25).abs() < 0.03, "variance of ±0.5: {quiet}");
        let w = o.wind(&Vector3::zeros(), 0.0, 1.5, &quad_x_drag()).unwrap();
        assert!(w.var_horiz_m2_s2 > 0.0 && w.var_horiz_m2_s2.is_finite());
        o.reset();
        assert!(!o.primed() && o.accel_ned_m_s2().norm() == 0.0);
    }
}
