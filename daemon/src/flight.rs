//! The flight loop in lockstep: every sensor frame is a tick, its time the clock. Messages come
//! from a [`SensorLink`], the [`Vehicle`] steps on each `HIL_SENSOR`, the answer goes back.

use crate::link::SensorLink;
use crate::score::FlightScore;
use crate::vehicle::Vehicle;
use anyhow::{Context, Result, bail};
use flight_core::core::StepOutput;
use flight_core::sequence::Phase;
use hil::{Decoded, Encoder};
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::{Duration, Instant};

/// The estimator converges in a few seconds at rest; a sequence still waiting after this long
/// never will, and the flight stops with the reason instead of waiting forever.
const READY_TIMEOUT_S: f64 = 60.0;

/// Wall-clock time without any sensor frame before the loop says so.
const SILENCE_WARNING: Duration = Duration::from_secs(2);

/// What happened, printed as one `key=value` line at the end.
#[derive(Debug, Default)]
pub struct FlightReport {
    source: String,
    sim_time_s: f64,
    wall_time_s: f64,
    frames: u64,
    malformed: u64,
    repeated: u64,
    score: FlightScore,
    disarmed: bool,
}

impl std::fmt::Display for FlightReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let opt = |x: Option<f64>| x.map_or("nan".to_owned(), |x| format!("{x:.3}"));
        write!(
            f,
            "autopilot summary: source={} sim_time_s={:.2} wall_time_s={:.2} realtime_factor={:.1} frames={} frames_per_s={:.0} malformed={} repeated={} max_alt_m={:.2} hover_alt_rms_m={} hover_drift_rms_m={} attitude_rms_deg={} touchdown_m_s={:.2} landed={} disarmed={}",
            self.source,
            self.sim_time_s,
            self.wall_time_s,
            self.sim_time_s / self.wall_time_s.max(1e-9),
            self.frames,
            self.frames as f64 / self.wall_time_s.max(1e-9),
            self.malformed,
            self.repeated,
            self.score.max_height_m,
            opt(self.score.hover_alt_rms_m()),
            opt(self.score.hover_drift_rms_m()),
            opt(self.score.attitude_rms_deg()),
            self.score.touchdown_m_s,
            self.score.on_ground(),
            self.disarmed
        )
    }
}

/// Flies the vehicle's sequence over `link` until it has landed and disarmed. `interrupts`
/// counts Ctrl-C presses: the first lands, the second stops at once.
pub fn fly(
    link: &mut dyn SensorLink,
    vehicle: &mut Vehicle,
    system_id: u8,
    interrupts: &AtomicU8,
) -> Result<FlightReport> {
    let started = Instant::now();
    let mut report = FlightReport {
        source: link.describe(),
        ..FlightReport::default()
    };
    let mut encoder = Encoder::with_ids(system_id, 1);
    let mut decoded = Decoded::default();
    let mut answer = Vec::with_capacity(128);
    let tty = std::io::stdout().is_terminal();
    let mut next_status = Duration::ZERO;
    let mut last_frame = Instant::now();
    let mut silence_logged = false;
    let mut done_at = None;
    let mut t_s = 0.0;
    'flight: loop {
        match interrupts.load(Ordering::Relaxed) {
            0 => {}
            1 => vehicle.request_land(),
            _ => break,
        }
        decoded.messages.clear();
        decoded.malformed = 0;
        let arrived = link
            .receive(Duration::from_millis(100), &mut decoded)
            .with_context(|| format!("reading {}", link.describe()))?;
        report.malformed += decoded.malformed as u64;
        if !arrived {
            if !silence_logged && last_frame.elapsed() > SILENCE_WARNING {
                tracing::warn!(
                    link = %link.describe(),
                    phase = ?vehicle.phase(),
                    "no sensor frames for {:.0?}: waiting",
                    last_frame.elapsed()
                );
                silence_logged = true;
            }
            continue;
        }
        for (_, msg) in &decoded.messages {
            let Some(step) = vehicle.on_message(msg) else {
                continue;
            };
            last_frame = Instant::now();
            silence_logged = false;
            report.frames += 1;
            t_s = step.t_s;
            answer.clear();
            encoder.push(&mut answer, &step.message);
            link.send(&answer)
                .with_context(|| format!("answering on {}", link.describe()))?;

            let elapsed = started.elapsed();
            if elapsed >= next_status {
                next_status = elapsed + Duration::from_millis(250);
                status(
                    &step.output,
                    vehicle.phase(),
                    t_s,
                    elapsed.as_secs_f64(),
                    tty,
                );
            }
            if vehicle.phase() == Phase::Disarmed && t_s > READY_TIMEOUT_S {
                let out = &step.output;
                bail!(
                    "not ready to arm after {READY_TIMEOUT_S} s of sensor time: attitude valid {}, horizontal position valid {}, vertical valid {}",
                    out.attitude.is_some_and(|a| a.valid),
                    out.translation.horizontal_valid,
                    out.translation.vertical_valid
                );
            }
            if vehicle.phase() == Phase::Done {
                // A second on the ground after disarming, then stop.
                let t = *done_at.get_or_insert(t_s);
                if t_s - t > 1.0 {
                    break 'flight;
                }
            }
        }
    }
    if tty {
        println!();
    }
    report.sim_time_s = t_s;
    report.wall_time_s = started.elapsed().as_secs_f64();
    report.score = vehicle.score().clone();
    report.repeated = vehicle.repeated_frames();
    report.disarmed = vehicle.phase() == Phase::Done;
    Ok(report)
}

/// The live one-line status: on a terminal it rewrites itself, otherwise one line each time.
fn status(out: &StepOutput, phase: Phase, t_s: f64, wall_s: f64, tty: bool) {
    let (roll, pitch, yaw) = out.attitude.map_or((0.0, 0.0, 0.0), |a| a.q.euler_angles());
    let line = format!(
        "t {t_s:6.1} s  {:<8} alt {:6.2} m  vz {:5.2} m/s  roll {:5.1}  pitch {:5.1}  yaw {:6.1} deg  x{:.0} real time",
        format!("{phase:?}"),
        -out.translation.pos_ned_m.z,
        -out.translation.vel_ned_m_s.z,
        roll.to_degrees(),
        pitch.to_degrees(),
        yaw.to_degrees(),
        t_s / wall_s.max(1e-9)
    );
    let mut stdout = std::io::stdout();
    if tty {
        let _ = write!(stdout, "\r{line}");
        let _ = stdout.flush();
    } else {
        let _ = writeln!(stdout, "{line}");
    }
}
