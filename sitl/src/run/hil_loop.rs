//! The HIL loop: sensor frames to the autopilot over UDP, a serial line or PX4's TCP, its
//! actuator commands back, in lockstep or real time.

use super::*;
use sitl_core::sensors::SensorKind;

/// The link to the autopilot the command line names: a serial line, PX4's TCP, or UDP (the
/// default); and what to call it.
fn open_transport(cli: &SitlCli) -> Result<(Box<dyn Transport>, String)> {
    Ok(match (&cli.serial, cli.tcp) {
        (Some(path), _) => {
            let t = SerialTransport::open(path, cli.baud)?;
            let name = t.name().to_owned();
            // Scripts read this line to learn the device of a new pseudo-terminal.
            println!("sitl serial: {name}");
            (Box::new(t), name)
        }
        (None, Some(addr)) => {
            let t = TcpTransport::listen(with_instance(addr, cli.instance, 1, "--tcp")?)?;
            let at = t.local_addr()?;
            // Scripts read this line to learn the port (`--tcp 127.0.0.1:0` takes a free one).
            println!("sitl tcp: {at}");
            (Box::new(t), format!("TCP {at}"))
        }
        (None, None) => {
            let target = with_instance(cli.autopilot, cli.instance, 1, "--autopilot")?;
            let t = UdpTransport::new(cli.bind, target)?;
            tracing::info!(local = %t.local_addr()?, "UDP bound");
            (Box::new(t), target.to_string())
        }
    })
}

/// The weather control port, if the command line opens one.
fn open_control(cli: &SitlCli, scenario: &Scenario) -> Result<Option<hil::control::Control>> {
    Ok(match cli.control {
        Some(addr) => {
            let addr = with_instance(addr, cli.instance, 1, "--control")?;
            let c = hil::control::Control::bind(
                addr,
                &scenario.sim.wind,
                scenario.sim.calibration_hand,
            )
            .with_context(|| format!("binding --control {addr}"))?;
            let local = c.local_addr()?;
            tracing::info!(control = %local, "weather control listening");
            // Scripts read this line to learn the port (a port 0 is the system's choice).
            println!("sitl control: udp://{local}");
            Some(c)
        }
        None => None,
    })
}

/// Runs behind the HIL link.
pub fn hil(
    scenario: &Scenario,
    cli: &SitlCli,
    speed: Option<f64>,
    stop: &AtomicBool,
) -> Result<Summary> {
    let sim = build(scenario)?;
    let mut dynamics = Dynamics::start(cli, scenario, &sim)?;
    let mut truth = open_truth(cli, &sim)?;
    let mut end = SimulatorEnd::new(sim, cli.hil_rate);
    let mut gps = match &cli.gps_device {
        Some(spec) => {
            let d = crate::gps_device::GpsDevice::open(spec)?;
            // Scripts read this line to learn the GPS's device.
            println!("sitl gps: {}", d.name());
            end.set_hil_gps(false);
            Some(d)
        }
        None => None,
    };
    let mut rc = match &cli.rc_device {
        Some(spec) => {
            let d = crate::rc_device::RcDevice::open(spec)?;
            // Scripts read this line to learn the RC receiver's device.
            println!("sitl rc: {}", d.name());
            Some(d)
        }
        None => None,
    };
    let (transport, target) = open_transport(cli)?;
    tracing::info!(
        airframe = %end.sim().airframe().name, autopilot = %target,
        mode = ?cli.mode, physics = ?cli.physics, physics_hz = 1.0 / end.sim().config().dt_s, exchange_hz = end.exchange_hz(),
        "simulator ready"
    );
    let started = Instant::now();
    let mut status = Status::new(cli.status_interval);
    let mut control = open_control(cli, scenario)?;
    let mut x = Exchange::new(cli, target, Link::new(transport), started, speed);
    while end.sim().time_s() < scenario.duration_s - 1e-9 && !stop.load(Ordering::Relaxed) {
        if !x.autopilot_there(&end)? {
            continue;
        }
        if let Some(interval) = x.link.take_state_interval() {
            end.set_state_interval(interval);
        }
        status.maybe_print(end.sim(), started);
        if let Some(c) = control.as_mut() {
            for action in c.poll(end.sim()) {
                end.sim_mut().apply(action);
            }
        }
        if cli.mode == Mode::Lockstep {
            // A cap, if `--speed` gives one: the frame waits for its wall-clock time.
            x.pacer.wait_until(end.sim().time_s());
        }
        if let Some(g) = gps.as_mut() {
            // Before the frame: the autopilot reads the device when the frame arrives.
            let health = end.sim().sensors().health_of(SensorKind::Gps);
            g.step(end.frame().gps.as_ref(), health)?;
        }
        if let Some(r) = rc.as_mut() {
            let t_s = end.sim().time_s();
            r.step(t_s, &scenario.pilot.at(t_s))?;
        }
        x.link.out.clear();
        let time_usec = end.encode_frame(&mut x.link.out);
        x.link.send()?;
        x.summary.frames_sent += 1;
        let waited = x.wait_for_answer(time_usec, &end)?;
        if !x.answered(waited, time_usec, &mut end)? {
            continue;
        }
        let record = |sim: &Simulator| -> Result<()> {
            match truth.as_mut() {
                Some(csv) => Ok(csv.record(&sim.truth(), sim.rotor_speeds())?),
                None => Ok(()),
            }
        };
        match cli.mode {
            Mode::Lockstep => end.advance_with(|sim, u| dynamics.step(sim, u), record)?,
            Mode::Realtime => {
                // Each physics step at its own wall time, with the newest answer there is.
                end.advance_live(
                    |t_s| x.latest_answer(t_s),
                    |sim, u| dynamics.step(sim, u),
                    record,
                )?;
                x.pacer.wait_until(end.sim().time_s());
            }
        }
    }
    status.maybe_print(end.sim(), started);
    if let Some(mut csv) = truth {
        csv.flush()?;
    }
    Ok(finish(end.sim(), started, x.summary))
}

