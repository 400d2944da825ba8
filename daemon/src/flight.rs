//! The control loop. It owns the [`Vehicle`] (the flight core and its sequence) and its sensor
//! link; other tasks reach it only through [`Ports`]: a bounded channel of [`Command`]s in, the
//! latest [`Telemetry`] out.
//!
//! Two pacings ([`Pacing`]): in lockstep every sensor frame is a tick and its time the clock (a
//! simulator that waits for each answer); with a flight board in the real world the loop wakes
//! at absolute deadlines, reads whatever the link holds without waiting, steps on every complete
//! frame, and counts its lateness and overruns ([`crate::deadline`]).

use crate::deadline::{Deadlines, LoopStats, LoopSummary, sleep_until};
use crate::link::SensorLink;
use crate::score::FlightScore;
use crate::vehicle::Vehicle;
use crate::vehicle::VehicleCommand;
use anyhow::{Context, Result, bail};
use flight_core::commander::{CommanderStatus, Denial};
use flight_core::control::Setpoint;
use flight_core::core::{SensorSample, StepOutput};
use flight_core::params::FlightParams;
use hil::{Decoded, Encoder};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot, watch};

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
pub enum Command {
    /// End the run: land if in the air, then stop (the first Ctrl-C).
    Land,
    /// Stop the loop at once (the second Ctrl-C).
    Stop,
    /// A vehicle command; the answer goes back on the channel given (if any).
    Vehicle(VehicleCommand, Option<oneshot::Sender<Result<(), Denial>>>),
}

/// What the control loop publishes after every step: the latest value, for the status line
/// and (later) the ground-station telemetry.
#[derive(Debug, Clone, Copy, Default)]
pub struct Telemetry {
    /// Time of the last sensor frame (s).
    pub t_s: f64,
    /// The commander's state.
    pub status: Option<CommanderStatus>,
    /// The last step's output.
    pub output: Option<StepOutput>,
    /// The last GPS solution.
    pub gps: Option<hil::GpsReport>,
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
    pub battery: flight_core::sensors::battery::BatteryState,
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
    pub mag_cal: Option<flight_core::sensors::mag_calibrator::MagCalStatus>,
}

/// The control loop's side of its channels.
pub struct Ports {
    /// Commands from other tasks (bounded; drained before each step).
    pub commands: mpsc::Receiver<Command>,
    /// The latest telemetry.
    pub telemetry: watch::Sender<Telemetry>,
    /// The parameters to fly with, when something (the ground-station side) changes them.
    pub params: Option<watch::Receiver<FlightParams>>,
}

impl Ports {
    /// Channels whose other ends are returned: a command sender (capacity `capacity`) and a
    /// telemetry receiver.
    pub fn new(capacity: usize) -> (Self, mpsc::Sender<Command>, watch::Receiver<Telemetry>) {
        let (tx, commands) = mpsc::channel(capacity);
        let (telemetry, rx) = watch::channel(Telemetry::default());
        (
            Self {
                commands,
                telemetry,
                params: None,
            },
            tx,
            rx,
        )
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
    sensor_timeouts: u64,
    /// The deadline loop's rate and timing over the whole run.
    deadline_loop: Option<(f64, LoopSummary)>,
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
}

impl std::fmt::Display for FlightReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let opt = |x: Option<f64>| x.map_or("nan".to_owned(), |x| format!("{x:.3}"));
        write!(
            f,
            "autopilot summary: source={} sim_time_s={:.2} wall_time_s={:.2} realtime_factor={:.1} frames={} frames_per_s={:.0} malformed={} repeated={} sensor_timeouts={} max_alt_m={:.2} hover_alt_rms_m={} hover_drift_rms_m={} attitude_rms_deg={} touchdown_m_s={:.2} impact_m_s={:.2} max_tilt_deg={:.1} max_distance_m={:.2} failsafe={} landed={} disarmed={}",
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
            self.score.failsafe,
            self.score.on_ground(),
            self.disarmed
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

/// Whether the loop goes on.
#[derive(Debug, PartialEq, Eq)]
enum Flow {
    Continue,
    Stop,
}

/// The loop's state between ticks, whatever paces it.
struct ControlLoop<'a> {
    link: &'a mut dyn SensorLink,
    vehicle: &'a mut Vehicle,
    ports: &'a mut Ports,
    report: FlightReport,
    encoder: Encoder,
    decoded: Decoded,
    answer: Vec<u8>,
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
}

impl<'a> ControlLoop<'a> {
    fn new(
        link: &'a mut dyn SensorLink,
        vehicle: &'a mut Vehicle,
        ports: &'a mut Ports,
        system_id: u8,
    ) -> Self {
        Self {
            report: FlightReport {
                source: link.describe(),
                ..FlightReport::default()
            },
            link,
            vehicle,
            ports,
            encoder: Encoder::with_ids(system_id, 1),
            decoded: Decoded::default(),
            answer: Vec::with_capacity(128),
            last_frame: Instant::now(),
            silence_logged: false,
            done_at: None,
            t_s: 0.0,
            last_frame_clock: None,
            silent: false,
            silent_done_at: None,
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
            self.vehicle.set_params(&p);
            tracing::debug!("flying with new parameters");
        }
        while let Ok(c) = self.ports.commands.try_recv() {
            match c {
                Command::Land => self.vehicle.request_land(),
                Command::Stop => return Flow::Stop,
                Command::Vehicle(VehicleCommand::GcsHeartbeat, _) => {
                    self.gcs_heartbeat = Some(Instant::now());
                }
                Command::Vehicle(c, reply) => {
                    // Sticks and offboard set-points arrive tens of times a second: not logged.
                    let what = match &c {
                        VehicleCommand::Sticks(_) | VehicleCommand::Offboard(_) => None,
                        VehicleCommand::SetMission(items) => {
                            Some(format!("SetMission({} items)", items.len()))
                        }
                        VehicleCommand::SetFence(zones) => {
                            Some(format!("SetFence({} zones)", zones.len()))
                        }
                        c => Some(format!("{c:?}")),
                    };
                    let result = self.vehicle.command(c);
                    match (&result, what) {
                        (_, None) => {}
                        (Ok(()), Some(c)) => tracing::info!(command = c, "accepted"),
                        (Err(e), Some(c)) => tracing::warn!(command = c, "{e}"),
                    }
                    if let Some(reply) = reply {
                        // The asker may have given up waiting: nothing to do then.
                        let _ = reply.send(result);
                    }
                }
            }
        }
        Flow::Continue
    }

