//! The control loop. It owns the [`Autopilot`], the records of its flight and its sensor link;
//! other tasks reach it only through [`Ports`]: a bounded channel of [`LoopCommand`]s in, the
//! latest [`Telemetry`] out. Each typed frame the link delivers ([`crate::links::frames`]) is
//! stepped on by the autopilot, the records observe the step, and the answer goes back on the
//! link.
//!
//! Two pacings ([`Pacing`]): in lockstep every sensor frame is a tick and its time the clock (a
//! simulator that waits for each answer); with a flight board in the real world the loop wakes
//! at absolute deadlines, reads whatever the link holds without waiting, steps on every complete
//! frame, and counts its lateness and overruns ([`crate::control_loop::deadline`]).

pub mod deadline;
mod report;
mod together;

pub use report::FlightReport;
pub use together::{SwarmReport, fly_together};

use crate::links::SensorLink;
use crate::links::frames::{self, Received};
use crate::records::FlightRecords;
use anyhow::{Context, Result, bail};
use deadline::{Deadlines, LoopStats, sleep_until};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{Autopilot, StepInputs};
use flight_core::commander::Denial;
use flight_core::params::FlightParams;
use flight_core::sensors::imu_calibrator::PoseRequest;
use gcs::telemetry::{LinkState, LoopSummary, Telemetry};
use hil::ActuatorCommand;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

/// The estimator converges in a few seconds at rest; a sequence still waiting after this long
/// never will, and the flight stops with the reason instead of waiting forever.
const READY_TIMEOUT_S: f64 = 60.0;

/// Wall-clock time without any sensor frame before the loop says so (before the first frame,
/// or from a lockstep simulator, whose world waits).
const SILENCE_WARNING: Duration = Duration::from_secs(2);

/// Silence of the sensor frames, on the link's clock, after which the estimate is invalid and
/// the vehicle reacts (s). With the loop's poll period below, the reaction starts within 0.1 s.
pub const SENSOR_TIMEOUT_S: f64 = 0.08;

/// How long one wait for frames lasts in lockstep: the watchdog's resolution.
const POLL: Duration = Duration::from_millis(10);

/// Reads per deadline tick at most: a link flooded with datagrams cannot hold the loop.
const MAX_READS_PER_TICK: usize = 32;

/// Shortest wall-clock interval between two telemetry publications: every step in real time,
/// about a thousand a second when lockstep runs faster (each wakes nobody but costs a notify).
const TELEMETRY_INTERVAL: Duration = Duration::from_millis(1);

/// What other tasks ask of the control loop.
#[derive(Debug)]
pub enum LoopCommand {
    /// End the run: land if in the air, then stop (the first Ctrl-C).
    Land,
    /// Stop the loop at once (the second Ctrl-C).
    Stop,
    /// A ground station's heartbeat arrived: the loop keeps its wall-clock time for the
    /// link-loss failsafe (the autopilot has no clock of its own).
    GcsHeartbeat,
    /// A ground station's request: an answered one's answer goes back on
    /// [`Ports::answers`] under its number.
    Vehicle {
        /// What is asked.
        command: AutopilotCommand,
        /// The number its answer carries back; none for a request not answered.
        answer: Option<u64>,
    },
}

/// The answer to an answered request: its number and the result.
pub type Answer = (u64, Result<(), Denial>);

/// The control loop's side of its channels.
pub struct Ports {
    /// Commands from other tasks (bounded; drained before each step).
    pub commands: mpsc::Receiver<LoopCommand>,
    /// The latest telemetry.
    pub telemetry: watch::Sender<Telemetry>,
    /// The parameters to fly with, when something (the ground-station side) changes them.
    pub params: Option<watch::Receiver<FlightParams>>,
    /// The answers to answered requests (never full: at most one per request admitted).
    pub answers: mpsc::UnboundedSender<Answer>,
    /// The system id to announce on stdout (`autopilot ready: system=N …`) the first time the
    /// vehicle passes its pre-arm checks, for scripts that wait for it; none: say nothing.
    pub announce_ready: Option<u8>,
}

