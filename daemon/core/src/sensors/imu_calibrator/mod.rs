//! Onboard IMU calibrations (`MAV_CMD_PREFLIGHT_CALIBRATION`), as PX4 runs them:
//! - **gyro** ([`gyro`]): the rate averaged at rest for 2.5 s is the offset; motion restarts it.
//! - **accelerometer** ([`accel`]): the vehicle held still on each of its six sides in any order;
//!   each pair of opposite sides gives an axis' offset and scale.
//! - **level horizon** ([`level`]): with the vehicle standing level, the calibrated specific
//!   force's tilt is the board's mounting angles.
//!
//! Each works on the raw readings (before [`crate::sensors::imu_correction`]), reports a small
//! status after every step — what the ground station's `[cal]` texts are made from — and says
//! what it needs of the person holding the vehicle ([`PoseRequest`]: a simulator can play that
//! person). Time is the sensor frames'; nothing allocates.

pub mod accel;
pub mod gyro;
pub mod level;
pub mod still;
#[cfg(test)]
mod tests;

use crate::sensors::imu_correction::ImuCalParams;
use nalgebra::Vector3;

/// Which calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImuCalKind {
    /// The gyro's offset.
    Gyro,
    /// The accelerometer's offsets and scales, six sides.
    Accel,
    /// The board's mounting angles (level horizon).
    Level,
}

impl ImuCalKind {
    /// Its name in PX4's `[cal]` texts.
    pub fn name(self) -> &'static str {
        match self {
            Self::Gyro => "gyro",
            Self::Accel => "accel",
            Self::Level => "level",
        }
    }
}

/// A side of the vehicle, named as PX4 names the one facing the ground; numbered in PX4's
/// order (its index in the calibration's sides).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Side {
    /// Tail down (nose up): the accelerometer reads +g on x.
    Back = 0,
    /// Nose down: −g on x.
    Front = 1,
    /// On its left side: +g on y.
    Left = 2,
    /// On its right side: −g on y.
    Right = 3,
    /// Upside down: +g on z.
    Up = 4,
    /// Upright: −g on z.
    Down = 5,
}

impl Side {
    /// All six in PX4's order.
    pub const ALL: [Side; 6] = [
        Side::Back,
        Side::Front,
        Side::Left,
        Side::Right,
        Side::Up,
        Side::Down,
    ];

    /// PX4's word for it.
    pub fn name(self) -> &'static str {
        match self {
            Side::Back => "back",
            Side::Front => "front",
            Side::Left => "left",
            Side::Right => "right",
            Side::Up => "up",
            Side::Down => "down",
        }
    }

    /// Its bit in a set of sides.
    pub fn bit(self) -> u8 {
        1 << self as u8
    }

    /// The axis (0 x, 1 y, 2 z) that reads ±g on this side, and the sign.
    pub fn axis(self) -> (usize, f64) {
        match self {
            Side::Back => (0, 1.0),
            Side::Front => (0, -1.0),
            Side::Left => (1, 1.0),
            Side::Right => (1, -1.0),
            Side::Up => (2, 1.0),
            Side::Down => (2, -1.0),
        }
    }

    /// The side a specific force at rest shows: one axis within 5 m/s² of ±g and the others
    /// within 5 m/s² of 0 (PX4's `accel_err_thr`); `None` in between.
    pub fn of(accel: &Vector3<f64>) -> Option<Side> {
        const TOLERANCE_M_S2: f64 = 5.0;
        Side::ALL.into_iter().find(|s| {
            let (axis, sign) = s.axis();
            (0..3).all(|i| {
                let expected = if i == axis {
                    sign * crate::GRAVITY_M_S2
                } else {
                    0.0
                };
                (accel[i] - expected).abs() < TOLERANCE_M_S2
            })
        })
    }
}

/// What a calibration needs of the person holding the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PoseRequest {
    /// Nothing (hold still wherever it is, or let it stand).
    #[default]
    None,
    /// Put it down on this side and hold it still.
    Place(Side),
    /// Turn it through every orientation (the magnetometer).
    Tumble,
}

/// A calibration's result: what its parameters become.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImuCalResult {
    /// `CAL_GYRO0_{X,Y,Z}OFF` (rad/s).
    Gyro {
        /// The offset.
        offset: Vector3<f64>,
    },
    /// `CAL_ACC0_{X,Y,Z}OFF` (m/s²) and `CAL_ACC0_{X,Y,Z}SCALE`.
    Accel {
        /// The offsets.
        offset: Vector3<f64>,
        /// The scales.
        scale: Vector3<f64>,
    },
    /// `SENS_BOARD_X_OFF`, `SENS_BOARD_Y_OFF` (deg).
    Level {
        /// The board's roll in the body (deg).
        roll_deg: f64,
        /// The board's pitch in the body (deg).
        pitch_deg: f64,
    },
}

/// Why a calibration failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImuCalFailure {
    /// The vehicle kept moving: restarted this many times.
    Motion(u16),
    /// Waited this long for what it needs.
    TimedOut {
        /// How long (s).
        waited_s: f64,
        /// What did not come.
        for_what: &'static str,
    },
    /// The sensor frames stopped.
    NoData,
    /// The result is outside its parameters' range: which.
    OutOfRange(&'static str),
}

