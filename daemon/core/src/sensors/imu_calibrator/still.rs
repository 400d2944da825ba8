//! Is the vehicle held still? PX4's test for a calibration's rest: the accelerometer's mean and
//! spread per axis, each a first-order low-pass with a 0.5 s time constant; still when every
//! axis spreads less than 0.25 m/s² (RMS), moving when one spreads more than twice that. A
//! non-finite reading is not taken.

use nalgebra::Vector3;

/// Time constant of the mean and the spread (s).
const TAU_S: f64 = 0.5;
/// Spread below which an axis is still (m/s², RMS).
pub const STILL_RMS_M_S2: f64 = 0.25;

/// The accelerometer's low-passed mean and spread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StillDetector {
    mean: Vector3<f64>,
    var: Vector3<f64>,
    last_t_s: Option<f64>,
    still_since_s: Option<f64>,
}

impl Default for StillDetector {
    fn default() -> Self {
        Self {
            mean: Vector3::zeros(),
            // Start as moving: rest must be seen, not assumed.
            var: Vector3::repeat(1.0),
            last_t_s: None,
            still_since_s: None,
        }
    }
}

impl StillDetector {
    /// Takes an accelerometer sample at `t_s`.
    pub fn update(&mut self, t_s: f64, accel: &Vector3<f64>) {
        if !(t_s.is_finite() && accel.iter().all(|x| x.is_finite())) {
            return;
        }
        let Some(last) = self.last_t_s.replace(t_s) else {
            self.mean = *accel;
            return;
        };
        let k = ((t_s - last).max(0.0) / TAU_S).min(1.0);
        let d = accel - self.mean;
        self.mean += d * k;
        self.var += (d.component_mul(&d) - self.var) * k;
        let (still, moving) = (STILL_RMS_M_S2.powi(2), (2.0 * STILL_RMS_M_S2).powi(2));
        if self.var.max() < still {
            self.still_since_s.get_or_insert(t_s);
        } else if self.var.max() > moving {
            self.still_since_s = None;
        }
    }

    /// How long the vehicle has been still (s; 0 when moving).
    pub fn still_for_s(&self) -> f64 {
        match (self.still_since_s, self.last_t_s) {
            (Some(since), Some(now)) => now - since,
            _ => 0.0,
        }
    }

    /// Whether it moves now: the spread is past the still one's hysteresis.
    pub fn moving(&self) -> bool {
        self.still_since_s.is_none()
    }

    /// Whether the vehicle has moved while a mean `mean` was being taken: it moves now, or
    /// the low-passed specific force has left that mean by more than `jump` (m/s²).
    pub fn left(&self, mean: &Vector3<f64>, jump: f64) -> bool {
        self.moving() || (self.mean - mean).amax() > jump
    }

    /// The low-passed specific force (m/s²).
    pub fn mean(&self) -> Vector3<f64> {
        self.mean
    }
}
