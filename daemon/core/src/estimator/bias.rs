//! Gyro bias of the tilt/heading filter: a Kalman filter over the three components, fed at rest
//! by the mean rate and in motion by the filter's own tilt and heading corrections.
//!
//! The idea is VQF's in-motion bias estimation (Laidig & Seel 2023, §3.3): a bias error `e`
//! (body frame) makes the gyro frame drift at `R e` in the level frame (`R` = level from body);
//! the tilt correction undoes that drift after the accelerometer's low-pass `F`, so its rate is
//! `c ≈ −F[R e]`. With the estimate `b̂` known, `y = −c + F[R b̂] ≈ F[R] b`: a linear
//! measurement of the true bias whose matrix `F[R]` is `R` through the same low-pass. The
//! filters start when the tilt does (the drift starts then), so the model holds from the first
//! sample, not only in steady state.
//!
//! Beyond VQF, the heading correction measures the vertical row the same way. The corrector
//! takes a fraction `k` of the heading error at each accepted magnetometer sample, and the error
//! is the integral of the vertical drift, so the model is the integral `G = ∫ R_z dt` shrunk by
//! `1 − k` at every correction (and not at a rejected sample: a gap in the corrections is
//! modelled exactly). VQF leaves the vertical bias to a slow forgetting instead.
//!
//! The process noise is set by a time constant: with a direct measurement every sample, the
//! steady filter tracks a change of bias with time constant `tau_motion_s` in motion and
//! `tau_rest_s` at rest.

use super::lowpass::LowPass;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// Measurement noise density of a correction rate in motion (rad/s·√s). Only its ratio to the
/// other noises matters for the gains; with it, the steady uncertainty is `σ / √τ`.
const SIGMA_MOTION: f64 = 0.0055;
/// Noise of one magnetic heading (rad).
const SIGMA_HEADING: f64 = 0.05;
const HEADING_NOISE_RATIO: f64 = 1.0;
/// Initial standard deviation of the bias (rad/s): a MEMS gyro's turn-on bias, about 1°/s.
const SIGMA_INITIAL: f64 = 0.0175;
/// The smallest standard deviation a fit of a start in motion is taken with (rad/s): 0.2°/s.
const FIT_SIGMA_FLOOR: f64 = 0.2 * std::f64::consts::PI / 180.0;

/// Settings of the bias filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasSettings {
    /// Time constant at rest (s).
    pub tau_rest_s: f64,
    /// Time constant in motion (s); 0 switches learning in motion off.
    pub tau_motion_s: f64,
    /// Largest bias estimate (rad/s); a correction faster than this is not a bias.
    pub limit_rad_s: f64,
    /// Time constant of the tilt correction's low-pass (s).
    pub tau_acc_s: f64,
}

/// The bias filter.
#[derive(Debug, Clone)]
pub struct BiasEstimator {
    settings: BiasSettings,
    bias: Vector3<f64>,
    p: Matrix3<f64>,
    /// F[R], rows x and y; F[R b̂] in x and y.
    r_x: LowPass,
    r_y: LowPass,
    r_bias: LowPass,
    /// G = ∫ R_z dt since the last heading correction, shrunk by each; the same for R_z b̂.
    heading_g: Vector3<f64>,
    heading_g_bias: f64,
    heading_live: bool,
}

impl BiasEstimator {
    /// A filter with a zero estimate and the initial uncertainty.
    pub fn new(settings: BiasSettings) -> Self {
        let mut b = Self {
            settings,
            bias: Vector3::zeros(),
            p: Matrix3::from_diagonal_element(SIGMA_INITIAL * SIGMA_INITIAL),
            r_x: LowPass::new(settings.tau_acc_s),
            r_y: LowPass::new(settings.tau_acc_s),
            r_bias: LowPass::new(settings.tau_acc_s),
            heading_g: Vector3::zeros(),
            heading_g_bias: 0.0,
            heading_live: false,
        };
        b.restart_tilt();
        b
    }

    /// Changes the settings, keeping the estimate, its uncertainty and the drift model.
    pub fn set_settings(&mut self, settings: BiasSettings) {
        self.settings = settings;
        for f in [&mut self.r_x, &mut self.r_y, &mut self.r_bias] {
            f.set_tau_s(settings.tau_acc_s);
        }
    }