    /// Reads the link: waits up to `timeout`, then (`drain`) takes what else is there.
    fn read(&mut self, timeout: Duration, drain: bool) -> Result<bool> {
        self.decoded.messages.clear();
        self.decoded.malformed = 0;
        let mut arrived = self
            .link
            .receive(timeout, &mut self.decoded)
            .with_context(|| format!("reading {}", self.link.describe()))?;
        if drain && arrived {
            for _ in 1..MAX_READS_PER_TICK {
                if !self.link.receive(Duration::ZERO, &mut self.decoded)? {
                    break;
                }
            }
            arrived = true;
        }
        self.report.malformed += self.decoded.malformed as u64;
        if !arrived && !self.silence_logged && self.last_frame.elapsed() > SILENCE_WARNING {
            tracing::warn!(
                link = %self.link.describe(),
                mode = self.vehicle.status().mode.name(),
                "no sensor frames for {:.0?}: waiting",
                self.last_frame.elapsed()
            );
            self.silence_logged = true;
        }
        Ok(arrived)
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
            self.vehicle.sensors_stopped();
            // No step publishes while the frames are silent: the ground station hears of it
            // (and of the failsafe) now.
            let status = self.vehicle.status();
            self.ports.telemetry.send_modify(|t| {
                t.status = Some(status);
                t.sensors_silent = true;
            });
        }
        // Keep the motors on the failsafe's command (a board wants a steady stream).
        let message = self.vehicle.silent_answer(now - last);
        self.send(&message)?;
        if self.vehicle.finished() {
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
        self.vehicle
            .set_gcs_link_age(self.gcs_heartbeat.map(|t| t.elapsed().as_secs_f64()));
        for i in 0..self.decoded.messages.len() {
            let Some(step) = self.vehicle.on_message(&self.decoded.messages[i].1) else {
                continue;
            };
            self.last_frame = Instant::now();
            self.silence_logged = false;
            self.last_frame_clock = self.link.silence_clock_s();
            if self.silent {
                self.silent = false;
                self.silent_done_at = None;
                self.vehicle.sensors_resumed();
            }
            self.report.frames += 1;
            self.t_s = step.t_s;
            self.send(&step.message)?;
            let status = self.vehicle.status();
            let changed = self.vehicle.take_changed();
            let now = self.last_frame;
            if now >= self.published + TELEMETRY_INTERVAL || changed {
                self.published = now;
                self.ports.telemetry.send_replace(Telemetry {
                    t_s: step.t_s,
                    status: Some(status),
                    gps: self.vehicle.gps(),
                    sample: self.vehicle.sample(),
                    setpoint: self.vehicle.setpoint(),
                    truth: self.vehicle.truth(),
                    max_thrust_n: self.vehicle.max_thrust_n(),
                    battery_v: self.vehicle.battery_v(),
                    battery: self.vehicle.battery(),
                    output: Some(step.output),
                    frames: self.report.frames,
                    loop_stats: self.loop_stats,
                    finished: false,
                    sensors_silent: false,
                    source_restarts: self.vehicle.source_restarts(),
                    mag_cal: self.vehicle.mag_calibration(),
                });
            }
            if self.vehicle.awaiting_takeoff() && self.t_s > READY_TIMEOUT_S {
                let out = &step.output;
                bail!(
                    "not ready to arm after {READY_TIMEOUT_S} s of sensor time: attitude valid {}, horizontal position valid {}, vertical valid {}",
                    out.attitude.is_some_and(|a| a.valid),
                    out.translation.horizontal_valid,
                    out.translation.vertical_valid
                );
            }
            if self.vehicle.finished() {
                // A second on the ground after the run ended, then stop.
                let t = *self.done_at.get_or_insert(self.t_s);
                if self.t_s - t > 1.0 {
                    return Ok(Flow::Stop);
                }
            }
        }
        Ok(Flow::Continue)
    }