/// The other ends of a control loop's channels, for the tasks around it.
pub struct LoopEnds {
    /// Commands to the loop (bounded).
    pub commands: mpsc::Sender<LoopCommand>,
    /// Its answers to answered requests.
    pub answers: mpsc::UnboundedReceiver<Answer>,
    /// Its latest telemetry.
    pub telemetry: watch::Receiver<Telemetry>,
}

impl Ports {
    /// Channels whose other ends are returned: commands in (capacity `capacity`), answers
    /// and telemetry out.
    pub fn new(capacity: usize) -> (Self, LoopEnds) {
        let (tx, commands) = mpsc::channel(capacity);
        let (answers, answers_rx) = mpsc::unbounded_channel();
        let (telemetry, rx) = watch::channel(Telemetry::default());
        let ports = Self {
            commands,
            telemetry,
            params: None,
            answers,
            announce_ready: None,
        };
        let ends = LoopEnds {
            commands: tx,
            answers: answers_rx,
            telemetry: rx,
        };
        (ports, ends)
    }
}

/// How the loop is paced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// Every sensor frame is a tick: the loop waits for it.
    Lockstep,
    /// Ticks at absolute deadlines every `period`; the last `spin` before each is spent
    /// spinning on the clock rather than sleeping (see [`sleep_until`]).
    Deadlines {
        /// The tick period.
        period: Duration,
        /// Spin before each deadline.
        spin: Duration,
        /// How often the loop's timing is logged.
        stats: Duration,
    },
}

/// Whether the loop goes on.
#[derive(Debug, PartialEq, Eq)]
enum Flow {
    Continue,
    Stop,
}

/// The loop's state between ticks, whatever paces it.
struct ControlLoop<'a> {
    link: &'a mut dyn SensorLink,
    autopilot: &'a mut Autopilot,
    records: &'a mut FlightRecords,
    ports: &'a mut Ports,
    report: FlightReport,
    received: Received,
    rotors: usize,
    last_frame: Instant,
    silence_logged: bool,
    done_at: Option<f64>,
    t_s: f64,
    /// The watchdog: the link-clock time of the last frame, and whether the vehicle reacted.
    last_frame_clock: Option<f64>,
    silent: bool,
    silent_done_at: Option<f64>,
    loop_stats: Option<LoopSummary>,
    /// When telemetry was last published.
    published: Instant,
    /// When the last ground-station heartbeat arrived (wall clock).
    gcs_heartbeat: Option<Instant>,
    /// A calibration's last request to the simulator's hand, and when it went (sensor time).
    pose_sent: (PoseRequest, f64),
}

/// How often a calibration's unchanged request to the hand is sent again (s): a few times
/// within the simulator's half second of patience, not on every frame of a slow serial line.
const POSE_REPEAT_S: f64 = 0.2;

impl<'a> ControlLoop<'a> {
    fn new(member: Onboard<'a>) -> Self {
        let Onboard {
            link,
            autopilot,
            records,
            ports,
        } = member;
        Self {
            report: FlightReport {
                source: link.describe(),
                ..FlightReport::default()
            },
            rotors: autopilot.state().rotors,
            link,
            autopilot,
            records,
            ports,
            received: Received::default(),
            last_frame: Instant::now(),
            silence_logged: false,
            done_at: None,
            t_s: 0.0,
            last_frame_clock: None,
            silent: false,
            silent_done_at: None,
            pose_sent: (PoseRequest::None, f64::NEG_INFINITY),
            loop_stats: None,
            published: Instant::now(),
            gcs_heartbeat: None,
        }
    }