impl std::fmt::Display for ImuCalFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Motion(n) => write!(f, "motion during calibration ({n} restarts), hold it still"),
            Self::TimedOut { waited_s, for_what } => {
                write!(f, "timeout: no {for_what} within {waited_s:.0} s")
            }
            Self::NoData => write!(f, "no IMU data"),
            Self::OutOfRange(what) => write!(f, "{what} out of range"),
        }
    }
}

/// Where a calibration is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImuCalState {
    /// Collecting.
    Collecting,
    /// Done: the result.
    Succeeded(ImuCalResult),
    /// Failed, and why.
    Failed(ImuCalFailure),
    /// Cancelled by the operator.
    Cancelled,
}

/// What a calibration reports after each step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuCalStatus {
    /// Which calibration (counted from 1, shared with the magnetometer's): a new one from the
    /// last.
    pub run: u32,
    /// Which kind.
    pub kind: ImuCalKind,
    /// Where it is.
    pub state: ImuCalState,
    /// Progress, 0–100.
    pub percent: u8,
    /// Times motion restarted a measurement.
    pub restarts: u16,
    /// The accelerometer's sides done (bits of [`Side::bit`]).
    pub sides_done: u8,
    /// The side being measured.
    pub measuring: Option<Side>,
    /// A side held still that was already done, and how many times that happened.
    pub repeated: (u16, Option<Side>),
}

/// Restarts for motion before a calibration fails (PX4's gyro calibration's 20).
pub const MAX_RESTARTS: u16 = 20;

impl ImuCalStatus {
    /// Motion restarted the measurement: counted, and after [`MAX_RESTARTS`] the calibration
    /// fails.
    fn moved(&mut self) {
        self.restarts += 1;
        if self.restarts > MAX_RESTARTS {
            self.state = ImuCalState::Failed(ImuCalFailure::Motion(self.restarts));
        }
    }

    /// Calibration `run` of `kind`, collecting, nothing done yet.
    pub fn new(run: u32, kind: ImuCalKind) -> Self {
        Self {
            run,
            kind,
            state: ImuCalState::Collecting,
            percent: 0,
            restarts: 0,
            sides_done: 0,
            measuring: None,
            repeated: (0, None),
        }
    }
}

/// A calibration under way (or ended).
#[derive(Debug, Clone)]
pub enum ImuCalibrator {
    /// The gyro's.
    Gyro(gyro::GyroCalibrator),
    /// The accelerometer's.
    Accel(accel::AccelCalibrator),
    /// The level horizon's.
    Level(level::LevelCalibrator),
}

impl ImuCalibrator {
    /// Starts calibration `run` of `kind`; the level horizon needs the accelerometer's current
    /// calibration from `params`.
    pub fn new(kind: ImuCalKind, run: u32, params: &ImuCalParams) -> Self {
        match kind {
            ImuCalKind::Gyro => Self::Gyro(gyro::GyroCalibrator::new(run)),
            ImuCalKind::Accel => Self::Accel(accel::AccelCalibrator::new(run)),
            ImuCalKind::Level => Self::Level(level::LevelCalibrator::new(run, params)),
        }
    }

    /// Takes one raw sample (`accel` m/s², `gyro` rad/s) at `t_s`; a non-finite one is not
    /// taken.
    pub fn step(&mut self, t_s: f64, accel: &Vector3<f64>, gyro: &Vector3<f64>) {
        let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        if !(t_s.is_finite() && finite(accel) && finite(gyro)) {
            return;
        }
        match self {
            Self::Gyro(c) => c.step(t_s, accel, gyro),
            Self::Accel(c) => c.step(t_s, accel),
            Self::Level(c) => c.step(t_s, accel),
        }
    }

    /// Where it is.
    pub fn status(&self) -> ImuCalStatus {
        match self {
            Self::Gyro(c) => c.status,
            Self::Accel(c) => c.status,
            Self::Level(c) => c.status,
        }
    }

    fn status_mut(&mut self) -> &mut ImuCalStatus {
        match self {
            Self::Gyro(c) => &mut c.status,
            Self::Accel(c) => &mut c.status,
            Self::Level(c) => &mut c.status,
        }
    }

    /// Still collecting.
    pub fn collecting(&self) -> bool {
        self.status().state == ImuCalState::Collecting
    }

    /// Cancels it if it is still collecting.
    pub fn cancel(&mut self) {
        if self.collecting() {
            self.status_mut().state = ImuCalState::Cancelled;
        }
    }

    /// Ends it, failed, if it is still collecting: the sensor frames have stopped. Whether it
    /// was.
    pub fn sensors_stopped(&mut self) -> bool {
        let collecting = self.collecting();
        if collecting {
            self.status_mut().state = ImuCalState::Failed(ImuCalFailure::NoData);
        }
        collecting
    }

    /// What it needs of the person holding the vehicle.
    pub fn pose_request(&self) -> PoseRequest {
        if !self.collecting() {
            return PoseRequest::None;
        }
        match self {
            Self::Gyro(_) => PoseRequest::None,
            Self::Accel(c) => c.pose_request(),
            Self::Level(_) => PoseRequest::Place(Side::Down),
        }
    }
}