    /// Encodes `message` and sends it on the link.
    fn send(&mut self, message: &mavlink::dialects::common::MavMessage) -> Result<()> {
        self.answer.clear();
        self.encoder.push(&mut self.answer, message);
        self.link
            .send(&self.answer)
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
        report.score = self.vehicle.score().clone();
        report.repeated = self.vehicle.repeated_frames();
        report.disarmed = !self.vehicle.status().armed;
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
            self.vehicle
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

/// Flies the vehicle's sequence over `link` until it has landed and disarmed, or a
/// [`Command::Stop`] arrives.
pub fn fly(
    link: &mut dyn SensorLink,
    vehicle: &mut Vehicle,
    system_id: u8,
    ports: &mut Ports,
    pacing: Pacing,
) -> Result<FlightReport> {
    let started = Instant::now();
    let mut l = ControlLoop::new(link, vehicle, ports, system_id);
    let result = match pacing {
        Pacing::Lockstep => l.run_lockstep(),
        Pacing::Deadlines {
            period,
            spin,
            stats,
        } => l.run_deadlines(period, spin, stats),
    };
    l.ports.telemetry.send_modify(|t| t.finished = true);
    result?;
    Ok(l.into_report(started))
}

/// One of several vehicles flown together by [`fly_together`]: its sensor link (a simulator
/// of its own, in lockstep and unpaced), its vehicle and its channels.
pub struct Member<'a> {
    /// The vehicle's simulator.
    pub link: &'a mut dyn SensorLink,
    /// The vehicle.
    pub vehicle: &'a mut Vehicle,
    /// Its channels to the tasks around it (its ground stations).
    pub ports: &'a mut Ports,
    /// Its MAVLink system id.
    pub system_id: u8,
}

/// How a flight of several vehicles together went.
#[derive(Debug)]
pub struct SwarmReport {
    /// Each vehicle's report, or why its flight ended in error, in the members' order.
    pub flights: Vec<Result<FlightReport>>,
    /// Rounds flown: in each, every vehicle still flying took one sensor frame.
    pub rounds: u64,
    /// Simulated time of the last round (s).
    pub sim_time_s: f64,
    /// Wall-clock time (s).
    pub wall_time_s: f64,
    /// Paced (`speed`): the largest lag of a round behind its wall-clock time (s); a swarm
    /// that runs in real time keeps it within a few exchange periods.
    pub max_lag_s: f64,
}

/// Flies several vehicles on this thread, in lockstep on one clock: every round each vehicle
/// still flying takes the next frame of its simulator (one exchange, `1 / exchange_hz` of
/// simulated time) and answers it, so all worlds advance together. With `speed` the rounds are
/// paced against the wall clock (× real time); without, they run as fast as they can. A vehicle
/// whose run ends (landed and disarmed, `Stop`, an error) leaves the round; the others fly on.
pub fn fly_together(members: Vec<Member<'_>>, exchange_hz: f64, speed: Option<f64>) -> SwarmReport {
    let started = Instant::now();
    let mut loops: Vec<Option<ControlLoop<'_>>> = members
        .into_iter()
        .map(|m| Some(ControlLoop::new(m.link, m.vehicle, m.ports, m.system_id)))
        .collect();
    let mut flights: Vec<Option<Result<FlightReport>>> = loops.iter().map(|_| None).collect();
    let (mut rounds, mut max_lag_s) = (0u64, 0.0f64);
    let mut flying = loops.len();
    while flying > 0 {
        for (slot, flight) in loops.iter_mut().zip(flights.iter_mut()) {
            let Some(l) = slot.as_mut() else { continue };
            let end = match l.tick(POLL, false) {
                Ok(Flow::Continue) => continue,
                Ok(Flow::Stop) => Ok(()),
                Err(e) => Err(e),
            };
            let Some(l) = slot.take() else { continue };
            l.ports.telemetry.send_modify(|t| t.finished = true);
            *flight = Some(end.map(|()| l.into_report(started)));
            flying -= 1;
        }
        rounds += 1;
        if let Some(speed) = speed {
            let due = started + Duration::from_secs_f64(rounds as f64 / exchange_hz / speed);
            match due.checked_duration_since(Instant::now()) {
                Some(wait) => std::thread::sleep(wait),
                None => max_lag_s = max_lag_s.max(due.elapsed().as_secs_f64()),
            }
        }
    }
    SwarmReport {
        flights: flights
            .into_iter()
            .map(|f| f.unwrap_or_else(|| Err(anyhow::anyhow!("never flown"))))
            .collect(),
        rounds,
        sim_time_s: rounds as f64 / exchange_hz,
        wall_time_s: started.elapsed().as_secs_f64(),
        max_lag_s,
    }
}

#[cfg(test)]
mod tests {
    //! Sensors that stop, flown in the embedded simulator: the link below loses frames or
    //! messages on cue while the world goes on, and keeps its own clock (the simulation time),
    //! so every run is the same run.
    #![allow(clippy::unwrap_used)]

