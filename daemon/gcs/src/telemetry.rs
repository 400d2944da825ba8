//! The vehicle as the ground station sees it: the control loop's latest [`Telemetry`].

use flight_core::commander::CommanderStatus;
use flight_core::control::Setpoint;
use flight_core::core::{SensorSample, StepOutput};
use flight_core::estimator::translation::GpsMeasurement;
use flight_core::sensors::battery::BatteryState;
use flight_core::sensors::imu_calibrator::ImuCalStatus;
use flight_core::sensors::mag_calibrator::MagCalStatus;

/// What the control loop publishes after every step, the latest value: what the streams say
/// and the commands are checked against (and the daemon's status line).
#[derive(Debug, Clone, Copy, Default)]
pub struct Telemetry {
    /// Time of the last sensor frame (s).
    pub t_s: f64,
    /// The commander's state.
    pub status: Option<CommanderStatus>,
    /// The last step's output.
    pub output: Option<StepOutput>,
    /// The last GPS solution.
    pub gps: Option<GpsMeasurement>,
    /// The last sensor sample stepped on.
    pub sample: Option<SensorSample>,
    /// The position set-point flown (armed only).
    pub setpoint: Option<Setpoint>,
    /// The simulator's ground truth (SITL only).
    pub truth: Option<hil::TruthReport>,
    /// The largest collective thrust (N).
    pub max_thrust_n: f64,
    /// Battery voltage (V).
    pub battery_v: f64,
    /// The battery estimate (voltage, current, charge left).
    pub battery: BatteryState,
    /// Sensor frames stepped.
    pub frames: u64,
    /// The deadline loop's timing over the last interval (none in lockstep).
    pub loop_stats: Option<LoopSummary>,
    /// The loop has ended.
    pub finished: bool,
    /// The sensor frames have stopped (the watchdog has fired; the vehicle is reacting).
    pub sensors_silent: bool,
    /// Times the sensor source started again from an earlier time (the vehicle with it).
    pub source_restarts: u32,
    /// The magnetometer calibration under way, or the last one.
    pub mag_cal: Option<MagCalStatus>,
    /// The gyro, accelerometer or level-horizon calibration under way, or the last one.
    pub imu_cal: Option<ImuCalStatus>,
}

/// The deadline loop's timing over an interval (a flight board in real time).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoopSummary {
    /// Ticks in the interval.
    pub ticks: u64,
    /// Median lateness of the wake-up after the deadline (µs).
    pub jitter_p50_us: u32,
    /// 99th percentile of the lateness (µs).
    pub jitter_p99_us: u32,
    /// Largest lateness (µs).
    pub jitter_max_us: u64,
    /// Longest tick's work (µs).
    pub work_max_us: u64,
    /// Deadlines missed because a tick's work (or its lateness) ran past them.
    pub overruns: u64,
}
