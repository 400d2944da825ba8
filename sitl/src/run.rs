//! The simulation loops: open-loop script, and the HIL link in lockstep or real time.

use crate::jsbsim::{Jsbsim, Launch};
use crate::tcp::TcpTransport;
use crate::transport::{Link, Peer, SerialTransport, Transport, UdpTransport};
use crate::{Mode, Physics, SitlCli};
use anyhow::{Context, Result, bail};
use hil::SimulatorEnd;
use sitl_core::airframe::MAX_ROTORS;
use sitl_core::scenario::{OpenLoopCommand, Scenario};
use sitl_core::sim::Simulator;
use sitl_core::truth_csv::TruthCsv;
use std::fmt;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

mod hil_loop;
pub use hil_loop::hil;

/// Everything a run counted, printed at the end as one `key=value` line.
#[derive(Debug, Default)]
pub struct Summary {
    sim_time_s: f64,
    wall_time_s: f64,
    steps: u64,
    pub(crate) frames_sent: u64,
    pub(crate) actuator_messages: u64,
    pub(crate) lockstep_timeouts: u64,
    pub(crate) malformed: u64,
    pub(crate) stale: u64,
    pub(crate) other_messages: u64,
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

/// `addr` with its port offset by `instance` times `stride` (the ports of instance N).
pub(crate) fn with_instance(
    mut addr: std::net::SocketAddr,
    instance: u16,
    stride: u16,
    flag: &str,
) -> Result<std::net::SocketAddr> {
    if addr.port() == 0 {
        // Any free port (the bound one is printed), never offset.
        return Ok(addr);
    }
    let port = instance
        .checked_mul(stride)
        .and_then(|offset| addr.port().checked_add(offset));
    addr.set_port(port.with_context(|| format!("--instance pushes the {flag} port past 65535"))?);
    Ok(addr)
}

pub(crate) fn build(scenario: &Scenario) -> Result<Simulator> {
    let mut sim = Simulator::new(&scenario.airframe, scenario.sim.clone(), scenario.initial)?;
    sim.schedule(&scenario.events)?;
    if scenario.rotors_at_hover {
        let hover = sim.hover_speeds();
        sim.set_rotor_speeds(&hover);
    }
    Ok(sim)
}

/// Who moves the rigid body this run.
pub(crate) enum Dynamics {
    /// The simulator's own integrator.
    Builtin,
    /// JSBSim, in its bridge process.
    Jsbsim(Box<Jsbsim>),
}

impl Dynamics {
    /// Starts what `--physics` names for `sim` (JSBSim at the physics rate, from the scenario's
    /// initial state).
    pub(crate) fn start(cli: &SitlCli, scenario: &Scenario, sim: &Simulator) -> Result<Self> {
        match cli.physics {
            Physics::Builtin => Ok(Self::Builtin),
            Physics::Jsbsim => {
                let rate_hz = 1.0 / sim.config().dt_s;
                let jsb = Jsbsim::launch(&Launch {
                    python: &cli.jsbsim_python,
                    airframe: sim.airframe(),
                    home: sim.config().home,
                    initial: scenario.initial,
                    rate_hz,
                    startup_timeout: Duration::from_secs(60),
                    step_timeout: Duration::from_secs(5),
                })?;
                tracing::info!(
                    rate_hz,
                    frames_per_step = sitl_core::jsbsim::frames_per_step(rate_hz),
                    "JSBSim running"
                );
                Ok(Self::Jsbsim(Box::new(jsb)))
            }
        }
    }

