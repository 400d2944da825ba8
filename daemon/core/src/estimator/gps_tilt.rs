//! The tilt checked against the GPS's velocity in flight.
//!
//! A vehicle that flies on a wrong tilt accelerates where it thinks it hovers, and the fused
//! velocity cannot show it: the position estimator integrates the same wrong attitude, so its
//! acceleration agrees with the tilt it was made from (a 30° error in a hover faded only with the
//! accelerometer's 3 s low-pass, over 15 s, with the vehicle swinging meanwhile). The GPS's
//! velocity is made without the attitude. Over a window of a second, the specific force the
//! estimate rotates into the level frame must equal the GPS's change of velocity less gravity:
//! `R̂ ∫f dt = Δv − g T`. Both sides are integrals, so the vehicle's swinging does not matter, and
//! the comparison is made at the GPS solution's own time (its age is the position estimator's
//! `EST_GPS_DELAY`).
//!
//! The specific force is integrated in the gyro frame, which the gyro error turns by a constant
//! rotation (a glitch, a saturated gyro), so a window measures that rotation whatever the vehicle
//! did. When the window's two halves agree on an error beyond the limit, and the force's length
//! is the GPS's, the tilt is taken from the later half at once (`TiltReset`, as `recovery.rs`).
//! The halves must agree so that a window that straddles the moment the error was made (half
//! before, half after) is not taken as the error.

use super::recovery::TiltReset;
use crate::GRAVITY_M_S2;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use std::collections::VecDeque;

/// A GPS velocity, and how old it is when it arrives (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayedVelocity {
    /// Velocity, NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Age (s).
    pub age_s: f64,
}

/// The window compared (s).
const WINDOW_S: f64 = 1.0;
/// The oldest GPS solution accepted (s): `EST_GPS_DELAY`'s range.
const MAX_AGE_S: f64 = 0.5;
/// How far the force's length may be from the GPS's (fraction).
const LENGTH_TOLERANCE: f64 = 0.05;
/// The error that is reset (rad): as `recovery.rs` armed.
const RESET_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;
/// How far the halves may disagree: at least this (rad), or this fraction of the error.
const HALVES_AGREE_RAD: f64 = 3.0 * std::f64::consts::PI / 180.0;
const HALVES_AGREE_FRACTION: f64 = 0.2;

/// The integrals the windows are made of, at one time: of the specific force and of the gyro
/// frame's rotation from the body.
#[derive(Debug, Clone, Copy)]
struct Integrals {
    force: Vector3<f64>,
    rotation: Matrix3<f64>,
}

impl Integrals {
    fn lerp(&self, other: &Self, w: f64) -> Self {
        Self {
            force: self.force + (other.force - self.force) * w,
            rotation: self.rotation + (other.rotation - self.rotation) * w,
        }
    }
}

/// A GPS solution with the integrals at its time.
#[derive(Debug, Clone, Copy)]
struct Fix {
    t_s: f64,
    vel: Vector3<f64>,
    integrals: Integrals,
}

/// A stretch between two GPS solutions: the mean specific force (gyro frame), the mean
/// rotation from the body to the gyro frame, and the GPS's mean acceleration (NED) over it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsWindow {
    /// Mean specific force, gyro frame (m/s²).
    pub force: Vector3<f64>,
    /// Mean rotation matrix, gyro frame from body.
    pub rotation: Matrix3<f64>,
    /// The GPS's mean acceleration, NED (m/s²).
    pub accel: Vector3<f64>,
    /// Its length (s).
    pub duration_s: f64,
}

type Half = GpsWindow;

impl GpsWindow {
    fn between(a: &Fix, b: &Fix) -> Option<Self> {
        let t = b.t_s - a.t_s;
        (t > 0.0).then(|| Self {
            force: (b.integrals.force - a.integrals.force) / t,
            rotation: (b.integrals.rotation - a.integrals.rotation) / t,
            accel: (b.vel - a.vel) / t,
            duration_s: t,
        })
    }

