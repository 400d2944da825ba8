//! The JSBSim back-end's process and link (`sitl --physics jsbsim`): writes the generated model
//! to a temporary root, starts JSBSim's console program on it, and steps it in lockstep, one
//! `set …`/`iterate 1` batch on its TCP command port per physics step and one state datagram
//! back on UDP. The model, the batch and the state lines are `sitl_core::jsbsim`'s.
//!
//! Traps this avoids (ARCHITECTURE.md, issue 8): the simulation rate is always given and `--nice`
//! never; the command port has no Nagle delay and its replies are drained without blocking; a
//! frame is taken by its counter, not by counting datagrams; nothing non-finite is sent; a step
//! that does not come back in time is an error that shows JSBSim's replies and its last words;
//! its console output is read for the whole run; on shutdown the TCP side closes first.

use anyhow::{Context, Result, bail};
use sitl_core::Airframe;
use sitl_core::body::BodyState;
use sitl_core::geo::Geodetic;
use sitl_core::jsbsim::{
    BridgeInputs, BridgePorts, FRAME_MODULUS, FrameFilter, FrameVerdict, MODEL_NAME, OutputLine,
    Replies, aircraft_xml, init_xml, parse_output,
};
use sitl_core::sim::{ExternalBody, ExternalBodyError, ExternalBodyStep, StepLoads};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream, UdpSocket};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

/// The line JSBSim prints when it is ready for commands.
const READY: &str = "JSBSim Execution beginning";
/// What it prints when its command port is taken.
const PORT_TAKEN: &str = "Could not bind";
/// Lines of JSBSim's console output kept for error reports.
const CONSOLE_LINES: usize = 30;

/// How to start JSBSim.
#[derive(Debug, Clone)]
pub struct Launch<'a> {
    /// JSBSim's console program (PyPI `jsbsim` installs it as `jsbsim`).
    pub program: &'a Path,
    /// The vehicle.
    pub airframe: &'a Airframe,
    /// The local NED origin: the rest position of the centre of mass.
    pub home: Geodetic,
    /// The start, in that frame.
    pub initial: BodyState,
    /// JSBSim's rate: one frame per physics step (Hz).
    pub rate_hz: f64,
    /// How long JSBSim may take to start.
    pub startup_timeout: Duration,
    /// How long one step may take before the run fails.
    pub step_timeout: Duration,
}

/// The link to a JSBSim that is up: its command port and its state datagrams, stepped in
/// lockstep. It is the rigid body, gravity and the ground of
/// [`sitl_core::sim::Simulator::step_with`].
pub struct Bridge {
    command: Option<TcpStream>,
    state: UdpSocket,
    origin: Geodetic,
    mass_kg: f64,
    rotors: usize,
    frames: FrameFilter,
    replies: Replies,
    step_timeout: Duration,
    rx: Vec<u8>,
}

impl Bridge {
    /// Connects to the command port on the loopback (retrying until `deadline`: JSBSim opens it
    /// a moment after saying it is ready); JSBSim streams to `state`. Positions are reported in
    /// the local NED frame of `origin`.
    pub fn connect(
        command_port: u16,
        state: UdpSocket,
        origin: Geodetic,
        airframe: &Airframe,
        step_timeout: Duration,
        deadline: Instant,
    ) -> Result<Self> {
        let command = loop {
            match TcpStream::connect((Ipv4Addr::LOCALHOST, command_port)) {
                Ok(s) => break s,
                Err(e) if Instant::now() < deadline => {
                    tracing::debug!("JSBSim's command port not open yet: {e}");
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => {
                    return Err(e).context(format!(
                        "connecting to JSBSim's command port {command_port}"
                    ));
                }
            }
        };
        // No Nagle: a batch goes out at once; replies are drained, never waited for.
        command.set_nodelay(true)?;
        command.set_nonblocking(true)?;
        state.set_read_timeout(Some(Duration::from_millis(50)))?;
        let mut bridge = Self {
            command: Some(command),
            state,
            origin,
            mass_kg: airframe.mass_kg,
            rotors: airframe.rotors.len(),
            frames: FrameFilter::default(),
            replies: Replies::default(),
            step_timeout,
            rx: vec![0; 65_536],
        };
        bridge.drain_replies()?;
        Ok(bridge)
    }

    /// Reads whatever the command port has answered, without waiting.
    fn drain_replies(&mut self) -> Result<()> {
        let Some(command) = self.command.as_mut() else {
            return Ok(());
        };
        let mut buf = [0u8; 4096];
        loop {
            match command.read(&mut buf) {
                Ok(0) => bail!("JSBSim closed its command port"),
                Ok(n) => self.replies.push(&buf[..n]),
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Ok(()),
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e).context("reading JSBSim's replies"),
            }
        }
    }