    /// The estimate (rad/s).
    pub fn bias(&self) -> Vector3<f64> {
        self.bias
    }

    /// Sets the estimate, keeping the uncertainty.
    pub fn set_bias(&mut self, bias: Vector3<f64>) {
        self.bias = bias;
    }

    /// The standard deviation of the estimate about the level frame's vertical (rad/s), given
    /// `level_from_body`.
    pub fn vertical_sigma(&self, level_from_body: &Rotation3<f64>) -> f64 {
        let r_z = level_from_body.matrix().row(2).transpose();
        r_z.dot(&(self.p * r_z)).max(0.0).sqrt()
    }

    /// The largest standard deviation of the estimate (rad/s).
    pub fn sigma(&self) -> f64 {
        self.p.diagonal().max().sqrt()
    }

    /// The tilt starts again (its low-pass cleared): so does its drift model, with the same
    /// start (the running mean for a time constant), so `F` is one operator for both.
    pub fn restart_tilt(&mut self) {
        for f in [&mut self.r_x, &mut self.r_y, &mut self.r_bias] {
            f.clear();
        }
        self.heading_live = false;
    }

    /// The tilt starts again from a steady state (at rest, `level_from_body` holding): so does
    /// its drift model.
    pub fn restart_tilt_at(&mut self, level_from_body: &Rotation3<f64>) {
        let r = level_from_body.matrix();
        self.r_x.reset_to(r.row(0).transpose());
        self.r_y.reset_to(r.row(1).transpose());
        self.r_bias.reset_to(r * self.bias);
        self.heading_live = false;
    }

    /// The time constant the process noise is set by (s).
    fn tracking_tau_s(&self) -> f64 {
        let s = self.settings;
        if s.tau_motion_s > 0.0 {
            s.tau_motion_s
        } else {
            s.tau_rest_s.max(1e-3)
        }
    }

    /// Process noise: `dt` seconds pass.
    pub fn predict(&mut self, dt: f64) {
        // V = σ² dt / τ²: with W = σ²/dt the steady gain is dt/τ.
        let v = SIGMA_MOTION * SIGMA_MOTION * dt / self.tracking_tau_s().powi(2);
        let cap = SIGMA_INITIAL * SIGMA_INITIAL;
        for i in 0..3 {
            if self.p[(i, i)] < cap {
                self.p[(i, i)] += v;
            }
        }
    }

    /// Noise density of the mean rate at rest (rad/s·√s): the rest time constant relative to the
    /// motion's.
    fn rest_sigma(&self) -> f64 {
        SIGMA_MOTION * self.settings.tau_rest_s / self.tracking_tau_s()
    }

    /// The first rest: the mean rate over `duration_s` of stillness is the bias, with the
    /// uncertainty of that many seconds of rest measurements.
    pub fn take_rest_mean(&mut self, mean_rate: &Vector3<f64>, duration_s: f64) {
        let n = mean_rate.norm();
        self.bias = if n > self.settings.limit_rad_s {
            mean_rate * (self.settings.limit_rad_s / n)
        } else {
            *mean_rate
        };
        let sigma = self.rest_sigma();
        self.p = Matrix3::from_diagonal_element(sigma * sigma / duration_s.max(1e-3));
    }

    /// A start in motion fitted the bias (`motion_start.rs`): it is the estimate, with the fit's
    /// covariance (no tighter than [`FIT_SIGMA_FLOOR`]: the fit takes the vehicle's
    /// accelerations for white noise, which they are not).
    pub fn take_fit(&mut self, bias: &Vector3<f64>, covariance: &Matrix3<f64>) {
        let n = bias.norm();
        self.bias = if n > self.settings.limit_rad_s {
            bias * (self.settings.limit_rad_s / n)
        } else {
            *bias
        };
        // Each principal direction between the floor and the initial uncertainty: a direction
        // the fit could not see (about the field, in a hover) stays as wide as it started.
        let eig = ((covariance + covariance.transpose()) * 0.5).symmetric_eigen();
        let clipped = eig.eigenvalues.map(|v| {
            v.clamp(
                FIT_SIGMA_FLOOR * FIT_SIGMA_FLOOR,
                SIGMA_INITIAL * SIGMA_INITIAL,
            )
        });
        self.p = eig.eigenvectors * Matrix3::from_diagonal(&clipped) * eig.eigenvectors.transpose();
    }