    /// The rotation from the estimate's specific force to the GPS's, in the level frame
    /// (scaled axis, rad), if their lengths agree.
    fn error(
        &self,
        q_tilt: &UnitQuaternion<f64>,
        heading: &UnitQuaternion<f64>,
    ) -> Option<Vector3<f64>> {
        let estimated = q_tilt * self.force;
        let measured = heading.inverse() * (self.accel - Vector3::new(0.0, 0.0, GRAVITY_M_S2));
        let length = measured.norm();
        if (estimated.norm() - length).abs() > LENGTH_TOLERANCE * length {
            return None;
        }
        Some(UnitQuaternion::rotation_between(&estimated, &measured)?.scaled_axis())
    }
}

/// The integral of the specific force and the GPS solutions of the last window.
#[derive(Debug, Clone, Default)]
pub struct GpsTiltCheck {
    t_s: f64,
    integrals: Option<Integrals>,
    /// The integrals at each step of the last [`MAX_AGE_S`].
    steps: VecDeque<(f64, Integrals)>,
    fixes: VecDeque<Fix>,
    /// The newest window's halves, when a solution completed one.
    halves: Option<(Half, Half)>,
    /// A solution was taken at this sample.
    fresh: bool,
}

impl GpsTiltCheck {
    /// Forgets everything (the filter started again, or the GPS went away).
    pub fn clear(&mut self) {
        self.steps.clear();
        self.fixes.clear();
        self.halves = None;
        self.fresh = false;
    }

    /// One sample: the specific force in the gyro frame, the gyro frame's rotation from the
    /// body, and a GPS velocity if one arrived.
    pub fn update(
        &mut self,
        f_gyro_frame: &Vector3<f64>,
        gyro_from_body: &Matrix3<f64>,
        gps: Option<&DelayedVelocity>,
        dt: f64,
    ) {
        self.t_s += dt;
        let last = self.integrals.unwrap_or(Integrals {
            force: Vector3::zeros(),
            rotation: Matrix3::zeros(),
        });
        let now = Integrals {
            force: last.force + f_gyro_frame * dt,
            rotation: last.rotation + gyro_from_body * dt,
        };
        self.integrals = Some(now);
        self.steps.push_back((self.t_s, now));
        while self
            .steps
            .front()
            .is_some_and(|(t, _)| *t < self.t_s - MAX_AGE_S - dt)
        {
            self.steps.pop_front();
        }
        self.halves = None;
        self.fresh = false;
        let Some(g) = gps.filter(|g| (0.0..=MAX_AGE_S).contains(&g.age_s)) else {
            return;
        };
        let Some(integrals) = self.integrals_at(self.t_s - g.age_s) else {
            return;
        };
        let fix = Fix {
            t_s: self.t_s - g.age_s,
            vel: g.vel_ned_m_s,
            integrals,
        };
        if self.fixes.back().is_some_and(|last| fix.t_s <= last.t_s) {
            return;
        }
        self.fixes.push_back(fix);
        self.fresh = true;
        // Keep a window and a little more, so the oldest is about a window before the newest.
        while self.fixes.len() > 2 && self.fixes[1].t_s <= fix.t_s - WINDOW_S {
            self.fixes.pop_front();
        }
        let first = self.fixes[0];
        if fix.t_s - first.t_s < 0.9 * WINDOW_S {
            return;
        }
        let middle_t = 0.5 * (first.t_s + fix.t_s);
        let middle = self.fixes.iter().min_by(|a, b| {
            (a.t_s - middle_t)
                .abs()
                .total_cmp(&(b.t_s - middle_t).abs())
        });
        if let Some(m) = middle {
            self.halves = Half::between(&first, m).zip(Half::between(m, &fix));
        }
    }

    /// The integrals at `t_s`, interpolated between the steps.
    fn integrals_at(&self, t_s: f64) -> Option<Integrals> {
        let i = self.steps.partition_point(|(t, _)| *t < t_s);
        let (t1, s1) = *self.steps.get(i)?;
        let Some(&(t0, s0)) = i.checked_sub(1).and_then(|j| self.steps.get(j)) else {
            return (t1 - t_s < 1e-9).then_some(s1);
        };
        Some(s0.lerp(&s1, ((t_s - t0) / (t1 - t0)).clamp(0.0, 1.0)))
    }