    /// Writes a batch on the non-blocking command port, draining replies while it is full.
    fn send(&mut self, batch: &[u8], deadline: Instant) -> std::result::Result<(), String> {
        let mut sent = 0;
        while sent < batch.len() {
            let Some(command) = self.command.as_mut() else {
                return Err("the command port is closed".into());
            };
            match command.write(&batch[sent..]) {
                Ok(0) => return Err("JSBSim closed its command port".into()),
                Ok(n) => sent += n,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::Interrupted) => {
                    if Instant::now() > deadline {
                        return Err("the command port stayed full".into());
                    }
                    self.drain_replies().map_err(|e| format!("{e:#}"))?;
                    std::thread::yield_now();
                }
                Err(e) => return Err(format!("writing to the command port: {e}")),
            }
        }
        Ok(())
    }

    /// Waits for the datagram of frame `next_frame`.
    fn receive(&mut self, deadline: Instant) -> std::result::Result<ExternalBodyStep, String> {
        loop {
            if Instant::now() > deadline {
                return Err(format!(
                    "no state for frame {} within {:?}",
                    self.frames.next(),
                    self.step_timeout
                ));
            }
            let len = match self.state.recv(&mut self.rx) {
                Ok(len) => len,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) =>
                {
                    // A refused `set` cancels the batch's iterate: no frame will come.
                    self.drain_replies().map_err(|e| format!("{e:#}"))?;
                    if !self.replies.errors.is_empty() {
                        return Err("it refused a command".into());
                    }
                    continue;
                }
                Err(e) => return Err(format!("receiving its state: {e}")),
            };
            let text = String::from_utf8_lossy(&self.rx[..len]);
            for line in text.lines().filter(|l| !l.trim().is_empty()) {
                let OutputLine::State(s) =
                    parse_output(line, self.mass_kg, &self.origin).map_err(|e| e.to_string())?
                else {
                    continue;
                };
                match self.frames.check(s.frame) {
                    FrameVerdict::Next => return Ok(s.body_step(&self.origin)),
                    // Each iterate first re-sends the frame before.
                    FrameVerdict::Stale => {}
                    FrameVerdict::Unexpected => {
                        return Err(format!(
                            "it sent frame {} (modulo {FRAME_MODULUS})",
                            s.frame
                        ));
                    }
                }
            }
        }
    }

    /// One step; on failure the reason and what the command port answered.
    fn step(&mut self, loads: &StepLoads) -> std::result::Result<ExternalBodyStep, String> {
        let deadline = Instant::now() + self.step_timeout;
        let batch = BridgeInputs::from_loads(loads, self.rotors)
            .encode()
            .map_err(|e| format!("refused to send {e}"))?;
        self.send(batch.as_bytes(), deadline)?;
        let step = self.receive(deadline)?;
        self.drain_replies().map_err(|e| format!("{e:#}"))?;
        if !self.replies.errors.is_empty() {
            return Err("it refused a command".into());
        }
        Ok(step)
    }

    /// Closes the command port (first, on shutdown, or it lingers in TIME_WAIT).
    fn close(&mut self) {
        if let Some(c) = self.command.take() {
            let _ = c.shutdown(std::net::Shutdown::Both);
        }
    }
}

