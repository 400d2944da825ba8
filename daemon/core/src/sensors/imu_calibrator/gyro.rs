//! The gyro's offset: the raw rate averaged over [`DURATION_S`] at rest. As PX4's, a sample whose
//! recent median (of the last [`MEDIAN_OF`]) strays more than [`MOTION_RAD_S`] from the mean so
//! far is motion: the average starts again, at most [`MAX_RESTARTS`] times.

use super::{ImuCalFailure, ImuCalKind, ImuCalResult, ImuCalState, ImuCalStatus};
use nalgebra::Vector3;

/// How long the rate is averaged (s): PX4's 250 samples at 100 Hz.
pub const DURATION_S: f64 = 2.5;
/// Samples in the median that detects motion.
pub const MEDIAN_OF: usize = 9;
/// A median this far from the mean is motion (rad/s): PX4's 0.6°/s.
pub const MOTION_RAD_S: f64 = 0.6 * std::f64::consts::PI / 180.0;
pub use super::MAX_RESTARTS;
/// Largest offset accepted (rad/s): the parameters' range.
pub const MAX_OFFSET_RAD_S: f64 = 0.5;

/// One gyro calibration.
#[derive(Debug, Clone)]
pub struct GyroCalibrator {
    pub(super) status: ImuCalStatus,
    start_s: Option<f64>,
    sum: Vector3<f64>,
    n: usize,
    recent: [Vector3<f64>; MEDIAN_OF],
}

impl GyroCalibrator {
    /// Calibration `run`.
    pub fn new(run: u32) -> Self {
        Self {
            status: ImuCalStatus::new(run, ImuCalKind::Gyro),
            start_s: None,
            sum: Vector3::zeros(),
            n: 0,
            recent: [Vector3::zeros(); MEDIAN_OF],
        }
    }

    /// Takes one raw sample.
    pub fn step(&mut self, t_s: f64, _accel: &Vector3<f64>, gyro: &Vector3<f64>) {
        if self.status.state != ImuCalState::Collecting {
            return;
        }
        let start = *self.start_s.get_or_insert(t_s);
        self.recent[self.n % MEDIAN_OF] = *gyro;
        self.sum += gyro;
        self.n += 1;
        if self.n >= MEDIAN_OF {
            let mean = self.sum / self.n as f64;
            let strays =
                (0..3).any(|axis| (median(&self.recent, axis) - mean[axis]).abs() > MOTION_RAD_S);
            if strays {
                return self.restart();
            }
        }
        let elapsed = t_s - start;
        self.status.percent = (100.0 * elapsed / DURATION_S).clamp(0.0, 99.0) as u8;
        if elapsed >= DURATION_S {
            let offset = self.sum / self.n as f64;
            self.status.state = if !offset
                .iter()
                .all(|x| x.is_finite() && x.abs() <= MAX_OFFSET_RAD_S)
            {
                ImuCalState::Failed(ImuCalFailure::OutOfRange("gyro offset"))
            } else {
                self.status.percent = 100;
                ImuCalState::Succeeded(ImuCalResult::Gyro { offset })
            };
        }
    }

    fn restart(&mut self) {
        self.status.moved();
        self.start_s = None;
        self.sum = Vector3::zeros();
        self.n = 0;
        self.status.percent = 0;
    }
}

/// The median of one axis of the samples.
fn median(samples: &[Vector3<f64>; MEDIAN_OF], axis: usize) -> f64 {
    let mut v = samples.map(|s| s[axis]);
    v.sort_by(f64::total_cmp);
    v[MEDIAN_OF / 2]
}
