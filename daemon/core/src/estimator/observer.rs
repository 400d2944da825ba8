//! The nonlinear attitude observer with gyro-bias estimation of Castillo (97)–(105).
//!
//! It filters the noisy attitude measurement of the q-method with the gyroscopes:
//! `Ω̂ = Ω_g − δ̂` (104), `q̃ = q̂* ⊗ q` (103), `r = q̃* ⊗ (0, Ω̂ + k sign(q̃₀) q̃̄) ⊗ q̃` (105),
//! `q̂ ← q̂ ⊗ exp(T r / 2)` (101), `δ̂ ← δ̂ − (T/2) sign(q̃₀) q̃̄` (102).
//!
//! Implemented as predict-then-correct: q̂ is first propagated with Ω̂ over the sample interval,
//! then compared with the measurement of the same instant. (The paper's recursion compares the
//! measurement at t with the estimate of t − T, a lag of Ω·T that the bias estimate then learns:
//! 0.7° per correction at 180 °/s and 250 Hz.) The correction `k sign(q̃₀) q̃̄` lies along q̃'s own
//! axis, so the rotation by q̃ in (105) leaves it unchanged.
//!
//! Beyond the paper: bias learning pauses while the innovation is large (a 173° start would
//! otherwise drive (102) into its bound for seconds), while the vehicle rotates fast, and while
//! the accelerometer is doubted; the bias estimate is bounded.

use crate::math::quat;
use nalgebra::{UnitQuaternion, Vector3};

/// Observer state: attitude estimate and gyro-bias estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeObserver {
    /// Estimated attitude `q̂` (`q_ned_from_frd`).
    pub q: UnitQuaternion<f64>,
    /// Estimated gyro bias `δ̂_Ω` (rad/s, FRD).
    pub bias: Vector3<f64>,
    /// Attitude gain `k` of (105) (1/s).
    pub gain: f64,
    /// Bias gain of (102): ½ in the paper.
    pub bias_gain: f64,
    /// Largest bias estimate magnitude (rad/s): a bound, so a long wrong measurement cannot wind
    /// the estimate up without limit.
    pub bias_limit: f64,
    /// Innovation angle (rad) above which the bias estimate is held.
    pub bias_freeze_rad: f64,
    /// Body rate (rad/s) above which the bias estimate is held: during manoeuvres small timing
    /// and scale errors look like bias (PX4's attitude estimator does the same).
    pub bias_freeze_rate_rad_s: f64,
}

impl AttitudeObserver {
    /// An observer starting at `q` with zero bias.
    pub fn new(q: UnitQuaternion<f64>, gain: f64, bias_gain: f64, bias_limit: f64) -> Self {
        Self {
            q,
            bias: Vector3::zeros(),
            gain,
            bias_gain,
            bias_limit,
            bias_freeze_rad: 2f64.to_radians(),
            bias_freeze_rate_rad_s: 20f64.to_radians(),
        }
    }

    /// The body rate corrected by the bias estimate, (104).
    pub fn rate(&self, gyro: &Vector3<f64>) -> Vector3<f64> {
        gyro - self.bias
    }

    /// One step of (101)–(105) with the mean gyro rate `gyro` over `dt`, corrected by the attitude
    /// measurement `measured` when there is one (otherwise pure gyro propagation).
    /// Returns the error angle `|q̃|` (rad), 0 without a measurement.
    /// `trust` ∈ [0, 1] scales the correction gain (a doubted accelerometer corrects less) and,
    /// below 1, pauses bias learning.
    pub fn update(
        &mut self,
        measured: Option<&UnitQuaternion<f64>>,
        trust: f64,
        gyro: &Vector3<f64>,
        dt: f64,
    ) -> f64 {
        let rate = self.rate(gyro); // (104)
        self.q = quat::propagate(&self.q, &rate, dt); // (101), the Ω̂ part
        let Some(qm) = measured else {
            return 0.0;
        };
        let e = self.q.inverse() * qm; // (103)
        let sign = if e.w >= 0.0 { 1.0 } else { -1.0 };
        let ev = e.imag();
        let innovation = 2.0 * ev.norm().atan2(e.w.abs());
        self.q = quat::propagate(&self.q, &(ev * (self.gain * trust * sign)), dt); // (101), (105)
        if innovation < self.bias_freeze_rad
            && trust >= 1.0
            && rate.norm() < self.bias_freeze_rate_rad_s
        {
            self.bias -= ev * (self.bias_gain * dt * sign); // (102)
            let n = self.bias.norm();
            if n > self.bias_limit {
                self.bias *= self.bias_limit / n;
            }
        }
        innovation
    }
}