    /// Drains the commands and takes new parameters.
    fn commands(&mut self) -> Flow {
        if let Some(params) = self.ports.params.as_mut()
            && params.has_changed().unwrap_or(false)
        {
            let p = params.borrow_and_update().clone();
            self.autopilot.set_params(&p);
            tracing::debug!("flying with new parameters");
        }
        while let Ok(c) = self.ports.commands.try_recv() {
            match c {
                LoopCommand::Land => self.autopilot.request_land(),
                LoopCommand::Stop => return Flow::Stop,
                LoopCommand::GcsHeartbeat => {
                    self.gcs_heartbeat = Some(Instant::now());
                }
                LoopCommand::Vehicle { command: c, answer } => {
                    // Sticks, offboard set-points and target fixes are streams: not logged.
                    let what = match &c {
                        AutopilotCommand::Sticks(_)
                        | AutopilotCommand::Offboard(_)
                        | AutopilotCommand::FollowTarget { .. } => None,
                        AutopilotCommand::SetMission(items) => {
                            Some(format!("SetMission({} items)", items.len()))
                        }
                        AutopilotCommand::SetFence(zones) => {
                            Some(format!("SetFence({} zones)", zones.len()))
                        }
                        c => Some(format!("{c:?}")),
                    };
                    let result = self.autopilot.command(c);
                    match (&result, what) {
                        (_, None) => {}
                        (Ok(()), Some(c)) => tracing::info!(command = c, "accepted"),
                        (Err(e), Some(c)) => tracing::warn!(command = c, "{e}"),
                    }
                    if let Some(id) = answer {
                        // The links may have ended (or given up on it): nothing to do then.
                        let _ = self.ports.answers.send((id, result));
                    }
                }
            }
        }
        Flow::Continue
    }

    /// Reads the link: waits up to `timeout`, then (`drain`) takes what else is there.
    fn read(&mut self, timeout: Duration, drain: bool) -> Result<bool> {
        self.received.frames.clear();
        self.received.malformed = 0;
        let mut arrived = self
            .link
            .receive(timeout, &mut self.received)
            .with_context(|| format!("reading {}", self.link.describe()))?;
        if drain && arrived {
            for _ in 1..MAX_READS_PER_TICK {
                if !self.link.receive(Duration::ZERO, &mut self.received)? {
                    break;
                }
            }
            arrived = true;
        }
        self.report.malformed += self.received.malformed as u64;
        if !arrived && !self.silence_logged && self.last_frame.elapsed() > SILENCE_WARNING {
            tracing::warn!(
                link = %self.link.describe(),
                mode = self.autopilot.status().mode.name(),
                "no sensor frames for {:.0?}: waiting",
                self.last_frame.elapsed()
            );
            self.silence_logged = true;
        }
        Ok(arrived)
    }

    /// The calibration's request to the hand for this answer: when it changes, and again every
    /// [`POSE_REPEAT_S`].
    fn pose_to_send(&mut self) -> PoseRequest {
        let pose = self.autopilot.pose_request();
        let (last, at) = self.pose_sent;
        if pose != PoseRequest::None && (pose != last || self.t_s - at >= POSE_REPEAT_S) {
            self.pose_sent = (pose, self.t_s);
            return pose;
        }
        if pose == PoseRequest::None {
            self.pose_sent.0 = pose;
        }
        PoseRequest::None
    }

    /// The sensor watchdog: on the link's clock, frames silent for [`SENSOR_TIMEOUT_S`] make
    /// the estimate invalid and the vehicle react; its commands keep going out meanwhile.
    fn watchdog(&mut self) -> Result<Flow> {
        let (Some(now), Some(last)) = (self.link.silence_clock_s(), self.last_frame_clock) else {
            return Ok(Flow::Continue);
        };
        if now - last < SENSOR_TIMEOUT_S {
            return Ok(Flow::Continue);
        }
        if !self.silent {
            self.silent = true;
            self.report.sensor_timeouts += 1;
            // Armed, the silence is a failsafe (the blind descent), whether or not a frame
            // ever comes again to show it.
            self.report.blind_failsafe |= self.autopilot.status().armed;
            self.autopilot.sensors_stopped();
            // No step publishes while the frames are silent: the ground station hears of it
            // (and of the failsafe) now.
            let state = *self.autopilot.state();
            self.ports.telemetry.send_modify(|t| {
                t.vehicle = Some(state);
                t.link.sensors_silent = true;
            });
        }
        // Keep the motors on the failsafe's command (a board wants a steady stream).
        let a = self.autopilot.silent_answer(now - last);
        let command = ActuatorCommand::as_sent(a.t_usec, &a.commands[..self.rotors], a.armed);
        self.send(&command)?;
        if self.autopilot.finished() {
            // Disarmed by the failsafe at the end of the run: a second more of motors-off,
            // then stop.
            if now - *self.silent_done_at.get_or_insert(now) > 1.0 {
                return Ok(Flow::Stop);
            }
        }
        Ok(Flow::Continue)
    }

