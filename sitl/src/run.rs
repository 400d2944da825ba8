//! The simulation loops: open-loop script, and the HIL link in lockstep or real time.

use crate::{Cli, Mode};
use anyhow::{Context, Result, bail};
use hil::{ActuatorCommand, SimulatorEnd};
use mavlink::dialects::common::MavMessage;
use sitl_core::airframe::MAX_ROTORS;
use sitl_core::scenario::{OpenLoopCommand, Scenario};
use sitl_core::sim::Simulator;
use sitl_core::truth_csv::TruthCsv;
use std::fmt;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Everything a run counted, printed at the end as one `key=value` line.
#[derive(Debug, Default)]
pub struct Summary {
    sim_time_s: f64,
    wall_time_s: f64,
    steps: u64,
    frames_sent: u64,
    actuator_messages: u64,
    lockstep_timeouts: u64,
    malformed: u64,
    stale: u64,
    other_messages: u64,
    clamped: u64,
    nonfinite: u64,
    touchdowns: u64,
    last_touchdown_speed_m_s: f64,
    final_ned_m: [f64; 3],
    landed: bool,
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "sitl summary: sim_time_s={:.3} wall_time_s={:.3} realtime_factor={:.1} steps={} \
             frames_sent={} actuator_messages={} lockstep_timeouts={} malformed={} stale={} \
             other_messages={} clamped_commands={} nonfinite_commands={} touchdowns={} \
             last_touchdown_speed_m_s={:.3} final_n_m={:.3} final_e_m={:.3} final_d_m={:.3} landed={}",
            self.sim_time_s,
            self.wall_time_s,
            self.sim_time_s / self.wall_time_s.max(1e-9),
            self.steps,
            self.frames_sent,
            self.actuator_messages,
            self.lockstep_timeouts,
            self.malformed,
            self.stale,
            self.other_messages,
            self.clamped,
            self.nonfinite,
            self.touchdowns,
            self.last_touchdown_speed_m_s,
            self.final_ned_m[0],
            self.final_ned_m[1],
            self.final_ned_m[2],
            self.landed
        )
    }
}

fn build(scenario: &Scenario) -> Result<Simulator> {
    let mut sim = Simulator::new(&scenario.airframe, scenario.sim.clone(), scenario.initial)?;
    sim.schedule(&scenario.events)?;
    if scenario.rotors_at_hover {
        let hover = sim.hover_speeds();
        sim.set_rotor_speeds(&hover);
    }
    Ok(sim)
}

fn finish(sim: &Simulator, started: Instant, mut s: Summary) -> Summary {
    let st = sim.stats();
    let t = sim.truth();
    s.sim_time_s = sim.time_s();
    s.wall_time_s = started.elapsed().as_secs_f64();
    s.steps = st.steps;
    s.clamped = st.clamped_commands;
    s.nonfinite = st.nonfinite_commands;
    s.touchdowns = st.touchdowns;
    s.last_touchdown_speed_m_s = st.last_touchdown_speed_m_s;
    s.final_ned_m = t.body.pos_ned_m.into();
    s.landed = t.landed;
    s
}

/// Prints one status line per `interval` simulated seconds.
struct Status {
    interval_usec: u64,
    next_usec: u64,
    header_done: bool,
}

impl Status {
    fn new(interval_s: f64) -> Self {
        Self {
            interval_usec: if interval_s > 0.0 {
                (interval_s * 1e6) as u64
            } else {
                u64::MAX
            },
            next_usec: 0,
            header_done: false,
        }
    }

    fn maybe_print(&mut self, sim: &Simulator, started: Instant) {
        let t = sim.truth();
        if self.interval_usec == u64::MAX || t.time_usec < self.next_usec {
            return;
        }
        self.next_usec = t.time_usec + self.interval_usec;
        if !self.header_done {
            println!(
                "{:>7} {:>8} {:>7} {:>7} {:>7} {:>7} {:>8} {:>6} {:>6} {:>6}",
                "t_s",
                "alt_m",
                "vd_m/s",
                "roll°",
                "pitch°",
                "yaw°",
                "rpm_avg",
                "batt_V",
                "landed",
                "x_rt"
            );
            self.header_done = true;
        }
        let (r, p, y) = t.body.q_ned_from_frd.euler_angles();
        let speeds = sim.rotor_speeds();
        let rpm = speeds.iter().sum::<f64>() / speeds.len() as f64 * 60.0 / std::f64::consts::TAU;
        println!(
            "{:7.2} {:8.3} {:7.3} {:7.2} {:7.2} {:7.2} {:8.0} {:6.2} {:>6} {:6.1}",
            sim.time_s(),
            -t.body.pos_ned_m.z,
            t.body.vel_ned_m_s.z,
            r.to_degrees(),
            p.to_degrees(),
            y.to_degrees(),
            rpm,
            t.battery_voltage_v,
            t.landed,
            sim.time_s() / started.elapsed().as_secs_f64().max(1e-9)
        );
    }
}

