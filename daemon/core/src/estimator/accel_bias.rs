//! The accelerometer's bias in flight, from the GPS's velocity.
//!
//! A bias `b` (body frame) tilts the estimate by `b/g`: the tilt filter turns the biased specific
//! force to the vertical. In a hover at one heading nothing tells that tilt from a true one (the
//! bias rotates with the body, and so does the error); when the heading changes, the bias turns
//! in the level frame and the error it made does not follow at once, so the two come apart. EKF2
//! and EKF3 estimate it the same way, as states beside the attitude.
//!
//! Each GPS window (`gps_tilt.rs`, a second between two solutions) gives the level-frame
//! specific force two ways: from the GPS, `v = H⁻¹(Δv/T − g)`, and from the estimate,
//! `q_tilt · mean(R_g f)` (`R_g` the gyro frame from the body). With the estimate's error `ε` (a
//! small rotation in the level frame, heading included) and the bias,
//! `v − q_tilt·mean(R_g (f − b̂)) = −[v]× ε − q_tilt·mean(R_g)·(b − b̂)`, where `b̂` is the bias
//! already taken off the accelerometer: linear in `x = (ε, b)`. A Kalman filter over those six states
//! measures it once per window. Between windows `ε` moves by what the tilt and heading filters
//! corrected (known exactly: the estimate's own change) and by a little process noise. `ε` is
//! only a nuisance state here: the tilt filter corrects the tilt itself once the bias is off.
//!
//! What cannot be observed is not learned: at one heading the horizontal bias stays at its
//! prior, correlated with `ε`; only the vertical row (the specific force's length) measures
//! the body's `z` bias.

use super::gps_tilt::GpsWindow;
use crate::GRAVITY_M_S2;
use nalgebra::{SMatrix, SVector, UnitQuaternion, Vector3};

type Matrix3<T> = nalgebra::Matrix3<T>;
/// The state: the estimate's error ε, the accelerometer's bias, the gyro bias's residual.
type State = SVector<f64, 9>;
type Covariance = SMatrix<f64, 9, 9>;

/// Prior standard deviations: the estimate's tilt and heading error (rad), the bias (m/s²), the
/// gyro bias's residual (rad/s).
const SIGMA_TILT: f64 = 0.05;
const SIGMA_HEADING: f64 = 0.3;
const SIGMA_BIAS: f64 = 0.2;
const SIGMA_GYRO: f64 = 0.002;
/// Random walks: of the error (rad/√s), of the bias (m/s²/√s), of the gyro bias (rad/s/√s).
const WALK_ERROR: f64 = 0.001;
const WALK_BIAS: f64 = 0.001;
const WALK_GYRO: f64 = 1e-4;
/// Noise of a window's specific force (m/s², per axis): a 0.05 m/s GPS over a second (0.07)
/// and the rotors' vibration averaged over it; the innovations in a realistic-sensor flight
/// spread about this much.
const SIGMA_WINDOW: f64 = 0.1;
/// A window is taken this often (s): windows a second long that do not overlap.
const WINDOW_EVERY_S: f64 = 1.0;
/// A window whose innovation is beyond this (χ², 3 degrees of freedom, 99.9 %) is not fused.
const GATE_CHI2: f64 = 16.3;
/// A bias component is taken off once its standard deviation is below this (m/s²; 0.2°).
const LEARNED_SIGMA: f64 = 0.035;
/// The largest bias taken off (m/s²).
const LIMIT: f64 = 1.0;

/// What the filter keeps of the last window.
#[derive(Debug, Clone, Copy)]
struct Last {
    estimate: UnitQuaternion<f64>,
    t_s: f64,
    rotation_integral: Matrix3<f64>,
    gyro_bias: Vector3<f64>,
}

/// The filter.
#[derive(Debug, Clone)]
pub struct AccelBiasEstimator {
    x: State,
    p: Covariance,
    /// At the last window: the estimate (gyro frame → NED), to know how far the filters turned
    /// it since; the integral of the gyro frame's rotation from the body and the gyro bias
    /// taken off, to know how far an error of that bias turned it.
    last: Option<Last>,
    /// When the last window was taken (s, the windows' clock).
    last_window_s: f64,
    /// The bias taken off the accelerometer: [`Self::bias`], as the last window left it.
    applied: Vector3<f64>,
}

impl Default for AccelBiasEstimator {
    fn default() -> Self {
        let mut e = Self {
            x: State::zeros(),
            p: Covariance::zeros(),
            last: None,
            last_window_s: 0.0,
            applied: Vector3::zeros(),
        };
        e.forget_error();
        for i in 3..6 {
            e.p[(i, i)] = SIGMA_BIAS * SIGMA_BIAS;
        }
        e
    }
}

impl AccelBiasEstimator {
    /// The bias to take off the accelerometer (body frame, m/s²): the components learned
    /// ([`LEARNED_SIGMA`]); one the flight has not shown stays at zero, not at whatever share of
    /// the tilt's error its prior would give it. It changes only at a window.
    pub fn bias(&self) -> Vector3<f64> {
        self.applied
    }

