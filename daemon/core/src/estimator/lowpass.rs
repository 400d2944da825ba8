//! A second-order Butterworth low-pass filter for vectors, with a time constant instead of a
//! cut-off and any sample interval.
//!
//! The cut-off is `f_c = √2 / (2π τ)`, so a step settles in about `τ` (the convention of VQF,
//! Laidig & Seel 2023). The coefficients come from the bilinear transform with pre-warping and are
//! recomputed only when the sample interval changes by more than 1 %. The first sample fills the
//! state (no start-up transient from zero).

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

    /// Sets the state to a steady `value`.
    pub fn reset_to(&mut self, value: Vector3<f64>) {
        self.x = [value; 2];
        self.y = [value; 2];
        self.started = true;
    }

    /// Forgets the state: the next sample starts it again.
    pub fn clear(&mut self) {
        self.started = false;
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
            self.reset_to(*x);
            return *x;
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