    use super::*;
    use crate::sim::{EXCHANGE_HZ, EmbeddedSim};
    use flight_core::params::FlightParams;
    use mavlink::dialects::common::MavMessage;
    use nalgebra::Vector3;
    use sitl_core::Airframe;
    use sitl_core::sensors::SensorPreset;
    use std::io;
    use std::path::PathBuf;

    /// What stops, and when.
    #[derive(Clone, Copy)]
    enum Fault {
        /// All frames, `after_s` after take-off (0: at once), for `for_s` seconds.
        Frames { after_s: f64, for_s: f64 },
        /// All frames, half a second after arming, on the ground, for good.
        FramesOnGround,
        /// The GPS messages, two seconds into the hover, for good.
        Gps,
        /// The IMU repeats one reading (gyro and accelerometer), two seconds into the hover.
        ImuFrozen,
        /// The simulator stops two seconds into the hover and a new one (a new world, the
        /// vehicle on the ground, its clock from zero) starts a second later.
        SimRestart,
    }

    struct FaultyLink {
        sim: EmbeddedSim,
        fault: Fault,
        /// Simulation time the fault began, once it has.
        began_s: Option<f64>,
        lost_until_s: f64,
        armed_at_s: Option<f64>,
        hover_from_s: Option<f64>,
        last_frame_s: f64,
        silent_waits: u32,
        reaction_s: Option<f64>,
        last_answer_armed: bool,
        max_tilt_after_deg: f64,
        /// Largest tilt from a second after the frames came back.
        max_tilt_closed_loop_deg: f64,
        touchdown_m_s: f64,
        max_height_m: f64,
        horizontal_at_fault: Vector3<f64>,
        max_drift_after_m: f64,
        /// The reading a frozen IMU repeats.
        frozen_imu: Option<[f32; 6]>,
        /// The seed and airframe of a simulator started again, and whether it has been.
        seed: u64,
        airframe: Airframe,
        restarted: bool,
    }

    impl FaultyLink {
        fn new(fault: Fault, seed: u64) -> Self {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
            let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
            Self {
                sim: EmbeddedSim::new(&airframe, seed, SensorPreset::Typical, None, None).unwrap(),
                seed,
                airframe,
                restarted: false,
                fault,
                began_s: None,
                lost_until_s: 0.0,
                armed_at_s: None,
                hover_from_s: None,
                last_frame_s: 0.0,
                silent_waits: 0,
                reaction_s: None,
                last_answer_armed: false,
                max_tilt_after_deg: 0.0,
                max_tilt_closed_loop_deg: 0.0,
                touchdown_m_s: 0.0,
                max_height_m: 0.0,
                horizontal_at_fault: Vector3::zeros(),
                max_drift_after_m: 0.0,
                frozen_imu: None,
            }
        }

        fn now_s(&self) -> f64 {
            self.sim.truth().time_usec as f64 * 1e-6
        }