    /// Steps the vehicle on every complete sensor frame read, and answers each.
    fn frames(&mut self) -> Result<Flow> {
        let inputs = StepInputs {
            gcs_link_age_s: self.gcs_heartbeat.map(|t| t.elapsed().as_secs_f64()),
            rc: None,
        };
        let mut received = std::mem::take(&mut self.received.frames);
        let flow = self.step_on(&mut received, inputs);
        self.received.frames = received;
        flow
    }

    /// The first time the vehicle could arm: a line on stdout, if asked for.
    fn announce_ready(&mut self) {
        if let Some(system) = self.ports.announce_ready
            && self.autopilot.status().prearm_ok
        {
            self.ports.announce_ready = None;
            // On a terminal, over the status line being rewritten there (it goes on below).
            let clear = if std::io::IsTerminal::is_terminal(&std::io::stdout()) {
                "\r\x1b[K"
            } else {
                ""
            };
            println!(
                "{clear}autopilot ready: system={system} t_s={:.3}",
                self.t_s
            );
        }
    }

    /// Steps on `frames` in order, answering each.
    fn step_on(&mut self, frames: &mut [frames::LinkFrame], inputs: StepInputs) -> Result<Flow> {
        for frame in frames {
            let inputs = StepInputs {
                rc: frame.rc,
                ..inputs
            };
            // The sample is flown in place, and left as the records take it.
            if !self.autopilot.step_in_place(&mut frame.sample, &inputs) {
                continue;
            }
            let Some(step) = self.autopilot.output() else {
                continue;
            };
            self.records
                .observe(step, &frame.sample, self.autopilot.state(), frame.truth);
            self.t_s = step.t_usec as f64 * 1e-6;
            self.last_frame = Instant::now();
            self.silence_logged = false;
            self.last_frame_clock = self.link.silence_clock_s();
            if self.silent {
                self.silent = false;
                self.silent_done_at = None;
                self.autopilot.sensors_resumed();
            }
            self.report.frames += 1;
            let pose = self.pose_to_send();
            if let Some(step) = self.autopilot.output() {
                let answer = frames::answer(step, self.rotors, pose);
                self.send(&answer)?;
            }
            self.announce_ready();
            let changed = self.autopilot.take_changed();
            let now = self.last_frame;
            if now >= self.published + TELEMETRY_INTERVAL || changed {
                self.published = now;
                self.publish_telemetry();
            }
            if self.autopilot.awaiting_takeoff()
                && self.t_s > READY_TIMEOUT_S
                && let Some(out) = self.autopilot.state().estimate.as_ref()
            {
                bail!(
                    "not ready to arm after {READY_TIMEOUT_S} s of sensor time: attitude valid {}, horizontal position valid {}, vertical valid {}",
                    out.attitude.is_some_and(|a| a.valid),
                    out.translation.horizontal_valid,
                    out.translation.vertical_valid
                );
            }
            if self.autopilot.finished() {
                // A second on the ground after the run ended, then stop.
                let t = *self.done_at.get_or_insert(self.t_s);
                if self.t_s - t > 1.0 {
                    return Ok(Flow::Stop);
                }
            }
        }
        Ok(Flow::Continue)
    }

    /// The latest telemetry, written in place: the state (2.5 kB) copied once, not built,
    /// moved and dropped. (A function of its own: how often it runs follows the wall clock, and
    /// `tools/bench_cost.py` counts it apart from the frame.)
    #[inline(never)]
    fn publish_telemetry(&mut self) {
        let link = LinkState {
            t_s: self.t_s,
            truth: self.records.truth(),
            frames: self.report.frames,
            loop_stats: self.loop_stats,
            finished: false,
            sensors_silent: false,
            logs_stopped: self.records.logs_stopped(),
        };
        let state = self.autopilot.state();
        self.ports.telemetry.send_modify(|t| {
            t.vehicle = Some(*state);
            t.link = link;
        });
    }

