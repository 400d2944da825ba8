//! The accelerometer's offsets and scales from six sides, as PX4's six-side calibration: the
//! vehicle is held still on each side in any order; a side held still for [`STILL_S`] is
//! recognised from the specific force ([`Side::of`]) and measured for [`MEASURE_S`] (motion — the
//! low-passed specific force more than [`JUMP_M_S2`] from the side's mean so far, or its spread
//! past the still one — starts the side again; [`MAX_RESTARTS`] fail it). A side done is
//! recognised again only after the vehicle has moved. Each pair of
//! opposite sides gives an axis: with `a⁺` and `a⁻` the means of that axis on the two sides
//! (`+g` and `−g` true), the offset is `(a⁺ + a⁻) / 2` and the scale `2g / (a⁺ − a⁻)`.

use super::still::StillDetector;
use super::{
    ImuCalFailure, ImuCalKind, ImuCalResult, ImuCalState, ImuCalStatus, PoseRequest, Side,
};
use crate::GRAVITY_M_S2;
use nalgebra::Vector3;

/// Rest before a side is recognised (s): PX4's 1.3 s.
pub const STILL_S: f64 = 1.3;
/// How long a side is measured (s): PX4's 750 samples at 250 Hz.
pub const MEASURE_S: f64 = 3.0;
/// A sample this far from the side's mean so far is motion (m/s²): PX4's 0.5.
pub const JUMP_M_S2: f64 = 0.5;
pub use super::MAX_RESTARTS;
/// Longest wait for the next side (s).
pub const SIDE_TIMEOUT_S: f64 = 60.0;
/// Largest offset accepted (m/s²) and the scales accepted: the parameters' ranges.
pub const MAX_OFFSET_M_S2: f64 = 3.0;
/// Scales accepted.
pub const SCALE_RANGE: (f64, f64) = (0.8, 1.2);

/// One accelerometer calibration.
#[derive(Debug, Clone)]
pub struct AccelCalibrator {
    pub(super) status: ImuCalStatus,
    still: StillDetector,
    /// Each side's mean, once measured.
    means: [Option<Vector3<f64>>; 6],
    /// The side being measured: when it started, the sum and count so far.
    sum: Vector3<f64>,
    n: usize,
    measure_start_s: f64,
    /// A repeated side was said: wait for motion before recognising a side again.
    await_motion: bool,
    /// When the last side was done (or the calibration started).
    progress_s: Option<f64>,
}

impl AccelCalibrator {
    /// Calibration `run`.
    pub fn new(run: u32) -> Self {
        Self {
            status: ImuCalStatus::new(run, ImuCalKind::Accel),
            still: StillDetector::default(),
            means: [None; 6],
            sum: Vector3::zeros(),
            n: 0,
            measure_start_s: 0.0,
            await_motion: false,
            progress_s: None,
        }
    }

    /// The first side not yet done (the one a person is asked for).
    pub fn pose_request(&self) -> PoseRequest {
        match self.status.measuring {
            Some(s) => PoseRequest::Place(s),
            None => Side::ALL
                .into_iter()
                .find(|s| self.status.sides_done & s.bit() == 0)
                .map_or(PoseRequest::None, PoseRequest::Place),
        }
    }

    /// Takes one raw sample.
    pub fn step(&mut self, t_s: f64, accel: &Vector3<f64>) {
        if self.status.state != ImuCalState::Collecting {
            return;
        }
        self.still.update(t_s, accel);
        let since = *self.progress_s.get_or_insert(t_s);
        match self.status.measuring {
            Some(side) => self.measure(t_s, side, accel),
            None if t_s - since > SIDE_TIMEOUT_S => {
                self.status.state = ImuCalState::Failed(ImuCalFailure::TimedOut {
                    waited_s: SIDE_TIMEOUT_S,
                    for_what: "a pending side held still",
                });
            }
            None => self.recognise(t_s),
        }
    }

    fn recognise(&mut self, t_s: f64) {
        if self.await_motion {
            self.await_motion = self.still.still_for_s() > 0.0;
            return;
        }
        if self.still.still_for_s() < STILL_S {
            return;
        }
        let Some(side) = Side::of(&self.still.mean()) else {
            return;
        };
        if self.status.sides_done & side.bit() != 0 {
            self.status.repeated = (self.status.repeated.0 + 1, Some(side));
            self.await_motion = true;
            return;
        }
        self.status.measuring = Some(side);
        self.measure_start_s = t_s;
        self.sum = Vector3::zeros();
        self.n = 0;
    }

    fn measure(&mut self, t_s: f64, side: Side, accel: &Vector3<f64>) {
        let mean = match self.n {
            0 => self.still.mean(),
            n => self.sum / n as f64,
        };
        if self.still.left(&mean, JUMP_M_S2) {
            // Moved: this side again, once it is still.
            self.status.moved();
            self.status.measuring = None;
            return;
        }
        self.sum += accel;
        self.n += 1;
        if t_s - self.measure_start_s < MEASURE_S {
            return;
        }
        self.means[side as usize] = Some(self.sum / self.n as f64);
        self.status.sides_done |= side.bit();
        self.status.measuring = None;
        // Done: the next side only once it has been moved (not this one said again).
        self.await_motion = true;
        self.progress_s = Some(t_s);
        let done = self.status.sides_done.count_ones() as f64;
        self.status.percent = (100.0 * done / 6.0).round() as u8;
        if self.means.iter().all(Option::is_some) {
            self.status.state = solve(&self.means.map(|m| m.unwrap_or_else(Vector3::zeros)));
        }
    }
}

/// Offsets and scales from the six sides' means (in [`Side::ALL`]'s order).
fn solve(means: &[Vector3<f64>; 6]) -> ImuCalState {
    let mut offset = Vector3::zeros();
    let mut scale = Vector3::zeros();
    for axis in 0..3 {
        // Sides 2·axis (+g) and 2·axis + 1 (−g).
        let (plus, minus) = (means[2 * axis][axis], means[2 * axis + 1][axis]);
        offset[axis] = (plus + minus) / 2.0;
        scale[axis] = 2.0 * GRAVITY_M_S2 / (plus - minus);
    }
    if !(offset.iter().chain(scale.iter()).all(|x| x.is_finite()))
        || offset.amax() > MAX_OFFSET_M_S2
    {
        return ImuCalState::Failed(ImuCalFailure::OutOfRange("accelerometer offset"));
    }
    if scale
        .iter()
        .any(|s| !(SCALE_RANGE.0..=SCALE_RANGE.1).contains(s))
    {
        return ImuCalState::Failed(ImuCalFailure::OutOfRange("accelerometer scale"));
    }
    ImuCalState::Succeeded(ImuCalResult::Accel { offset, scale })
}