impl ExternalBody for Bridge {
    fn advance(&mut self, loads: &StepLoads) -> Result<ExternalBodyStep, ExternalBodyError> {
        self.step(loads).map_err(|why| {
            let _ = self.drain_replies();
            ExternalBodyError(format!(
                "JSBSim at frame {}: {why}; its replies: {:?}",
                self.frames.next(),
                self.replies.errors
            ))
        })
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        self.close();
    }
}

/// A JSBSim process of our own, and the bridge to it.
pub struct Jsbsim {
    bridge: Bridge,
    child: Child,
    root: PathBuf,
    console: Arc<Mutex<VecDeque<String>>>,
}

/// Keeps the last lines of JSBSim's stdout or stderr, and passes them on while someone listens
/// (the start-up); reads until the stream closes, so JSBSim never blocks on a full pipe.
fn drain_console(
    stream: impl Read + Send + 'static,
    console: Arc<Mutex<VecDeque<String>>>,
    tx: mpsc::Sender<String>,
) {
    std::thread::spawn(move || {
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            if let Ok(mut c) = console.lock() {
                if c.len() == CONSOLE_LINES {
                    c.pop_front();
                }
                c.push_back(line.clone());
            }
            let _ = tx.send(line);
        }
    });
}

fn tail(console: &Mutex<VecDeque<String>>) -> String {
    console
        .lock()
        .map(|c| c.iter().cloned().collect::<Vec<_>>().join("\n  "))
        .unwrap_or_default()
}

/// Runs JSBSim (`$0 $@`) under a small `sh` that holds the read end of a pipe from `sitl`: when
/// `sitl` goes, however it goes (even SIGKILL, which no handler sees), the pipe closes and the
/// guardian stops JSBSim, which would otherwise run on, polling at full speed. The guardian drops
/// its own copies of the output pipes, so they close when JSBSim exits.
const GUARDIAN: &str = r#""$0" "$@" &
jsbsim=$!
exec >/dev/null 2>&1
read -r _ || true
kill "$jsbsim" 2>/dev/null
wait "$jsbsim""#;

/// Stops JSBSim through its guardian (closing the pipe), waiting a little, then for good.
fn stop(guardian: &mut Child) {
    drop(guardian.stdin.take());
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        if matches!(guardian.try_wait(), Ok(Some(_))) {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = guardian.kill();
    let _ = guardian.wait();
}

/// A free TCP port on the loopback (JSBSim binds it a moment later; a clash is retried).
fn free_tcp_port() -> Result<u16> {
    let l = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).context("finding a free TCP port")?;
    Ok(l.local_addr()?.port())
}

/// Why one start-up attempt failed.
enum Start {
    /// The command port was taken between finding it free and JSBSim binding it: try another.
    PortTaken(anyhow::Error),
    /// Anything else.
    Failed(anyhow::Error),
}

impl Jsbsim {
    /// Writes the model to a temporary root, starts JSBSim on it and connects; fails with
    /// JSBSim's own words when it does not come up.
    pub fn launch(l: &Launch) -> Result<Self> {
        let root = std::env::temp_dir().join(format!(
            "sitl-jsbsim-{}-{}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_nanos())
                .unwrap_or(0)
        ));
        let result = Self::launch_in(l, &root);
        if result.is_err() {
            let _ = std::fs::remove_dir_all(&root);
        }
        result
    }