    /// At rest: the mean rate measures the bias directly.
    pub fn at_rest(&mut self, mean_rate: &Vector3<f64>, dt: f64) {
        let sigma = self.rest_sigma();
        let w = sigma * sigma / dt;
        for (i, h) in [Vector3::x(), Vector3::y(), Vector3::z()]
            .iter()
            .enumerate()
        {
            self.measure(h, mean_rate[i], w);
        }
    }

    /// One tilt step: `level_from_body` after the step and the tilt correction made in it (rad,
    /// level frame), if any. Measures the bias when `learn` (in motion, not too fast).
    pub fn tilt(
        &mut self,
        level_from_body: &Rotation3<f64>,
        correction: Option<&Vector3<f64>>,
        learn: bool,
        dt: f64,
    ) {
        let r = level_from_body.matrix();
        let rb = r * self.bias;
        let f_rx = self.r_x.update(&r.row(0).transpose(), dt);
        let f_ry = self.r_y.update(&r.row(1).transpose(), dt);
        let f_rb = self.r_bias.update(&rb, dt);
        // The heading model integrates the vertical drift at every step.
        self.heading_g += r.row(2).transpose() * dt;
        self.heading_g_bias += rb.z * dt;
        let (Some(c), true) = (correction, learn && self.settings.tau_motion_s > 0.0) else {
            return;
        };
        let rate = c / dt;
        if rate.norm() > self.settings.limit_rad_s {
            return; // A correction faster than any bias: a convergence or a disturbance.
        }
        let w = SIGMA_MOTION * SIGMA_MOTION / dt;
        self.measure(&f_rx, -rate.x + f_rb.x, w);
        self.measure(&f_ry, -rate.y + f_rb.y, w);
    }

    /// A heading correction: `step` (rad, about the level frame's vertical) with gain `k`, `dt`
    /// seconds after the previous magnetometer sample. The first one (the heading taken as
    /// measured) starts the model; later ones measure the bias when `learn`.
    pub fn heading(&mut self, step: f64, k: f64, learn: bool, dt: f64) {
        if !self.heading_live {
            // The error is about zero now: the model starts here.
            self.heading_live = true;
            self.heading_g = Vector3::zeros();
            self.heading_g_bias = 0.0;
            return;
        }
        // The error is the integrated drift less what was corrected: it shrinks by 1 − k.
        let (h, h_bias) = (self.heading_g * k, self.heading_g_bias * k);
        self.heading_g *= 1.0 - k;
        self.heading_g_bias *= 1.0 - k;
        if !learn || self.settings.tau_motion_s <= 0.0 || dt <= 0.0 {
            return;
        }
        let rate = step / dt;
        if rate.abs() > self.settings.limit_rad_s {
            return;
        }
        // The magnetometer's noise enters through k: the running mean of the start (k = 1/n)
        // is noisy, the steady correction (k = dt/τ) is not.
        let w = HEADING_NOISE_RATIO * SIGMA_MOTION * SIGMA_MOTION / dt
            + (k * SIGMA_HEADING / dt).powi(2);
        self.measure(&(h / dt), -rate + h_bias / dt, w);
    }

    /// A scalar Kalman update: `y = h·b` with noise variance `w`.
    fn measure(&mut self, h: &Vector3<f64>, y: f64, w: f64) {
        let ph = self.p * h;
        let s = h.dot(&ph) + w;
        if s.is_nan() || s <= 0.0 {
            return;
        }
        let k = ph / s;
        self.bias += k * (y - h.dot(&self.bias));
        self.p -= k * ph.transpose();
        self.p = (self.p + self.p.transpose()) * 0.5;
        let n = self.bias.norm();
        if n > self.settings.limit_rad_s {
            self.bias *= self.settings.limit_rad_s / n;
        }
    }
}
