//! The vehicle as the ground station sees it: the control loop's latest [`Telemetry`].

use flight_core::autopilot::VehicleState;
use flight_core::commander::CommanderStatus;
use flight_core::core::StepOutput;

/// What the control loop publishes after every step, the latest value: what the streams say
/// and the commands are checked against (and the daemon's status line).
#[derive(Debug, Clone, Copy, Default)]
pub struct Telemetry {
    /// The vehicle after its last step (none before the first).
    pub vehicle: Option<VehicleState>,
    /// The loop's and the sensor link's side.
    pub link: LinkState,
}

impl Telemetry {
    /// The commander's state (none before the first step).
    pub fn status(&self) -> Option<CommanderStatus> {
        self.vehicle.as_ref().map(|v| v.status)
    }

    /// The flight core's last output.
    pub fn estimate(&self) -> Option<StepOutput> {
        self.vehicle.as_ref().and_then(|v| v.estimate)
    }
}

/// The control loop's and its sensor link's side of the telemetry.
#[derive(Debug, Clone, Copy, Default)]
pub struct LinkState {
    /// Time of the last sensor frame (s).
    pub t_s: f64,
    /// The simulator's ground truth (SITL only).
    pub truth: Option<mavwire::TruthReport>,
    /// Sensor frames stepped.
    pub frames: u64,
    /// The deadline loop's timing over the last interval (none in lockstep).
    pub loop_stats: Option<LoopSummary>,
    /// The loop has ended.
    pub finished: bool,
    /// The sensor frames have stopped (the watchdog has fired; the vehicle is reacting).
    pub sensors_silent: bool,
    /// The flight's logs stopped, and why (the flight goes on).
    pub logs_stopped: Option<LogFault>,
}

/// Why a flight's logs stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFault {
    /// The disk is full.
    DiskFull,
    /// The log directory (or the file) is gone.
    DirectoryGone,
    /// Another write error.
    WriteFailed,
}

impl LogFault {
    /// Every fault, in the order of their `log_fault_t` values (the events metadata's).
    pub const ALL: [LogFault; 3] = [Self::DiskFull, Self::DirectoryGone, Self::WriteFailed];

    /// The fault of a write error.
    pub fn of(e: &std::io::Error) -> Self {
        match e.kind() {
            std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => Self::DiskFull,
            std::io::ErrorKind::NotFound => Self::DirectoryGone,
            _ => Self::WriteFailed,
        }
    }

    /// In words (what the ground station is told).
    pub fn describe(self) -> &'static str {
        match self {
            Self::DiskFull => "disk full",
            Self::DirectoryGone => "log directory gone",
            Self::WriteFailed => "write failed",
        }
    }

    /// Its name in the events metadata.
    pub fn name(self) -> &'static str {
        match self {
            Self::DiskFull => "disk_full",
            Self::DirectoryGone => "directory_gone",
            Self::WriteFailed => "write_failed",
        }
    }
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
