//! The filter's starts: at its first rest (the mean rate as the bias), and in motion (the
//! fit of its first seconds, `motion_start.rs`).

use super::TiltHeadingFilter;
use crate::GRAVITY_M_S2;
use crate::estimator::motion_start::MotionStart;
use nalgebra::{UnitQuaternion, Vector3};

impl TiltHeadingFilter {
    /// The first rest: the mean rate becomes the bias, and the tilt and heading start again from
    /// the mean specific force and the next magnetometer samples. What the gyro integrated
    /// before, with the bias unknown, is dropped: through the accelerometer's 3 s low-pass a
    /// 0.5°/s bias leaves 1.5° of tilt that would take seconds to fade, and through the tilt
    /// 4° of heading.
    pub(super) fn align_at_rest(&mut self) {
        self.rest_aligned = true;
        self.bias
            .take_rest_mean(&self.rest.mean_rate(), self.rest.min_time_s());
        let q = self.attitude();
        let up = Vector3::new(0.0, 0.0, -1.0);
        let mean_accel = self.rest.mean_accel();
        let level = UnitQuaternion::rotation_between(&(q * mean_accel), &up).map_or(q, |c| c * q);
        self.start_at(level);
        // Still at rest: the low-passes start steady at the rest's values, not from the samples
        // to come (the take-off may be among them).
        self.accel_lp.reset_to(self.q_gyro * mean_accel);
        self.vel_accel_lp.reset_to(Vector3::zeros());
        self.bias.restart_tilt_at(&self.q_gyro.to_rotation_matrix());
    }

    /// A start in motion fitted (`motion_start.rs`): its bias is taken, the tilt starts again
    /// from its frame and the heading from its field, with the low-passes steady there (the
    /// vehicle's acceleration low-passed as it was).
    /// The estimate jumps: that is said as a tilt reset, so what was learned through the
    /// estimate before it (the position estimator's velocity and bias) is forgotten too.
    pub(super) fn align_in_motion(&mut self, fit: &MotionStart, integrated_bias: &Vector3<f64>) {
        let before = self.attitude();
        self.bias.take_fit(
            &(integrated_bias + fit.bias_correction),
            &fit.bias_covariance,
        );
        let up = Vector3::new(0.0, 0.0, -1.0);
        let start = UnitQuaternion::from_rotation_matrix(&fit.start_from_body);
        let level_from_start =
            UnitQuaternion::rotation_between(&fit.up, &up).unwrap_or_else(UnitQuaternion::identity);
        let (vel_accel_lp, last_vel) = (self.vel_accel_lp, self.last_vel);
        self.start_at(level_from_start * start);
        self.heading
            .take_field(&(level_from_start * fit.field), fit.field_samples);
        (self.vel_accel_lp, self.last_vel) = (vel_accel_lp, last_vel);
        let accel = if self.vel_accel_lp.started() {
            self.vel_accel_lp.value()
        } else {
            Vector3::zeros()
        };
        self.accel_lp
            .reset_to(up * GRAVITY_M_S2 + self.heading.rotation().inverse() * accel);
        self.bias.restart_tilt_at(&self.q_gyro.to_rotation_matrix());
        // The tilt starts steady, but at the window's mean acceleration: one time constant to
        // settle (not two, as from a first sample) before its corrections are taken for drift.
        self.running_s = self.settings.tau_acc_s;
        self.status.started_in_motion = true;
        self.heading_held = true;
        let down = |q: UnitQuaternion<f64>| q * Vector3::z();
        self.status.reset.tilt += 1;
        self.status.reset.tilt_rad = down(before).angle(&down(self.attitude()));
    }
}