    /// The time (s) and the integral of the gyro frame's rotation from the body so far.
    pub fn rotation_integral(&self) -> (f64, Matrix3<f64>) {
        (
            self.t_s,
            self.integrals.map_or(Matrix3::zeros(), |i| i.rotation),
        )
    }

    /// The whole window a GPS solution completed at this sample (about a second), if one did.
    pub fn window(&self) -> Option<GpsWindow> {
        self.halves?;
        let (first, last) = (self.fixes.front()?, self.fixes.back()?);
        GpsWindow::between(first, last)
    }

    /// From the oldest solution kept to the one taken at this sample, if one was (up to about a
    /// second): after [`Self::clear`], the stretch since then.
    pub fn span(&self) -> Option<GpsWindow> {
        if !self.fresh {
            return None;
        }
        GpsWindow::between(self.fixes.front()?, self.fixes.back()?)
    }

    /// The reset to make now, if the window a GPS solution just completed shows a tilt error
    /// beyond the limit that both its halves agree on: the tilt `q_tilt` (gyro frame → level)
    /// and the heading (level → NED) as they are.
    pub fn check(
        &self,
        q_tilt: &UnitQuaternion<f64>,
        heading: &UnitQuaternion<f64>,
    ) -> Option<TiltReset> {
        let (early, late) = self.halves?;
        let e1 = early.error(q_tilt, heading)?;
        let e2 = late.error(q_tilt, heading)?;
        let error = 0.5 * (e1 + e2).norm();
        let agree = (e1 - e2).norm() <= HALVES_AGREE_RAD.max(HALVES_AGREE_FRACTION * error);
        (error > RESET_RAD && agree).then_some(TiltReset {
            specific_force: late.force,
            accel_ned: late.accel,
            error_rad: error,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vehicle swinging at ±2 m/s² whose gyro frame is turned by `error(t)` from the truth:
    /// every check's error, with its time (s), over `seconds`.
    fn checks(error: impl Fn(f64) -> UnitQuaternion<f64>, seconds: f64) -> Vec<(f64, f64)> {
        let mut c = GpsTiltCheck::default();
        let dt = 0.004;
        let accel = |t: f64| Vector3::new(2.0 * (t * 2.0).sin(), (t * 3.0).cos(), 0.0);
        let velocity = |t: f64| Vector3::new(1.0 - (t * 2.0).cos(), (t * 3.0).sin() / 3.0, 0.0);
        let mut found = Vec::new();
        for i in 1..=(seconds / dt) as usize {
            let t = i as f64 * dt;
            let f = error(t) * (accel(t) - Vector3::new(0.0, 0.0, GRAVITY_M_S2));
            // A 10 Hz GPS whose solutions are 0.1 s old.
            let gps = (i % 25 == 0 && t > 0.1).then(|| DelayedVelocity {
                vel_ned_m_s: velocity(t - 0.1),
                age_s: 0.1,
            });
            c.update(&f, &Matrix3::identity(), gps.as_ref(), dt);
            let level = UnitQuaternion::identity();
            if let Some(r) = c.check(&level, &level) {
                found.push((t, r.error_rad.to_degrees()));
            }
        }
        found
    }

    #[test]
    fn a_constant_error_is_measured_whatever_the_vehicle_does() {
        let turned = UnitQuaternion::from_scaled_axis(Vector3::new(20f64.to_radians(), 0.0, 0.0));
        let found = checks(|_| turned, 3.0);
        let (first, error) = found[0];
        assert!((1.0..1.3).contains(&first), "first at {first} s");
        assert!((error - 20.0).abs() < 0.5, "{error}°");
        assert!(checks(|_| UnitQuaternion::identity(), 10.0).is_empty());
    }

    #[test]
    fn a_window_that_straddles_the_error_is_not_taken() {
        let turned = UnitQuaternion::from_scaled_axis(Vector3::new(30f64.to_radians(), 0.0, 0.0));
        let found = checks(
            |t| {
                if t < 2.0 {
                    UnitQuaternion::identity()
                } else {
                    turned
                }
            },
            5.0,
        );
        let (first, error) = found[0];
        // Half a window after the error the halves disagree; the error taken is most of it.
        assert!(first > 2.5, "first at {first} s");
        assert!(error > 24.0, "{error}°");
    }
}