/// What the HIL loop keeps between its exchanges with the autopilot: the link, the pacing, the
/// counts, and whether (and how) the autopilot answers.
struct Exchange<'a> {
    cli: &'a SitlCli,
    /// Who the autopilot is, in words.
    target: String,
    link: Link,
    /// The frames' pace against the wall clock (`--speed`), and, while PX4 boots, real time.
    pacer: Pacer,
    boot_pacer: Pacer,
    summary: Summary,
    /// The autopilot has answered since it (re)appeared.
    connected: bool,
    /// How long a lockstep frame waits for its answer.
    timeout: Duration,
    last_timeout_log: Option<Instant>,
    awaiting: AwaitAutopilot,
    /// PX4's simulator interface (TCP): its first word starts the sensor stream, and the clock
    /// runs in real time until its first answer, as PX4 boots on the simulator's clock.
    boots_in_real_time: bool,
}

impl<'a> Exchange<'a> {
    fn new(
        cli: &'a SitlCli,
        target: String,
        link: Link,
        started: Instant,
        speed: Option<f64>,
    ) -> Self {
        Self {
            cli,
            target,
            link,
            pacer: Pacer::new(started, speed),
            boot_pacer: Pacer::new(started, Some(speed.unwrap_or(1.0))),
            summary: Summary::default(),
            connected: false,
            timeout: Duration::from_millis(cli.timeout_ms.max(1)),
            last_timeout_log: None,
            awaiting: AwaitAutopilot::new(started),
            boots_in_real_time: cli.tcp.is_some(),
        }
    }

    /// Whether an autopilot is there to send the frame to (false: physics waits).
    fn autopilot_there(&mut self, end: &SimulatorEnd) -> Result<bool> {
        match self.link.peer(Duration::from_millis(200))? {
            Peer::Absent => {
                self.awaiting.unanswered(self.cli, &self.target)?;
                return Ok(false); // nobody connected: physics waits
            }
            Peer::New => {
                self.connected = false;
                self.pacer.restart_at(end.sim().time_s());
            }
            Peer::There => {}
        }
        if self.boots_in_real_time && !self.connected && self.link.heard == 0 {
            if !self
                .link
                .listen(Duration::from_millis(200), &mut self.summary)?
            {
                self.awaiting.unanswered(self.cli, &self.target)?;
                return Ok(false);
            }
            tracing::info!("autopilot heard: sensor frames in real time until its first command");
            self.boot_pacer.restart_at(end.sim().time_s());
        }
        Ok(true)
    }

    /// The answer to the frame of `time_usec`, as the mode takes it.
    fn wait_for_answer(
        &mut self,
        time_usec: u64,
        end: &SimulatorEnd,
    ) -> Result<Option<::hil::ActuatorCommand>> {
        Ok(match self.cli.mode {
            Mode::Lockstep if self.boots_in_real_time && !self.connected => {
                self.boot_pacer.wait_until(end.sim().time_s());
                self.link.drain(&mut self.summary)?
            }
            Mode::Lockstep => {
                let wait = if self.connected {
                    self.timeout
                } else {
                    Duration::from_millis(200)
                };
                self.link.wait_for(time_usec, wait, &mut self.summary)?
            }
            // Answers are taken between the physics steps, as they arrive.
            Mode::Realtime => None,
        })
    }

    /// The answer (or its absence) applied; false when the frame is to be sent again, physics
    /// waiting.
    fn answered(
        &mut self,
        waited: Option<::hil::ActuatorCommand>,
        time_usec: u64,
        end: &mut SimulatorEnd,
    ) -> Result<bool> {
        let lockstep = self.cli.mode == Mode::Lockstep;
        match waited {
            Some(cmd) => {
                if !self.connected {
                    tracing::info!("autopilot answered: lockstep running");
                    self.pacer.restart_at(end.sim().time_s());
                }
                self.connected = true;
                end.apply(&cmd);
            }
            // The autopilot went away: physics waits for the next one.
            None if self.link.gone() => return Ok(false),
            None if lockstep && !self.connected && self.boots_in_real_time => {
                self.awaiting.unanswered(self.cli, &self.target)?; // and physics steps on: the clock runs
            }
            None if lockstep && !self.connected => {
                self.awaiting.unanswered(self.cli, &self.target)?;
                return Ok(false); // resend the same frame; physics waits
            }
            None if lockstep => {
                self.summary.lockstep_timeouts += 1;
                if self
                    .last_timeout_log
                    .is_none_or(|t| t.elapsed() > Duration::from_secs(1))
                {
                    tracing::warn!(
                        total = self.summary.lockstep_timeouts,
                        "lockstep timeout: no HIL_ACTUATOR_CONTROLS for t = {time_usec} us within {:?}; stepping with the last command",
                        self.timeout
                    );
                    self.last_timeout_log = Some(Instant::now());
                }
            }
            None => {}
        }
        Ok(true)
    }

    /// In real time, before the physics step at `t_s` (its wall time waited for): the newest
    /// answer there is.
    fn latest_answer(&mut self, t_s: f64) -> Result<Option<::hil::ActuatorCommand>> {
        self.pacer.wait_until(t_s);
        let latest = self.link.drain(&mut self.summary)?;
        if latest.is_some() && !self.connected {
            tracing::info!("autopilot answering");
            self.connected = true;
        }
        Ok(latest)
    }
}
