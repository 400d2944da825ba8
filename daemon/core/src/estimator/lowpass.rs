//! A second-order Butterworth low-pass filter for vectors, with a time constant instead of a
//! cut-off and any sample interval.
//!
//! The cut-off is `f_c = √2 / (2π τ)`, so a step settles in about `τ` (the convention of VQF,
//! Laidig & Seel 2023). The coefficients come from the bilinear transform with pre-warping and are
//! recomputed only when the sample interval changes by more than 1 %. As VQF's filters do, it
//! starts with the running mean of its inputs for the first `τ` seconds and then fills the state
//! with that mean: no start-up transient from zero, and no dependence on one first sample (a
//! single accelerated or vibrating sample would otherwise stay in the output for seconds).

use nalgebra::Vector3;

/// Butterworth low-pass filter of order two over a 3-vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass {
    tau_s: f64,
    dt_s: f64,
    b: [f64; 3],
    a: [f64; 2],
    x: [Vector3<f64>; 2],
    y: [Vector3<f64>; 2],
    started: bool,
    /// While starting: the sum of the inputs, their count and the time they span (s).
    start: Option<(Vector3<f64>, f64, f64)>,
}

impl LowPass {
    /// A filter with time constant `tau_s` (s); `tau_s ≤ 0` passes the input through.
    pub fn new(tau_s: f64) -> Self {
        Self {
            tau_s,
            dt_s: f64::NAN,
            b: [1.0, 0.0, 0.0],
            a: [0.0, 0.0],
            x: [Vector3::zeros(); 2],
            y: [Vector3::zeros(); 2],
            started: false,
            start: None,
        }
    }

    /// The time constant (s).
    pub fn tau_s(&self) -> f64 {
        self.tau_s
    }

    /// The last output (zero before the first sample).
    pub fn value(&self) -> Vector3<f64> {
        self.y[0]
    }

    /// Whether a sample has been taken.
    pub fn started(&self) -> bool {
        self.started
    }

    /// Changes the time constant, keeping the state (the next sample uses the new coefficients).
    pub fn set_tau_s(&mut self, tau_s: f64) {
        self.tau_s = tau_s;
        self.dt_s = f64::NAN;
    }

    /// Sets the state to a steady `value` (no start: it filters from the next sample).
    pub fn reset_to(&mut self, value: Vector3<f64>) {
        self.x = [value; 2];
        self.y = [value; 2];
        self.started = true;
        self.start = None;
    }

    /// Forgets the state: the next sample starts it again (the running mean for `τ`).
    pub fn clear(&mut self) {
        self.started = false;
        self.start = None;
        self.y = [Vector3::zeros(); 2];
    }

    fn coefficients(&mut self, dt: f64) {
        if (dt - self.dt_s).abs() <= 0.01 * dt {
            return;
        }
        self.dt_s = dt;
        if self.tau_s <= 0.0 {
            self.b = [1.0, 0.0, 0.0];
            self.a = [0.0, 0.0];
            return;
        }
        let fc = std::f64::consts::SQRT_2 / (std::f64::consts::TAU * self.tau_s);
        // Pre-warped bilinear transform; the cut-off is kept below Nyquist.
        let k = (std::f64::consts::PI * (fc * dt).min(0.45)).tan();
        let norm = 1.0 / (1.0 + std::f64::consts::SQRT_2 * k + k * k);
        let b0 = k * k * norm;
        self.b = [b0, 2.0 * b0, b0];
        self.a = [
            2.0 * (k * k - 1.0) * norm,
            (1.0 - std::f64::consts::SQRT_2 * k + k * k) * norm,
        ];
    }

    /// Filters one sample taken `dt` seconds after the previous one.
    pub fn update(&mut self, x: &Vector3<f64>, dt: f64) -> Vector3<f64> {
        if !self.started {
            self.started = true;
            self.start = Some((Vector3::zeros(), 0.0, 0.0));
        }
        if let Some((sum, n, spanned_s)) = self.start.as_mut() {
            *sum += x;
            *n += 1.0;
            *spanned_s += dt;
            let (mean, done) = (*sum / *n, *spanned_s >= self.tau_s);
            if done {
                self.reset_to(mean);
            } else {
                self.y = [mean; 2];
            }
            return mean;
        }
        self.coefficients(dt);
        let y = x * self.b[0] + self.x[0] * self.b[1] + self.x[1] * self.b[2]
            - self.y[0] * self.a[0]
            - self.y[1] * self.a[1];
        self.x = [*x, self.x[0]];
        self.y = [y, self.y[0]];
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_a_constant_and_settles_a_step_in_about_tau() {
        let mut f = LowPass::new(1.0);
        let dt = 0.004;
        assert_eq!(f.update(&Vector3::x(), dt), Vector3::x());
        for _ in 0..1000 {
            f.update(&Vector3::x(), dt);
        }
        assert!((f.value() - Vector3::x()).norm() < 1e-9);
        // A step: about half-way at τ, and by 4τ within the Butterworth overshoot (4 %).
        let mut t = 0.0;
        let mut at_tau = 0.0;
        while t < 4.0 {
            let y = f.update(&Vector3::y(), dt);
            t += dt;
            if (t - 1.0).abs() < dt / 2.0 {
                at_tau = y.y;
            }
        }
        assert!((0.4..0.9).contains(&at_tau), "{at_tau}");
        assert!((f.value() - Vector3::y()).norm() < 0.05, "{}", f.value());
        // A new time constant keeps the state: a steady input stays where it is.
        let steady = f.value();
        f.set_tau_s(3.0);
        assert!((f.update(&steady, dt) - steady).norm() < 0.05);
    }

    /// For its first τ the output is the mean of the inputs so far, then the filter goes on
    /// from that mean: one odd first sample does not linger.
    #[test]
    fn starts_with_the_running_mean_for_a_time_constant() {
        let mut f = LowPass::new(1.0);
        let dt = 0.01;
        assert_eq!(f.update(&(Vector3::x() * 100.0), dt), Vector3::x() * 100.0);
        for k in 2..=99 {
            let y = f.update(&Vector3::x(), dt);
            assert!(
                (y.x - (100.0 + (k - 1) as f64) / k as f64).abs() < 1e-9,
                "{k}: {y}"
            );
        }
        // Past τ it filters from that mean (2), not from the first sample (100): by 4τ the odd
        // sample is gone.
        for _ in 0..300 {
            f.update(&Vector3::x(), dt);
        }
        assert!((f.value() - Vector3::x()).norm() < 0.05, "{}", f.value());
        // Cleared, it starts again; reset, it filters from a steady state at once.
        f.clear();
        assert_eq!(f.update(&Vector3::y(), dt), Vector3::y());
        f.reset_to(Vector3::zeros());
        assert!(f.update(&Vector3::y(), dt).norm() < 0.01);
    }

    #[test]
    fn attenuates_a_vibration_far_above_the_cut_off() {
        let mut f = LowPass::new(0.5);
        let dt = 1.0 / 286.0;
        let mut peak: f64 = 0.0;
        for i in 0..5000 {
            let t = i as f64 * dt;
            let y = f.update(
                &Vector3::new((2.0 * std::f64::consts::PI * 40.0 * t).sin(), 0.0, 0.0),
                dt,
            );
            if t > 2.0 {
                peak = peak.max(y.x.abs());
            }
        }
        assert!(peak < 1e-3, "{peak}");
    }
}