        /// Watches the truth after every exchange.
        fn observe(&mut self) {
            let truth = self.sim.truth();
            let t = self.now_s();
            let height = -truth.body.pos_ned_m.z;
            self.max_height_m = self.max_height_m.max(height);
            if height > 4.9 && self.hover_from_s.is_none() {
                self.hover_from_s = Some(t);
            }
            let start = match self.fault {
                Fault::Frames { after_s, for_s } => {
                    self.lost_until_s = f64::INFINITY;
                    self.hover_from_s.map(|h| {
                        self.lost_until_s = h + after_s + for_s;
                        h + after_s
                    })
                }
                Fault::FramesOnGround => {
                    self.lost_until_s = f64::INFINITY;
                    self.armed_at_s.map(|a| a + 0.5)
                }
                Fault::Gps | Fault::ImuFrozen | Fault::SimRestart => {
                    self.hover_from_s.map(|h| h + 2.0)
                }
            };
            if self.began_s.is_none() && !self.restarted && start.is_some_and(|s| t >= s) {
                self.began_s = Some(t);
                self.horizontal_at_fault = truth.body.pos_ned_m;
            }
            if self.began_s.is_some() {
                let up = Vector3::new(0.0, 0.0, -1.0);
                let tilt = (truth.body.q_ned_from_frd * up).angle(&up).to_degrees();
                self.max_tilt_after_deg = self.max_tilt_after_deg.max(tilt);
                if t > self.lost_until_s + 1.0 {
                    self.max_tilt_closed_loop_deg = self.max_tilt_closed_loop_deg.max(tilt);
                }
                let drift = (truth.body.pos_ned_m - self.horizontal_at_fault)
                    .xy()
                    .norm();
                self.max_drift_after_m = self.max_drift_after_m.max(drift);
            }
            if height < 0.3 && !truth.landed {
                self.touchdown_m_s = self.touchdown_m_s.max(truth.body.vel_ned_m_s.z);
            }
        }

        fn frames_lost(&self) -> bool {
            if matches!(self.fault, Fault::SimRestart) {
                return !self.restarted && self.began_s.is_some();
            }
            matches!(self.fault, Fault::Frames { .. } | Fault::FramesOnGround)
                && self
                    .began_s
                    .is_some_and(|_| self.now_s() < self.lost_until_s)
        }
    }

    impl SensorLink for FaultyLink {
        fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> io::Result<bool> {
            if self.now_s() > 300.0 {
                return Err(io::Error::other("the flight did not end within 300 s"));
            }
            if matches!(self.fault, Fault::SimRestart)
                && self.frames_lost()
                && self.began_s.is_some_and(|b| self.now_s() >= b + 1.0)
            {
                // A new world: the vehicle on the ground, the clock from zero.
                self.sim = EmbeddedSim::new(
                    &self.airframe,
                    self.seed + 1,
                    SensorPreset::Typical,
                    None,
                    None,
                )
                .map_err(|e| io::Error::other(format!("{e:#}")))?;
                self.restarted = true;
                self.max_height_m = 0.0;
                self.touchdown_m_s = 0.0;
            }
            if self.frames_lost() {
                // The world goes on for the wait; no frame reaches the autopilot.
                let n = (timeout.as_secs_f64() * EXCHANGE_HZ).round().max(1.0) as usize;
                self.sim.advance_silently(n);
                self.observe();
                self.silent_waits += 1;
                return Ok(false);
            }
            let before = into.messages.len();
            self.sim.receive(timeout, into)?;
            self.observe();
            if matches!(self.fault, Fault::Gps) && self.began_s.is_some() {
                let mut i = before;
                while i < into.messages.len() {
                    if matches!(into.messages[i].1, MavMessage::HIL_GPS(_)) {
                        into.messages.remove(i);
                    } else {
                        i += 1;
                    }
                }
            }
            if matches!(self.fault, Fault::ImuFrozen) && self.began_s.is_some() {
                for (_, m) in &mut into.messages[before..] {
                    if let MavMessage::HIL_SENSOR(s) = m {
                        let [ax, ay, az, gx, gy, gz] = *self
                            .frozen_imu
                            .get_or_insert([s.xacc, s.yacc, s.zacc, s.xgyro, s.ygyro, s.zgyro]);
                        (s.xacc, s.yacc, s.zacc) = (ax, ay, az);
                        (s.xgyro, s.ygyro, s.zgyro) = (gx, gy, gz);
                    }
                }
            }
            self.last_frame_s = self.now_s();
            Ok(true)
        }

        fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
            for (_, msg) in hil::decode(bytes).messages {
                if let MavMessage::HIL_ACTUATOR_CONTROLS(m) = msg {
                    let armed = hil::actuator_command(&m).armed;
                    if armed && self.armed_at_s.is_none() {
                        self.armed_at_s = Some(self.now_s());
                    }
                    // The first answer sent into the silence (not the one to the last frame).
                    if self.silent_waits > 0 && self.reaction_s.is_none() {
                        self.reaction_s = Some(self.now_s() - self.last_frame_s);
                    }
                    self.last_answer_armed = armed;
                }
            }
            self.sim.send(bytes)
        }

        fn describe(&self) -> String {
            "faulty sim".into()
        }

        fn silence_clock_s(&self) -> Option<f64> {
            Some(self.now_s())
        }
    }

    fn fly_with(fault: Fault) -> (FaultyLink, FlightReport, Vehicle) {
        fly_seed(fault, 3)
    }

    fn fly_seed(fault: Fault, seed: u64) -> (FaultyLink, FlightReport, Vehicle) {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
        let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
        let mut params = FlightParams::load(&dir.join("flight.toml")).unwrap();
        crate::link::Source::Embedded.preset_params(&mut params);
        let auto = crate::vehicle::AutoFlight {
            takeoff_m: 5.0,
            hover_s: 30.0,
        };
        let mut vehicle = Vehicle::new(&airframe, &params, Some(auto)).unwrap();
        let mut link = FaultyLink::new(fault, seed);
        let (mut ports, _commands, _telemetry) = Ports::new(4);
        let report = fly(&mut link, &mut vehicle, 1, &mut ports, Pacing::Lockstep).unwrap();
        eprintln!(
            "fault began at {:?} s: reaction {:?} s, tilt after ≤ {:.1}°, drift after ≤ {:.2} m, touchdown {:.2} m/s, ended at {:.1} s\n{report}",
            link.began_s,
            link.reaction_s,
            link.max_tilt_after_deg,
            link.max_drift_after_m,
            link.touchdown_m_s,
            link.now_s()
        );
        (link, report, vehicle)
    }

    /// Open loop, the descent is only as level as the hover commands are balanced and the
    /// vehicle was still when the frames stopped: over twenty seeds and both blind faults (frames
    /// stopped, IMU frozen) it tilts 14° at the median, 25° at the 90th percentile, and lands
    /// at 1.5 m/s (2.1 m/s), a firm landing against ≈ 10 m/s for a fall from 5 m; one flight
    /// state (seed 3) tilts 65° and lands at 4.5 m/s in both. What is asserted on every seed is
    /// the reaction and a descent that ends on the ground, never inverted, slower than half a
    /// fall, motors stopped; over the five seeds, the median tilt and touchdown.
    #[test]
    fn frames_that_stop_in_the_air_start_a_blind_descent_to_the_ground() {
        let mut descents = Vec::new();
        for seed in 2..=6 {
            let (link, report, vehicle) = fly_seed(
                Fault::Frames {
                    after_s: 2.0,
                    for_s: f64::INFINITY,
                },
                seed,
            );
            let reaction = link.reaction_s.expect("a failsafe answer while silent");
            assert!(
                reaction <= 0.1,
                "seed {seed}: reacted {reaction:.3} s after the last frame"
            );
            assert_eq!(report.sensor_timeouts, 1);
            descents.push(assert_came_down_blind(&link, &vehicle, seed));
        }
        assert_typical_blind_descents(&mut descents);
    }

    /// Over several seeds, the median blind descent tilts at most 30° and lands at 2.5 m/s.
    fn assert_typical_blind_descents(descents: &mut [(f64, f64)]) {
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let tilt = median(&mut descents.iter().map(|d| d.0).collect());
        let touchdown = median(&mut descents.iter().map(|d| d.1).collect());
        assert!(
            tilt <= 30.0 && touchdown <= 2.5,
            "median tilt {tilt:.1}°, touchdown {touchdown:.2} m/s"
        );
    }

    /// The end of a blind descent: on the ground, never inverted, landed slower than half a
    /// fall from 5 m, motors stopped. Returns the largest tilt (°) and the touchdown (m/s).
    fn assert_came_down_blind(link: &FaultyLink, vehicle: &Vehicle, seed: u64) -> (f64, f64) {
        assert!(link.max_height_m > 4.9, "was flying");
        assert!(
            link.sim.truth().landed,
            "seed {seed}: on the ground at the end"
        );
        assert!(!link.last_answer_armed, "motors stopped at the end");
        assert!(vehicle.finished() && !vehicle.status().armed);
        assert!(
            link.touchdown_m_s <= 5.0,
            "seed {seed}: touchdown at {:.2} m/s",
            link.touchdown_m_s
        );
        assert!(
            link.max_tilt_after_deg < 90.0,
            "seed {seed}: never inverted: tilt up to {:.1}°",
            link.max_tilt_after_deg
        );
        (link.max_tilt_after_deg, link.touchdown_m_s)
    }