/// Paces simulated time against the wall clock at a factor, by absolute deadlines.
struct Pacer {
    start: Instant,
    factor: Option<f64>,
}

impl Pacer {
    fn wait_until(&self, sim_time_s: f64) {
        if let Some(f) = self.factor {
            let due = self.start + Duration::from_secs_f64(sim_time_s / f);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
    }
}

fn open_truth(cli: &Cli, sim: &Simulator) -> Result<Option<TruthCsv>> {
    cli.truth_csv
        .as_ref()
        .map(|p| {
            TruthCsv::create(p, cli.truth_rate, sim.airframe().rotors.len())
                .with_context(|| format!("creating truth CSV {}", p.display()))
        })
        .transpose()
}

/// Flies the scenario's open-loop script.
pub fn open_loop(
    scenario: &Scenario,
    cli: &Cli,
    speed: Option<f64>,
    stop: &AtomicBool,
) -> Result<Summary> {
    let mut sim = build(scenario)?;
    let mut truth = open_truth(cli, &sim)?;
    let started = Instant::now();
    let pacer = Pacer {
        start: started,
        factor: if cli.mode == Mode::Realtime {
            speed
        } else {
            None
        },
    };
    let mut status = Status::new(cli.status_interval);
    let n = sim.airframe().rotors.len();
    let mut u = [0.0; MAX_ROTORS];
    while sim.time_s() < scenario.duration_s - 1e-9 && !stop.load(Ordering::Relaxed) {
        status.maybe_print(&sim, started);
        match scenario.open_loop_at(sim.time_s()) {
            Some(OpenLoopCommand::Throttle(x)) => u[..n].fill(*x),
            Some(OpenLoopCommand::HoverDelta(d)) => {
                let hover = sim.hover_commands();
                for i in 0..n {
                    u[i] = hover[i] + d;
                }
            }
            Some(OpenLoopCommand::Controls(c)) => u[..n].copy_from_slice(c),
            None => u.fill(0.0),
        }
        sim.step(&u[..n]);
        sim.sample_sensors();
        if let Some(csv) = truth.as_mut() {
            csv.record(&sim.truth(), sim.rotor_speeds())?;
        }
        pacer.wait_until(sim.time_s());
    }
    status.maybe_print(&sim, started);
    if let Some(mut csv) = truth {
        csv.flush()?;
    }
    Ok(finish(&sim, started, Summary::default()))
}

/// Runs behind the HIL link.
pub fn hil(
    scenario: &Scenario,
    cli: &Cli,
    speed: Option<f64>,
    stop: &AtomicBool,
) -> Result<Summary> {
    let sim = build(scenario)?;
    let mut truth = open_truth(cli, &sim)?;
    let socket = UdpSocket::bind(cli.bind).with_context(|| format!("binding {}", cli.bind))?;
    let mut target = cli.autopilot;
    target.set_port(
        target
            .port()
            .checked_add(cli.instance)
            .context("--instance pushes the autopilot port past 65535")?,
    );
    let mut end = SimulatorEnd::new(sim, cli.hil_rate);
    tracing::info!(
        airframe = %end.sim().airframe().name, autopilot = %target, local = %socket.local_addr()?,
        mode = ?cli.mode, physics_hz = 1.0 / end.sim().config().dt_s, exchange_hz = end.exchange_hz(),
        "simulator ready"
    );
    let started = Instant::now();
    let pacer = Pacer {
        start: started,
        factor: speed,
    };
    let mut status = Status::new(cli.status_interval);
    let mut summary = Summary::default();
    let mut link = Link::new(socket, target);
    let mut connected = false;
    let timeout = Duration::from_millis(cli.timeout_ms.max(1));
    let mut last_timeout_log: Option<Instant> = None;
    while end.sim().time_s() < scenario.duration_s - 1e-9 && !stop.load(Ordering::Relaxed) {
        status.maybe_print(end.sim(), started);
        link.out.clear();
        let time_usec = end.encode_frame(&mut link.out);
        link.send()?;
        summary.frames_sent += 1;
        let waited = match cli.mode {
            Mode::Lockstep => link.wait_for(
                time_usec,
                if connected {
                    timeout
                } else {
                    Duration::from_millis(200)
                },
                &mut summary,
            )?,
            Mode::Realtime => link.drain(&mut summary)?,
        };
        match waited {
            Some(cmd) => {
                if !connected {
                    tracing::info!("autopilot answered: lockstep running");
                }
                connected = true;
                end.apply(&cmd);
            }
            None if cli.mode == Mode::Lockstep && !connected => {
                let waited_s = started.elapsed().as_secs_f64();
                if cli.connect_timeout > 0.0 && waited_s > cli.connect_timeout {
                    bail!(
                        "no autopilot answered at {target} within {:.1} s",
                        cli.connect_timeout
                    );
                }
                if last_timeout_log.is_none_or(|t| t.elapsed() > Duration::from_secs(5)) {
                    tracing::info!("waiting for an autopilot at {target}");
                    last_timeout_log = Some(Instant::now());
                }
                continue; // resend the same frame; physics waits
            }
            None if cli.mode == Mode::Lockstep => {
                summary.lockstep_timeouts += 1;
                if last_timeout_log.is_none_or(|t| t.elapsed() > Duration::from_secs(1)) {
                    tracing::warn!(
                        total = summary.lockstep_timeouts,
                        "lockstep timeout: no HIL_ACTUATOR_CONTROLS for t = {time_usec} us within {timeout:?}; stepping with the last command",
                    );
                    last_timeout_log = Some(Instant::now());
                }
            }
            None => {}
        }
        end.advance(|sim| match truth.as_mut() {
            Some(csv) => csv.record(&sim.truth(), sim.rotor_speeds()),
            None => Ok(()),
        })?;
        if cli.mode == Mode::Realtime {
            pacer.wait_until(end.sim().time_s());
        }
    }
    status.maybe_print(end.sim(), started);
    if let Some(mut csv) = truth {
        csv.flush()?;
    }
    Ok(finish(end.sim(), started, summary))
}

/// The UDP side of the HIL link.
struct Link {
    socket: UdpSocket,
    target: SocketAddr,
    out: Vec<u8>,
    rx: Vec<u8>,
}

impl Link {
    fn new(socket: UdpSocket, target: SocketAddr) -> Self {
        Self {
            socket,
            target,
            out: Vec::with_capacity(1024),
            rx: vec![0; 65_536],
        }
    }

