//! `autopilot --sim`: the flight core flying the embedded simulator.
//!
//! The simulator (`sitl-core`) runs in-process behind the same message boundary as an external
//! simulator or a flight board: every exchange is encoded to MAVLink 2 HIL messages and decoded
//! again on the autopilot's side, and the actuator commands travel back as
//! `HIL_ACTUATOR_CONTROLS` bytes. Physics runs at the airframe scenario's rate (1 kHz), the
//! exchange at 250 Hz; the simulation clock is the autopilot's clock.

use crate::vehicle::Vehicle;
use anyhow::{Result, bail};
use flight_core::params::FlightParams;
use flight_core::sequence::Phase;
use hil::{Accumulator, Encoder};
use mavlink::dialects::common::MavMessage;
use sitl_core::sim::{SimConfig, Simulator};
use sitl_core::{Airframe, BodyState};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::{Duration, Instant};

/// Options of an embedded flight.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// Airframe file.
    pub airframe: PathBuf,
    /// Flight parameters.
    pub params: FlightParams,
    /// Take-off altitude (m).
    pub takeoff_m: f64,
    /// Hover time before landing (s).
    pub hover_s: f64,
    /// Real-time factor; `None` as fast as possible.
    pub speed: Option<f64>,
    /// Seed of the simulated sensors.
    pub seed: u64,
}

/// What happened, for the summary line.
#[derive(Debug, Default)]
pub struct FlightReport {
    sim_time_s: f64,
    wall_time_s: f64,
    max_alt_m: f64,
    touchdown_m_s: f64,
    landed: bool,
    disarmed: bool,
    malformed: u32,
}

impl std::fmt::Display for FlightReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "autopilot summary: sim_time_s={:.2} wall_time_s={:.2} realtime_factor={:.1} max_alt_m={:.2} touchdown_m_s={:.2} landed={} disarmed={} malformed={}",
            self.sim_time_s,
            self.wall_time_s,
            self.sim_time_s / self.wall_time_s.max(1e-9),
            self.max_alt_m,
            self.touchdown_m_s,
            self.landed,
            self.disarmed,
            self.malformed
        )
    }
}

const EXCHANGE_STEPS: usize = 4;

/// The estimator converges in a few seconds at rest; a sequence still waiting after this long
/// never will, and the flight stops with the reason instead of waiting forever.
const READY_TIMEOUT_S: f64 = 60.0;

/// Flies the sequence in the embedded simulator. `interrupts` counts Ctrl-C presses: the first
/// lands, the second stops at once.
pub fn run(o: &SimOptions, interrupts: &AtomicU8) -> Result<FlightReport> {
    let airframe = Airframe::load(&o.airframe)?;
    let n = airframe.rotors.len();
    let mut sim = Simulator::new(
        &airframe,
        SimConfig {
            seed: o.seed,
            ..SimConfig::default()
        },
        BodyState::default(),
    )?;
    let mut vehicle = Vehicle::new(&airframe, &o.params, o.takeoff_m, o.hover_s)?;
    let started = Instant::now();
    let mut report = FlightReport::default();
    let (mut to_autopilot, mut to_sim) = (Encoder::default(), Encoder::default());
    let mut bytes = Vec::with_capacity(512);
    let mut acc = Accumulator::new(sim.sample_sensors());
    let mut controls = [0.0f64; 16];
    let mut next_state_usec = 0;
    let mut next_status = Duration::ZERO;
    let tty = std::io::stdout().is_terminal();
    let mut done_at = None;
    loop {
        if interrupts.load(Ordering::Relaxed) >= 2 {
            break;
        }
        if interrupts.load(Ordering::Relaxed) == 1 {
            vehicle.request_land();
        }
        // Simulator side: physics, then one exchange's messages as bytes.
        acc.start();
        for _ in 0..EXCHANGE_STEPS {
            sim.step(&controls[..n]);
            acc.add(sim.sample_sensors());
        }
        let truth = sim.truth();
        let send_state = truth.time_usec >= next_state_usec;
        if send_state {
            next_state_usec = truth.time_usec + 20_000;
        }
        bytes.clear();
        hil::encode_exchange(
            &mut to_autopilot,
            &mut bytes,
            acc.frame(),
            &truth,
            n,
            send_state,
        );

        // Autopilot side: decode, and a flight-core step for the sensor frame.
        let decoded = hil::decode(&bytes);
        report.malformed += decoded.malformed;
        let mut step = None;
        for (_, msg) in &decoded.messages {
            step = vehicle.on_message(msg).or(step);
        }
        let Some(step) = step else {
            continue;
        };
        let (out, t_s) = (step.output, step.t_s);
        bytes.clear();
        to_sim.push(&mut bytes, &step.message);

        // Simulator side again: the command as it arrives.
        for (_, msg) in hil::decode(&bytes).messages {
            if let MavMessage::HIL_ACTUATOR_CONTROLS(m) = msg {
                let cmd = hil::actuator_command(&m);
                controls = if cmd.armed { cmd.controls } else { [0.0; 16] };
            }
        }

        report.max_alt_m = report.max_alt_m.max(-truth.body.pos_ned_m.z);
        if sim.stats().touchdowns == 0 && report.max_alt_m > 1.0 && -truth.body.pos_ned_m.z < 0.3 {
            report.touchdown_m_s = report.touchdown_m_s.max(truth.body.vel_ned_m_s.z);
        }
        let elapsed = started.elapsed();
        if elapsed >= next_status {
            next_status = elapsed + Duration::from_millis(250);
            status(&out, vehicle.phase(), t_s, elapsed.as_secs_f64(), tty);
        }
        if vehicle.phase() == Phase::Disarmed && t_s > READY_TIMEOUT_S {
            bail!(
                "not ready to arm after {READY_TIMEOUT_S} s of simulation: attitude valid {}, horizontal position valid {}, vertical valid {}",
                out.attitude.is_some_and(|a| a.valid),
                out.translation.horizontal_valid,
                out.translation.vertical_valid
            );
        }
        if vehicle.phase() == Phase::Done {
            // A second on the ground after disarming, then stop.
            let t = *done_at.get_or_insert(t_s);
            if t_s - t > 1.0 {
                break;
            }
        }
        if let Some(f) = o.speed {
            let due = started + Duration::from_secs_f64(t_s / f);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
    }
    if tty {
        println!();
    }
    let truth = sim.truth();
    report.sim_time_s = sim.time_s();
    report.wall_time_s = started.elapsed().as_secs_f64();
    report.landed = truth.landed;
    report.disarmed = vehicle.phase() == Phase::Done;
    Ok(report)
}

pub fn status(out: &flight_core::core::StepOutput, phase: Phase, t_s: f64, wall_s: f64, tty: bool) {
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