    /// Sends `command` on the link.
    fn send(&mut self, command: &ActuatorCommand) -> Result<()> {
        self.link
            .send(command)
            .with_context(|| format!("answering on {}", self.link.describe()))
    }

    /// One tick: commands, the link, the watchdog, the frames.
    fn tick(&mut self, timeout: Duration, drain: bool) -> Result<Flow> {
        if self.commands() == Flow::Stop {
            return Ok(Flow::Stop);
        }
        let arrived = self.read(timeout, drain)?;
        if self.watchdog()? == Flow::Stop || (arrived && self.frames()? == Flow::Stop) {
            return Ok(Flow::Stop);
        }
        Ok(Flow::Continue)
    }

    /// The run's report, once the loop has ended (`started`: when it began).
    fn into_report(self, started: Instant) -> FlightReport {
        let mut report = self.report;
        report.sim_time_s = self.t_s;
        report.wall_time_s = started.elapsed().as_secs_f64();
        report.score = self.records.score().clone();
        report.repeated = self.autopilot.repeated_frames();
        report.disarmed = !self.autopilot.status().armed;
        report
    }

    /// Lockstep: every frame is a tick.
    fn run_lockstep(&mut self) -> Result<()> {
        while self.tick(POLL, false)? == Flow::Continue {}
        Ok(())
    }

    /// Ticks at absolute deadlines, never waiting on the link.
    fn run_deadlines(&mut self, period: Duration, spin: Duration, stats: Duration) -> Result<()> {
        let start = Instant::now();
        let mut deadlines = Deadlines::new(start, period);
        let (mut interval, mut whole) = (LoopStats::default(), LoopStats::default());
        let mut interval_start = start;
        loop {
            let due = deadlines.next();
            sleep_until(due, spin);
            let woke = Instant::now();
            self.records
                .set_loop_late(woke.saturating_duration_since(due));
            let flow = self.tick(Duration::ZERO, true)?;
            let end = Instant::now();
            let missed = deadlines.advance(end);
            interval.record(woke - due, end - woke, missed);
            if end >= interval_start + stats || flow == Flow::Stop {
                let s = interval.summary();
                let elapsed = (end - interval_start).as_secs_f64();
                tracing::info!(
                    rate_hz = format!("{:.0}", s.ticks as f64 / elapsed),
                    jitter_p50_us = s.jitter_p50_us,
                    jitter_p99_us = s.jitter_p99_us,
                    jitter_max_us = s.jitter_max_us,
                    work_max_us = s.work_max_us,
                    overruns = s.overruns,
                    "control loop"
                );
                self.loop_stats = Some(s);
                whole.merge(&interval);
                interval.clear();
                interval_start = end;
            }
            if flow == Flow::Stop {
                break;
            }
        }
        let wall = start.elapsed().as_secs_f64();
        let s = whole.summary();
        self.report.deadline_loop = Some((s.ticks as f64 / wall.max(1e-9), s));
        Ok(())
    }
}

/// Flies one vehicle until it has landed and disarmed, or a [`LoopCommand::Stop`] arrives.
pub fn fly(vehicle: Onboard<'_>, pacing: Pacing) -> Result<FlightReport> {
    let started = Instant::now();
    let mut l = ControlLoop::new(vehicle);
    let result = match pacing {
        Pacing::Lockstep => l.run_lockstep(),
        Pacing::Deadlines {
            period,
            spin,
            stats,
        } => l.run_deadlines(period, spin, stats),
    };
    l.ports.telemetry.send_modify(|t| t.link.finished = true);
    result?;
    Ok(l.into_report(started))
}

/// What the control loop flies for one vehicle: its sensor link, its autopilot, the records of
/// its flight and its channels. Flown together ([`fly_together`]), each has a simulator of its
/// own, in lockstep and unpaced.
pub struct Onboard<'a> {
    /// The sensor link: a simulator or a flight board.
    pub link: &'a mut dyn SensorLink,
    /// The autopilot.
    pub autopilot: &'a mut Autopilot,
    /// The records its steps feed.
    pub records: &'a mut FlightRecords,
    /// Its channels to the tasks around it (its ground stations).
    pub ports: &'a mut Ports,
}

#[cfg(test)]
mod tests;