    /// Sends `out` (one exchange's messages) as one datagram.
    fn send(&mut self) -> Result<()> {
        match self.socket.send_to(&self.out, self.target) {
            Ok(_) => Ok(()),
            // Nobody listening yet (ICMP port unreachable): keep going, the autopilot may start later.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => Ok(()),
            Err(e) => Err(e).with_context(|| format!("sending to {}", self.target)),
        }
    }

    fn handle(
        &mut self,
        len: usize,
        time_usec: Option<u64>,
        s: &mut Summary,
        latest: &mut Option<ActuatorCommand>,
    ) -> bool {
        let decoded = hil::decode(&self.rx[..len]);
        s.malformed += decoded.malformed as u64;
        let mut matched = false;
        for (_, msg) in decoded.messages {
            match msg {
                MavMessage::HIL_ACTUATOR_CONTROLS(m) => {
                    s.actuator_messages += 1;
                    let cmd = hil::actuator_command(&m);
                    match time_usec {
                        Some(t) if cmd.time_usec != t => s.stale += 1,
                        _ => {
                            *latest = Some(cmd);
                            matched = true;
                        }
                    }
                }
                _ => s.other_messages += 1,
            }
        }
        matched
    }

    /// Lockstep: waits up to `timeout` for the command answering `time_usec`.
    fn wait_for(
        &mut self,
        time_usec: u64,
        timeout: Duration,
        s: &mut Summary,
    ) -> Result<Option<ActuatorCommand>> {
        let deadline = Instant::now() + timeout;
        let mut latest = None;
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            self.socket.set_read_timeout(Some(deadline - now))?;
            match self.socket.recv_from(&mut self.rx) {
                Ok((len, _)) => {
                    if self.handle(len, Some(time_usec), s, &mut latest) {
                        return Ok(latest);
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::Interrupted
                            | std::io::ErrorKind::ConnectionRefused
                    ) => {}
                Err(e) => return Err(e).context("receiving HIL_ACTUATOR_CONTROLS"),
            }
        }
    }

    /// Real time: takes whatever arrived, keeping the newest command.
    fn drain(&mut self, s: &mut Summary) -> Result<Option<ActuatorCommand>> {
        self.socket.set_nonblocking(true)?;
        let mut latest = None;
        loop {
            match self.socket.recv_from(&mut self.rx) {
                Ok((len, _)) => {
                    self.handle(len, None, s, &mut latest);
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                            | std::io::ErrorKind::ConnectionRefused
                    ) =>
                {
                    break;
                }
                Err(e) => return Err(e).context("receiving HIL_ACTUATOR_CONTROLS"),
            }
        }
        self.socket.set_nonblocking(false)?;
        Ok(latest)
    }
}
