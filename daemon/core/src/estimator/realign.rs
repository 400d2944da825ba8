//! The attitude found again in flight, after a gap in the samples.
//!
//! When the samples stop for longer than `ATT_MAX_DR_T` in the air (a telemetry radio out of
//! range, a USB cable pulled, a flight board that resets), the vehicle goes on turning with no
//! gyro to see it: after two seconds on a held command it may be 60° over and still turning.
//! Started again at the last attitude, the filter cannot see that: under thrust the
//! accelerometer points along the thrust wherever the vehicle points, so it shows the stale
//! attitude as level.
//!
//! Instead the attitude is unknown from the samples' return, and found as an in-flight
//! alignment does (Savage, "Strapdown Analytics", 2nd ed., §6.1.2, velocity matching): the gyro
//! carries a frame from the return on, off the truth by one unknown constant rotation `C`
//! (NED ← gyro frame). Between two GPS solutions the specific force integrated in that frame,
//! `u = ∫ q_gyro f dt`, and the GPS's change of velocity less gravity's, `v = Δv − g T`, are one
//! vector seen in both frames: `C u = v` (two of `C`'s three angles, the same equation
//! `gps_tilt.rs` checks). The third, about `v`, is the one that puts the magnetic field, seen in
//! the gyro frame, in the magnetic meridian (the declination's vertical plane): the field's
//! direction within that plane (its dip) is not needed, only to choose between the two turns that
//! put it there. Under thrust `|v|` is about `g T`, so a window of 0.5 s is a vector of 5 m/s
//! against GPS velocity noise of a few cm/s: about a degree of tilt, twice that of heading
//! through a steep field's dip.

use super::gps_tilt::{DelayedVelocity, GpsTiltCheck, GpsWindow};
use crate::GRAVITY_M_S2;
use nalgebra::{Unit, UnitQuaternion, Vector3};

/// The shortest GPS window solved (s): six solutions of a 10 Hz receiver.
pub const MIN_WINDOW_S: f64 = 0.5;
/// The shortest `v` solved, over gravity's in the same time: the vehicle under at least this
/// fraction of its weight's thrust (in a free fall the force shows nothing).
const MIN_FORCE_FRACTION: f64 = 0.3;
/// How far the two lengths may differ (fraction): more, and something (a GPS glitch, a gap in
/// the window) broke the equation.
const LENGTH_TOLERANCE: f64 = 0.1;
/// The least part of the field's direction across `v` (fraction): along `v` it shows no turn.
const MIN_ACROSS: f64 = 0.2;
/// The least magnetometer samples averaged.
const MIN_FIELD_SAMPLES: u32 = 5;

/// What the search collects from the samples' return on, in the frame the gyro carried from
/// there (the search frame): the specific force's integral and the GPS solutions
/// (`gps_tilt.rs`), the magnetic field's mean direction.
#[derive(Debug, Clone, Default)]
pub struct InFlightAlignment {
    check: GpsTiltCheck,
    field_sum: Vector3<f64>,
    field_samples: u32,
    /// The first sample after the return has been taken.
    started: bool,
    /// Time since the samples returned (s).
    pub elapsed_s: f64,
}

impl InFlightAlignment {
    /// One sample: the search frame from the body, the specific force and the calibrated field
    /// (FRD), and a GPS velocity if one arrived.
    pub fn update(
        &mut self,
        search_from_body: &UnitQuaternion<f64>,
        accel: &Vector3<f64>,
        field: Option<&Vector3<f64>>,
        gps: Option<&DelayedVelocity>,
        dt: f64,
    ) {
        // The first sample closes the gap: its interval is the gap's, not one the force was
        // measured over, and a GPS solution measured in the dark (arriving just after) must
        // find no integral to pair with. The search's clock starts here.
        let dt = if self.started { dt } else { 0.0 };
        self.started = true;
        self.elapsed_s += dt;
        let rotation = search_from_body.to_rotation_matrix();
        self.check
            .update(&(search_from_body * accel), rotation.matrix(), gps, dt);
        if let Some(m) = field.and_then(|m| (search_from_body * m).try_normalize(1e-9)) {
            self.field_sum += m;
            self.field_samples += 1;
        }
    }

    /// The search frame's attitude (NED from it), when the GPS solution taken at this sample
    /// completes a window of [`MIN_WINDOW_S`]. (A longer window, taken while the vehicle levels
    /// on the first, was no better: 1.4° became 5.5° in one flight, 2.2° 0.5° in another.)
    pub fn try_solve(&self, declination_rad: f64, dip_rad: f64) -> Option<UnitQuaternion<f64>> {
        self.solve(&self.check.span()?, declination_rad, dip_rad)
    }

    /// The search frame's attitude (NED from it), from a GPS window taken wholly after the
    /// return, the declination (rad) and the field's expected dip (rad, positive down), if they
    /// pin it.
    pub fn solve(
        &self,
        window: &GpsWindow,
        declination_rad: f64,
        dip_rad: f64,
    ) -> Option<UnitQuaternion<f64>> {
        if window.duration_s < MIN_WINDOW_S || self.field_samples < MIN_FIELD_SAMPLES {
            return None;
        }
        let u = window.force;
        let v = window.accel - Vector3::new(0.0, 0.0, GRAVITY_M_S2);
        let length = v.norm();
        if length < MIN_FORCE_FRACTION * GRAVITY_M_S2
            || (u.norm() - length).abs() > LENGTH_TOLERANCE * length
        {
            return None;
        }
        // Two angles: the force onto `v`.
        let onto_v = UnitQuaternion::rotation_between(&u, &v)?;
        let w = onto_v * self.field_sum.try_normalize(1e-9)?;
        // The third: a turn ψ about `v` that puts `w` in the magnetic meridian, n·R(ψ)w = 0.
        let axis = Unit::new_normalize(v);
        let along = axis.into_inner() * axis.dot(&w);
        let across = w - along;
        if across.norm() < MIN_ACROSS {
            return None;
        }
        let beside = axis.cross(&across);
        let north = Vector3::new(declination_rad.cos(), declination_rad.sin(), 0.0);
        let normal = Vector3::new(-declination_rad.sin(), declination_rad.cos(), 0.0);
        let (c, a, b) = (normal.dot(&along), normal.dot(&across), normal.dot(&beside));
        let r = a.hypot(b);
        if r < 1e-6 || c.abs() > r {
            return None;
        }
        let phi = b.atan2(a);
        let spread = (-c / r).acos();
        let expected = north * dip_rad.cos() + Vector3::z() * dip_rad.sin();
        let turned = |psi: f64| UnitQuaternion::from_axis_angle(&axis, psi);
        let psi = [phi + spread, phi - spread].into_iter().max_by(|p, q| {
            let d = |psi: f64| (turned(psi) * w).dot(&expected);
            d(*p).total_cmp(&d(*q))
        })?;
        Some(turned(psi) * onto_v)
    }
}

#[cfg(test)]
mod tests;
