//! What a flight did, printed as one `key=value` line at the end of the run.

use crate::records::score::FlightScore;
use gcs::telemetry::LoopSummary;

/// What happened, printed as one `key=value` line at the end.
#[derive(Debug, Default)]
pub struct FlightReport {
    pub(super) source: String,
    pub(super) sim_time_s: f64,
    pub(super) wall_time_s: f64,
    pub(super) frames: u64,
    pub(super) malformed: u64,
    pub(super) repeated: u64,
    pub(super) score: FlightScore,
    pub(super) disarmed: bool,
    pub(super) sensor_timeouts: u64,
    /// The deadline loop's rate and timing over the whole run.
    pub(super) deadline_loop: Option<(f64, LoopSummary)>,
    /// The sensor frames stopped while armed: the blind descent, a failsafe the frames' score
    /// cannot see (no frame comes while it flies).
    pub(super) blind_failsafe: bool,
    /// The flight's logs stopped before its end (a full disk, a directory gone): the flight
    /// went on; its logs end where the fault was.
    pub(super) logs_stopped: bool,
}

impl FlightReport {
    /// The vehicle ended its run on the ground, disarmed.
    pub fn landed(&self) -> bool {
        self.disarmed && self.score.on_ground()
    }

    /// The flight's figures against the simulator's truth.
    pub fn score(&self) -> &FlightScore {
        &self.score
    }

    /// Sensor time flown (s).
    pub fn sim_time_s(&self) -> f64 {
        self.sim_time_s
    }

    /// Times the sensor frames stopped (the watchdog fired).
    pub fn sensor_timeouts(&self) -> u64 {
        self.sensor_timeouts
    }

    /// A failsafe acted in the flight: one the commander showed on a frame, or the blind
    /// descent of frames that stopped while armed.
    pub fn failsafe(&self) -> bool {
        self.score.failsafe || self.blind_failsafe
    }

    /// Says the flight's logs stopped before its end.
    pub fn set_logs_stopped(&mut self) {
        self.logs_stopped = true;
    }
}

impl std::fmt::Display for FlightReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let opt = |x: Option<f64>| x.map_or("nan".to_owned(), |x| format!("{x:.3}"));
        write!(
            f,
            "autopilot summary: source={} sim_time_s={:.2} wall_time_s={:.2} realtime_factor={:.1} frames={} frames_per_s={:.0} malformed={} repeated={} sensor_timeouts={} max_alt_m={:.2} hover_alt_rms_m={} hover_drift_rms_m={} attitude_rms_deg={} touchdown_m_s={:.2} impact_m_s={:.2} max_tilt_deg={:.1} max_distance_m={:.2} failsafe={} landed={} disarmed={} logs={}",
            self.source,
            self.sim_time_s,
            self.wall_time_s,
            self.sim_time_s / self.wall_time_s.max(1e-9),
            self.frames,
            self.frames as f64 / self.wall_time_s.max(1e-9),
            self.malformed,
            self.repeated,
            self.sensor_timeouts,
            self.score.max_height_m,
            opt(self.score.hover_alt_rms_m()),
            opt(self.score.hover_drift_rms_m()),
            opt(self.score.attitude_rms_deg()),
            self.score.touchdown_m_s,
            self.score.impact_m_s,
            self.score.max_tilt_deg,
            self.score.max_distance_m,
            self.failsafe(),
            self.score.on_ground(),
            self.disarmed,
            if self.logs_stopped {
                "stopped"
            } else {
                "whole"
            }
        )?;
        match &self.deadline_loop {
            None => write!(f, " pacing=lockstep"),
            Some((hz, s)) => write!(
                f,
                " pacing=deadlines loop_hz={hz:.0} ticks={} jitter_p50_us={} jitter_p99_us={} jitter_max_us={} work_max_us={} overruns={}",
                s.ticks,
                s.jitter_p50_us,
                s.jitter_p99_us,
                s.jitter_max_us,
                s.work_max_us,
                s.overruns
            ),
        }
    }
}
