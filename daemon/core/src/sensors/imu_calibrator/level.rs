//! The level horizon: with the vehicle standing level, the board's mounting angles. The
//! specific force, calibrated for offset and scale but still in the board's axes, is averaged
//! at rest over [`MEASURE_S`]; its tilt is the board's roll and pitch in the body:
//! `roll = atan2(−a_y, −a_z)`, `pitch = atan2(a_x, √(a_y² + a_z²))` (exact for a board turned by
//! roll then pitch, as `SENS_BOARD_X_OFF`/`Y_OFF` turn it). PX4 averages its estimator's
//! attitude instead; the accelerometer is what that attitude converges to, without waiting
//! for it. Motion (as for the accelerometer's sides) starts the average again;
//! [`super::MAX_RESTARTS`] fail it.

use super::accel::JUMP_M_S2;
use super::still::StillDetector;
use super::{ImuCalFailure, ImuCalKind, ImuCalResult, ImuCalState, ImuCalStatus};
use crate::sensors::imu_correction::ImuCalParams;
use nalgebra::Vector3;

/// Rest before the average starts (s).
pub const STILL_S: f64 = 1.0;
/// How long the specific force is averaged (s).
pub const MEASURE_S: f64 = 2.0;
/// Longest wait for rest (s).
pub const TIMEOUT_S: f64 = 30.0;
/// Largest mounting angle accepted (deg): the parameters' range (PX4 refuses above 0.8 rad).
pub const MAX_ANGLE_DEG: f64 = 45.0;

/// One level-horizon calibration.
#[derive(Debug, Clone)]
pub struct LevelCalibrator {
    pub(super) status: ImuCalStatus,
    params: ImuCalParams,
    still: StillDetector,
    sum: Vector3<f64>,
    n: usize,
    start_s: Option<f64>,
    measure_start_s: Option<f64>,
}

impl LevelCalibrator {
    /// Calibration `run`, with the accelerometer's calibration in `params`.
    pub fn new(run: u32, params: &ImuCalParams) -> Self {
        Self {
            status: ImuCalStatus::new(run, ImuCalKind::Level),
            params: *params,
            still: StillDetector::default(),
            sum: Vector3::zeros(),
            n: 0,
            start_s: None,
            measure_start_s: None,
        }
    }

    /// Takes one raw sample.
    pub fn step(&mut self, t_s: f64, raw: &Vector3<f64>) {
        if self.status.state != ImuCalState::Collecting {
            return;
        }
        let accel = self.params.accel_in_board(raw);
        self.still.update(t_s, &accel);
        let start = *self.start_s.get_or_insert(t_s);
        let Some(measure_start) = self.measure_start_s else {
            if self.still.still_for_s() >= STILL_S {
                self.measure_start_s = Some(t_s);
                self.sum = Vector3::zeros();
                self.n = 0;
            } else if t_s - start > TIMEOUT_S {
                self.status.state = ImuCalState::Failed(ImuCalFailure::TimedOut {
                    waited_s: TIMEOUT_S,
                    for_what: "the vehicle held still",
                });
            }
            return;
        };
        let mean = match self.n {
            0 => self.still.mean(),
            n => self.sum / n as f64,
        };
        if self.still.left(&mean, JUMP_M_S2) {
            self.status.moved();
            self.measure_start_s = None;
            self.status.percent = 0;
            return;
        }
        self.sum += accel;
        self.n += 1;
        let elapsed = t_s - measure_start;
        self.status.percent = (100.0 * elapsed / MEASURE_S).clamp(0.0, 99.0) as u8;
        if elapsed >= MEASURE_S {
            let a = self.sum / self.n as f64;
            let roll_deg = (-a.y).atan2(-a.z).to_degrees();
            let pitch_deg = a.x.atan2(a.y.hypot(a.z)).to_degrees();
            self.status.state =
                if !(roll_deg.abs() <= MAX_ANGLE_DEG && pitch_deg.abs() <= MAX_ANGLE_DEG) {
                    ImuCalState::Failed(ImuCalFailure::OutOfRange(
                        "level angle (is it standing level?)",
                    ))
                } else {
                    self.status.percent = 100;
                    ImuCalState::Succeeded(ImuCalResult::Level {
                        roll_deg,
                        pitch_deg,
                    })
                };
        }
    }
}