    /// Whether a window is due at `t_s` (the windows' clock): one every [`WINDOW_EVERY_S`], so
    /// that they do not overlap.
    pub fn due(&self, t_s: f64) -> bool {
        t_s - self.last_window_s >= WINDOW_EVERY_S
    }

    /// The learned components of the estimate, limited.
    fn learned(&self) -> Vector3<f64> {
        let sigma = self.sigma();
        let b = Vector3::from_fn(|i, _| {
            if sigma[i] <= LEARNED_SIGMA {
                self.x[i + 3]
            } else {
                0.0
            }
        });
        let n = b.norm();
        if n > LIMIT { b * (LIMIT / n) } else { b }
    }

    /// The bias's standard deviation per body axis (m/s²).
    pub fn sigma(&self) -> Vector3<f64> {
        Vector3::new(self.p[(3, 3)], self.p[(4, 4)], self.p[(5, 5)]).map(f64::sqrt)
    }

    /// The estimate's error is unknown again (it was reset, or started again): it and the gyro
    /// bias's residual start from the prior, uncorrelated; the bias keeps what it learned.
    pub fn forget_error(&mut self) {
        for (i, s) in [(0, SIGMA_TILT), (1, SIGMA_TILT), (2, SIGMA_HEADING)]
            .into_iter()
            .chain((6..9).map(|i| (i, SIGMA_GYRO)))
        {
            self.x[i] = 0.0;
            for j in 0..9 {
                self.p[(i, j)] = 0.0;
                self.p[(j, i)] = 0.0;
            }
            self.p[(i, i)] = s * s;
        }
        self.last = None;
    }

    /// A GPS window, with the tilt `q_tilt` (gyro frame → level) and heading `heading` (level →
    /// NED) as they are now, the time and the integral of the gyro frame's rotation from the
    /// body so far (`GpsTiltCheck::rotation_integral`), and the gyro bias taken off now.
    pub fn update(
        &mut self,
        w: &GpsWindow,
        q_tilt: &UnitQuaternion<f64>,
        heading: &UnitQuaternion<f64>,
        (t_s, rotation_integral): (f64, &Matrix3<f64>),
        gyro_bias: &Vector3<f64>,
    ) {
        self.last_window_s = t_s;
        let applied = self.applied;
        let estimate = heading * q_tilt;
        if let Some(last) = self.last {
            // The error moves by what the filters turned the estimate since the last window,
            // and by the gyro bias's residual through the level frame: ε ← ε − D − Φ e.
            let turned =
                (heading.inverse() * (estimate * last.estimate.inverse()) * heading).scaled_axis();
            let phi =
                q_tilt.to_rotation_matrix().matrix() * (rotation_integral - last.rotation_integral);
            let mut f = Covariance::identity();
            f.fixed_view_mut::<3, 3>(0, 6).copy_from(&-phi);
            self.x = f * self.x;
            for i in 0..3 {
                self.x[i] -= turned[i];
                // What the gyro filter learned since is no longer a residual.
                self.x[i + 6] -= gyro_bias[i] - last.gyro_bias[i];
            }
            let dt = (t_s - last.t_s).max(0.0);
            self.p = f * self.p * f.transpose();
            for (i, walk) in [(0, WALK_ERROR), (3, WALK_BIAS), (6, WALK_GYRO)] {
                for k in i..i + 3 {
                    self.p[(k, k)] += walk * walk * dt;
                }
            }
        }
        self.last = Some(Last {
            estimate,
            t_s,
            rotation_integral: *rotation_integral,
            gyro_bias: *gyro_bias,
        });

        // v − q_tilt·mean(R_g f) − M b̂ = −[v]× ε − M b, M = q_tilt·mean(R_g).
        let v = heading.inverse() * (w.accel - Vector3::new(0.0, 0.0, GRAVITY_M_S2));
        let m: Matrix3<f64> = q_tilt.to_rotation_matrix().matrix() * w.rotation;
        let y = v - q_tilt * w.force - m * applied;
        let mut h = SMatrix::<f64, 3, 9>::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).copy_from(&-v.cross_matrix());
        h.fixed_view_mut::<3, 3>(0, 3).copy_from(&-m);
        let r = Matrix3::from_diagonal_element(SIGMA_WINDOW * SIGMA_WINDOW / w.duration_s);
        let innovation = y - h * self.x;
        let s = h * self.p * h.transpose() + r;
        let Some(s_inv) = s.try_inverse() else {
            return;
        };
        if (innovation.transpose() * s_inv * innovation)[0] > GATE_CHI2 {
            return;
        }
        let k = self.p * h.transpose() * s_inv;
        self.x += k * innovation;
        // Joseph form: the covariance stays symmetric and positive.
        let i_kh = Covariance::identity() - k * h;
        self.p = i_kh * self.p * i_kh.transpose() + k * r * k.transpose();
        self.applied = self.learned();
    }
}

#[cfg(test)]
#[path = "accel_bias_tests.rs"]
mod tests;