    #[test]
    fn frames_that_stop_on_the_ground_disarm_at_once() {
        let (link, report, vehicle) = fly_with(Fault::FramesOnGround);
        let reaction = link.reaction_s.expect("a failsafe answer while silent");
        assert!(
            reaction <= 0.1,
            "reacted {reaction:.3} s after the last frame"
        );
        assert!(!link.last_answer_armed && vehicle.finished());
        assert!(report.disarmed);
        assert!(link.max_height_m < 0.1, "never left the ground");
    }

    #[test]
    fn frames_that_come_back_hand_the_descent_back_to_the_loops() {
        let (link, report, vehicle) = fly_with(Fault::Frames {
            after_s: 2.0,
            for_s: 1.5,
        });
        assert!(link.reaction_s.is_some_and(|r| r <= 0.1));
        assert_eq!(report.sensor_timeouts, 1);
        assert!(
            link.now_s() < link.began_s.unwrap() + 20.0,
            "descended instead of hovering"
        );
        assert!(link.sim.truth().landed && vehicle.finished());
        assert!(
            link.touchdown_m_s <= 1.0,
            "touchdown at {:.2} m/s",
            link.touchdown_m_s
        );
        assert!(
            link.max_tilt_closed_loop_deg <= 5.0,
            "level a second after the frames came back: {:.1}°",
            link.max_tilt_closed_loop_deg
        );
    }

    /// A simulator that stops in the air and starts again (a new world, its clock from zero):
    /// the silence is met by the blind descent; the frames of the new world make the vehicle
    /// start afresh (disarmed, estimator aligning) and fly again — here the auto flight: take
    /// off, hover, land — without the daemon restarting.
    #[test]
    fn a_simulator_restarted_in_flight_restarts_the_vehicle_which_flies_again() {
        let (link, report, vehicle) = fly_with(Fault::SimRestart);
        assert!(link.restarted, "the simulator was restarted");
        assert!(link.reaction_s.is_some(), "the silence was answered");
        assert_eq!(report.sensor_timeouts, 1);
        assert_eq!(vehicle.source_restarts(), 1);
        assert!(
            link.max_height_m > 4.5,
            "flew again: {:.2} m",
            link.max_height_m
        );
        let truth = link.sim.truth();
        assert!(
            truth.landed && report.disarmed,
            "landed and disarmed in the new world"
        );
        assert!(link.touchdown_m_s < 1.0, "{:.2} m/s", link.touchdown_m_s);
    }

    /// A frozen IMU leaves the frames coming: the monitor finds the repeated reading (0.2 s),
    /// the loops stop and the blind descent of silent frames flies the vehicle down. What is
    /// asserted holds for the silent frames too: on the ground upright, motors stopped.
    #[test]
    fn an_imu_that_freezes_in_the_air_starts_the_blind_descent() {
        let mut descents = Vec::new();
        for seed in 2..=6 {
            let (link, report, vehicle) = fly_seed(Fault::ImuFrozen, seed);
            let began = link.began_s.unwrap();
            assert_eq!(report.sensor_timeouts, 0, "the frames kept coming");
            assert!(link.now_s() < began + 20.0, "seed {seed}: came down");
            assert!(report.disarmed);
            descents.push(assert_came_down_blind(&link, &vehicle, seed));
        }
        assert_typical_blind_descents(&mut descents);
    }

    /// Without GPS the vehicle holds the level its accelerometer shows, which is off by the
    /// accelerometer's horizontal bias over g (no estimator separates the two in a hover at
    /// one heading): it drifts at most as that bias accelerates it for the descent, plus the
    /// speed it had when the GPS stopped. A tilt held from before would drift tens of metres.
    #[test]
    fn gps_that_stops_in_the_air_levels_and_descends_on_the_barometer() {
        for seed in 1..=5 {
            let (link, report, vehicle) = fly_seed(Fault::Gps, seed);
            let began = link.began_s.unwrap();
            let descent_s = link.now_s() - began;
            assert!(
                descent_s < 20.0,
                "seed {seed}: descended instead of hovering 30 s"
            );
            assert_eq!(report.sensor_timeouts, 0, "the frames kept coming");
            assert!(link.sim.truth().landed && vehicle.finished());
            assert!(report.disarmed);
            assert!(
                link.touchdown_m_s <= 1.0,
                "seed {seed}: touchdown at {:.2} m/s",
                link.touchdown_m_s
            );
            assert!(link.max_tilt_after_deg <= 5.0);
            let bias_drift_m = 0.5 * link.sim.accel_bias().xy().norm() * descent_s.powi(2);
            assert!(
                link.max_drift_after_m <= bias_drift_m + 1.0,
                "seed {seed}: drifted {:.2} m ({bias_drift_m:.2} m from the accelerometer bias)",
                link.max_drift_after_m
            );
        }
    }