    fn launch_in(l: &Launch, root: &Path) -> Result<Self> {
        let dir = root.join("aircraft").join(MODEL_NAME);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("creating JSBSim's root {}", dir.display()))?;
        std::fs::write(
            dir.join("start.xml"),
            init_xml(l.airframe, &l.home, &l.initial),
        )
        .context("writing JSBSim's start file")?;
        let mut last_error = None;
        for _attempt in 0..3 {
            let state =
                UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).context("binding JSBSim's state port")?;
            let ports = BridgePorts {
                command_tcp: free_tcp_port()?,
                state_udp: state.local_addr()?.port(),
            };
            std::fs::write(
                dir.join(format!("{MODEL_NAME}.xml")),
                aircraft_xml(l.airframe, &l.home, ports, l.rate_hz),
            )
            .context("writing JSBSim's aircraft model")?;
            match Self::start(l, root, ports, state) {
                Ok(jsb) => return Ok(jsb),
                Err(Start::PortTaken(e)) => last_error = Some(e),
                Err(Start::Failed(e)) => return Err(e),
            }
        }
        Err(last_error.unwrap_or_else(|| anyhow::anyhow!("JSBSim did not start")))
    }

    fn start(
        l: &Launch,
        root: &Path,
        ports: BridgePorts,
        state: UdpSocket,
    ) -> std::result::Result<Self, Start> {
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(GUARDIAN)
            .arg(l.program)
            // Its own process group: a Ctrl-C at the terminal reaches only `sitl`, which ends
            // its run cleanly and then stops JSBSim (SIGTERM and SIGHUP too).
            .process_group(0)
            .arg("--root")
            .arg(root)
            .args(["--aircraft", MODEL_NAME, "--initfile", "start"])
            .arg(format!("--simulation-rate={}", l.rate_hz))
            .arg("--suspend")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| {
                format!(
                    "starting the shell that runs JSBSim ({}) under guard",
                    l.program.display()
                )
            })
            .map_err(Start::Failed)?;
        let console = Arc::new(Mutex::new(VecDeque::new()));
        let (tx, rx) = mpsc::channel();
        if let Some(out) = child.stdout.take() {
            drain_console(out, console.clone(), tx.clone());
        }
        if let Some(err) = child.stderr.take() {
            drain_console(err, console.clone(), tx);
        }
        let fail = |child: &mut Child, why: String| {
            stop(child);
            anyhow::anyhow!("{why}; JSBSim said:\n  {}", tail(&console))
        };
        let deadline = Instant::now() + l.startup_timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok(line) if line.contains(READY) => break,
                Ok(line) if line.contains(PORT_TAKEN) => {
                    let why = format!("JSBSim's command port {} was taken", ports.command_tcp);
                    return Err(Start::PortTaken(fail(&mut child, why)));
                }
                Ok(_) => {}
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let why = format!("JSBSim not ready within {:?}", l.startup_timeout);
                    return Err(Start::Failed(fail(&mut child, why)));
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let why = format!(
                        "JSBSim exited during start-up (is {} JSBSim's console program? The \
                         pinned PyPI jsbsim==1.3.3 installs one; name it with --jsbsim)",
                        l.program.display()
                    );
                    return Err(Start::Failed(fail(&mut child, why)));
                }
            }
        }
        // From here on nobody listens: the readers only keep the tail.
        drop(rx);
        match Bridge::connect(
            ports.command_tcp,
            state,
            l.home,
            l.airframe,
            l.step_timeout,
            deadline,
        ) {
            Ok(bridge) => Ok(Self {
                bridge,
                child,
                root: root.to_owned(),
                console,
            }),
            Err(e) => Err(Start::Failed(fail(&mut child, format!("{e:#}")))),
        }
    }
}

impl ExternalBody for Jsbsim {
    fn advance(&mut self, loads: &StepLoads) -> Result<ExternalBodyStep, ExternalBodyError> {
        self.bridge.advance(loads).map_err(|e| {
            let exited = match self.child.try_wait() {
                Ok(Some(status)) => format!(" (JSBSim exited: {status})"),
                _ => String::new(),
            };
            ExternalBodyError(format!(
                "{e}{exited}; its console:\n  {}",
                tail(&self.console)
            ))
        })
    }
}

impl Drop for Jsbsim {
    /// The command port closes first (or it lingers in TIME_WAIT), then JSBSim stops and its
    /// root goes.
    fn drop(&mut self) {
        self.bridge.close();
        stop(&mut self.child);
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

#[cfg(test)]
mod tests;
