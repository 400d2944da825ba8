//! What a run leaves behind, observed from outside the autopilot's step: the flight-data CSV,
//! the score against a simulator's truth, the telemetry log's files, the parameter store and
//! the signing key's file with what signing remembers across restarts.

mod fixed;
pub mod flight_csv;
pub mod flight_ulog;
pub mod log_budget;
pub mod log_files;
pub mod param_file;
pub mod score;
pub mod signing_file;
pub mod ulog;
mod ulog_topics;

use anyhow::{Context, Result};
use flight_core::autopilot::{AutopilotOutput, StepKind, VehicleState};
use flight_core::sample::SensorSample;
use flight_csv::FlightCsv;
use flight_ulog::FlightUlog;
use gcs::telemetry::LogFault;
use hil::TruthReport;
use score::FlightScore;
use std::time::Duration;

/// The records one vehicle's steps feed: its score, its flight-data CSV and ULog flight log,
/// the simulator's last truth.
pub struct FlightRecords {
    /// The take-off altitude the score measures the hover against (m).
    takeoff_m: f64,
    score: FlightScore,
    csv: Option<FlightCsv>,
    csv_error: Option<std::io::Error>,
    ulog: Option<FlightUlog>,
    ulog_error: Option<std::io::Error>,
    /// How late the control loop woke for the frames it is stepping (deadline pacing only).
    loop_late: Option<Duration>,
    last_truth: Option<TruthReport>,
    /// The first fault that stopped a log.
    fault: Option<LogFault>,
}

impl FlightRecords {
    /// Records of a flight to `takeoff_m` above home.
    pub fn new(takeoff_m: f64) -> Self {
        Self {
            takeoff_m,
            score: FlightScore::new(takeoff_m),
            csv: None,
            csv_error: None,
            ulog: None,
            ulog_error: None,
            loop_late: None,
            last_truth: None,
            fault: None,
        }
    }

    /// Writes a flight-data row per step to `csv` from now on.
    pub fn log_to(&mut self, csv: FlightCsv) {
        self.csv = Some(csv);
    }

    /// Writes the flown steps to the ULog flight log `ulog` from now on.
    pub fn log_ulog_to(&mut self, ulog: FlightUlog) {
        self.ulog = Some(ulog);
    }

    /// How late the control loop woke for the frames it steps next (for the flight-data CSV).
    pub fn set_loop_late(&mut self, late: Duration) {
        self.loop_late = Some(late);
    }

    /// The flight's figures against the simulator's truth, where it sends one.
    pub fn score(&self) -> &FlightScore {
        &self.score
    }

    /// Why the flight's logs stopped, if they did (the flight goes on).
    pub fn logs_stopped(&self) -> Option<LogFault> {
        self.fault
    }

    /// The simulator's last ground truth (SITL only).
    pub fn truth(&self) -> Option<TruthReport> {
        self.last_truth
    }

    /// Observes one step and the vehicle after it: the truth that came with its frame scores it, a flown
    /// step is a CSV row and logged. A repeated frame adds nothing; a frame flown blind is
    /// scored, with no estimate.
    pub fn observe(
        &mut self,
        step: &AutopilotOutput,
        sample: &SensorSample,
        vehicle: &VehicleState,
        truth: Option<TruthReport>,
    ) {
        let status = &vehicle.status;
        if step.restarted {
            // Another world: its flight is scored from the start.
            self.score = FlightScore::new(self.takeoff_m);
        }
        match step.kind {
            StepKind::Repeated => {}
            StepKind::Blind => {
                // The world is still watched: the blind descent's landing is scored too.
                if let Some(truth) = truth {
                    let _ = self.score.add(&truth, None, status, status.armed);
                    self.last_truth = Some(truth);
                }
            }
            StepKind::Flown => {
                // A flown step always has the flight core's output.
                let Some(est) = vehicle.estimate.as_ref() else {
                    return;
                };
                let true_pose = truth.and_then(|truth| {
                    self.last_truth = Some(truth);
                    let estimate = est.attitude.map(|a| a.q);
                    let p = self.score.add(&truth, estimate, status, step.armed)?;
                    Some((p, truth.q))
                });
                if let Some(csv) = self.csv.as_mut()
                    && let Err(e) = csv.record(status, step, est, sample, true_pose, self.loop_late)
                {
                    // A full disk must not stop the flight: stop logging, report at the end.
                    tracing::error!("flight-data CSV: {e}; logging stopped");
                    self.csv = None;
                    self.fault.get_or_insert(LogFault::of(&e));
                    self.csv_error = Some(e);
                }
                if let Some(ulog) = self.ulog.as_mut()
                    && let Err(e) = ulog.record(step, est, sample, vehicle)
                {
                    tracing::error!("ULog flight log: {e}; logging stopped");
                    self.ulog = None;
                    self.fault.get_or_insert(LogFault::of(&e));
                    self.ulog_error = Some(e);
                }
            }
        }
    }

    /// Writes the rest of the flight-data CSV and the flight log, reporting the first write
    /// error of the flight.
    pub fn finish(&mut self) -> Result<()> {
        let ulog = match (self.ulog_error.take(), self.ulog.as_mut()) {
            (Some(e), _) => Err(e),
            (None, Some(ulog)) => ulog.finish(),
            (None, None) => Ok(()),
        };
        if let Some(e) = self.csv_error.take() {
            return Err(e).context("writing the flight-data CSV");
        }
        if let Some(csv) = self.csv.as_mut() {
            csv.finish().context("writing the flight-data CSV")?;
        }
        ulog.context("writing the ULog flight log")
    }
}