    /// A link that fails after `frames` frames: a vehicle whose flight ends in error.
    struct FailingLink {
        sim: EmbeddedSim,
        frames: u32,
    }

    impl SensorLink for FailingLink {
        fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> io::Result<bool> {
            if self.frames == 0 {
                return Err(io::Error::other("the simulator went away"));
            }
            self.frames -= 1;
            self.sim.receive(timeout, into)
        }
        fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
            self.sim.send(bytes)
        }
        fn describe(&self) -> String {
            "failing".into()
        }
        fn silence_clock_s(&self) -> Option<f64> {
            None
        }
    }

    /// A quad that takes off to 3 m, hovers 2 s and lands, flying with the seed's sensors.
    fn swarm_member(seed: u64) -> (Vehicle, EmbeddedSim, Ports) {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
        let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
        let mut params = FlightParams::load(&dir.join("flight.toml")).unwrap();
        crate::link::Source::Embedded.preset_params(&mut params);
        let auto = crate::vehicle::AutoFlight {
            takeoff_m: 3.0,
            hover_s: 2.0,
        };
        let vehicle = Vehicle::new(&airframe, &params, Some(auto)).unwrap();
        let sim = EmbeddedSim::new(&airframe, seed, SensorPreset::Typical, None, None).unwrap();
        (vehicle, sim, Ports::new(4).0)
    }

    /// Ten vehicles in lockstep on one clock: every round each vehicle still flying takes one
    /// frame, so each flies exactly the flight it flies alone (the same frames, the same
    /// figures to the bit), all land, and one whose link fails ends in error while the others
    /// fly on.
    #[test]
    fn ten_vehicles_fly_together_on_one_clock_each_as_it_flies_alone() {
        let mut members: Vec<_> = (1..=10).map(swarm_member).collect();
        let (mut failing_vehicle, sim, mut failing_ports) = swarm_member(11);
        let mut failing = FailingLink { sim, frames: 500 };
        let mut all: Vec<Member<'_>> = members
            .iter_mut()
            .enumerate()
            .map(|(k, (vehicle, sim, ports))| Member {
                link: sim,
                vehicle,
                ports,
                system_id: k as u8 + 1,
            })
            .collect();
        all.push(Member {
            link: &mut failing,
            vehicle: &mut failing_vehicle,
            ports: &mut failing_ports,
            system_id: 11,
        });
        let swarm = fly_together(all, EXCHANGE_HZ, None);
        assert_eq!(swarm.flights.len(), 11);
        let err = swarm.flights[10].as_ref().unwrap_err();
        assert!(format!("{err:#}").contains("went away"), "{err:#}");
        let mut longest = 0;
        for (k, flight) in swarm.flights[..10].iter().enumerate() {
            let r = flight.as_ref().unwrap();
            eprintln!("{r}");
            assert!(r.landed(), "vehicle {} landed", k + 1);
            assert!(
                (2.7..=3.5).contains(&r.score.max_height_m),
                "vehicle {}: {:.2} m",
                k + 1,
                r.score.max_height_m
            );
            longest = longest.max(r.frames);
        }
        assert_eq!(swarm.rounds, longest, "one frame per vehicle per round");
        assert!((swarm.sim_time_s - longest as f64 / EXCHANGE_HZ).abs() < 1e-9);
        for seed in [1, 7] {
            let (mut vehicle, mut sim, mut ports) = swarm_member(seed);
            let alone = fly(&mut sim, &mut vehicle, 1, &mut ports, Pacing::Lockstep).unwrap();
            let together = swarm.flights[seed as usize - 1].as_ref().unwrap();
            assert_eq!(alone.frames, together.frames, "seed {seed}");
            assert_eq!(alone.score.max_height_m, together.score.max_height_m);
            assert_eq!(alone.score.touchdown_m_s, together.score.touchdown_m_s);
            assert_eq!(
                alone.score.attitude_rms_deg(),
                together.score.attitude_rms_deg()
            );
        }
    }
}