    /// One physics step under `controls`.
    pub(crate) fn step(&mut self, sim: &mut Simulator, controls: &[f64]) -> Result<()> {
        match self {
            Self::Builtin => {
                sim.step(controls);
                Ok(())
            }
            Self::Jsbsim(jsb) => Ok(sim.step_with(controls, jsb.as_mut())?),
        }
    }
}

pub(crate) fn finish(sim: &Simulator, started: Instant, mut s: Summary) -> Summary {
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
pub(crate) struct Status {
    interval_usec: u64,
    next_usec: u64,
    header_done: bool,
}

impl Status {
    pub(crate) fn new(interval_s: f64) -> Self {
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

    pub(crate) fn maybe_print(&mut self, sim: &Simulator, started: Instant) {
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

/// Waiting for the first word from an autopilot: said every 5 s, given up after
/// `--connect-timeout`.
pub(crate) struct AwaitAutopilot {
    started: Instant,
    said: Option<Instant>,
}

impl AwaitAutopilot {
    /// Waiting since `started`.
    pub(crate) fn new(started: Instant) -> Self {
        Self {
            started,
            said: None,
        }
    }

    /// Another wait went unanswered; `at` says where the autopilot is awaited.
    pub(crate) fn unanswered(&mut self, cli: &SitlCli, at: &str) -> Result<()> {
        if cli.connect_timeout > 0.0 && self.started.elapsed().as_secs_f64() > cli.connect_timeout {
            bail!(
                "no autopilot answered at {at} within {:.1} s",
                cli.connect_timeout
            );
        }
        if self
            .said
            .is_none_or(|t| t.elapsed() > Duration::from_secs(5))
        {
            tracing::info!("waiting for an autopilot at {at}");
            self.said = Some(Instant::now());
        }
        Ok(())
    }
}

/// Paces simulated time against the wall clock at a factor, by absolute deadlines.
pub(crate) struct Pacer {
    start: Instant,
    factor: Option<f64>,
    /// When a resume from now was last said (said at most every 10 s).
    said: Option<Instant>,
}

/// Behind its deadline by more than this (wall time), the pace starts again from now: a process
/// stopped (Ctrl-Z, a debugger, a suspended machine) or starved resumes where it is, not with
/// the missed time replayed in a burst, which an autopilot would meet as seconds of frames
/// with its last command held. Scheduling delays below it are caught up.
const RESUME_AFTER: Duration = Duration::from_millis(250);

impl Pacer {
    /// Sim time 0 due at `start`, `factor` times real time (`None`: as fast as it goes).
    pub(crate) fn new(start: Instant, factor: Option<f64>) -> Self {
        Self {
            start,
            factor,
            said: None,
        }
    }

    /// Paces from now on as if `sim_time_s` were due now (time spent waiting for an autopilot
    /// is not caught up in a burst).
    pub(crate) fn restart_at(&mut self, sim_time_s: f64) {
        if let Some(f) = self.factor {
            let now = Instant::now();
            self.start = now
                .checked_sub(Duration::from_secs_f64(sim_time_s / f))
                .unwrap_or(now);
        }
    }

    /// Sleeps until `sim_time_s` is due; far behind ([`RESUME_AFTER`]), paces from now on.
    pub(crate) fn wait_until(&mut self, sim_time_s: f64) {
        if let Some(f) = self.factor {
            let due = self.start + Duration::from_secs_f64(sim_time_s / f);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            } else if now - due > RESUME_AFTER {
                if self.said.is_none_or(|t| now - t > Duration::from_secs(10)) {
                    tracing::warn!(
                        behind_s = format!("{:.2}", (now - due).as_secs_f64()),
                        sim_time_s = format!("{sim_time_s:.3}"),
                        "behind the wall clock (stopped or starved): going on from now, the \
                         missed time not replayed"
                    );
                    self.said = Some(now);
                }
                self.restart_at(sim_time_s);
            }
        }
    }
}

pub(crate) fn open_truth(cli: &SitlCli, sim: &Simulator) -> Result<Option<TruthCsv>> {
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
    cli: &SitlCli,
    speed: Option<f64>,
    stop: &AtomicBool,
) -> Result<Summary> {
    let mut sim = build(scenario)?;
    let mut dynamics = Dynamics::start(cli, scenario, &sim)?;
    let mut truth = open_truth(cli, &sim)?;
    let started = Instant::now();
    let mut pacer = Pacer::new(started, speed);
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
        dynamics.step(&mut sim, &u[..n])?;
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
