//! The JSBSim back-end's process and link (`sitl --physics jsbsim`): writes the generated model,
//! its start file and the bridge program (`jsbsim/bridge.py`, embedded) to a temporary root,
//! runs the bridge with a Python that has the pinned PyPI `jsbsim`, and steps it in lockstep:
//! one request datagram per physics step (the loads), one reply (the state). The model, the
//! request and the reply are `sitl_core::jsbsim`'s.
//!
//! JSBSim runs inside the bridge through its Python API, not as its console program: the
//! console polls its command port at full speed (a core at 100 %, which starves the autopilot
//! beside it in real time), parses a text line per property, and lets idle zero-length frames
//! run between commands, so the frame in which a set value acts depended on timing and one seed
//! did not give one trajectory. The bridge blocks between requests and runs a fixed number of
//! frames per request, at a kilohertz or more (a force acts one JSBSim frame late).
//!
//! What can go wrong is said with the bridge's own words (the tail of its output): a Python
//! without `jsbsim`, a model JSBSim refuses, an unknown property, a bridge that exits or falls
//! silent (each step has a deadline). The bridge reads its standard input from `sitl` and ends
//! when that closes, so it never outlives `sitl`, even a `sitl` killed by SIGKILL.

use anyhow::{Context, Result};
use navmath::geo::{LatLonAlt, LocalFrame};
use sitl_core::Airframe;
use sitl_core::body::BodyState;
use sitl_core::jsbsim::{
    BridgeInputs, MODEL_NAME, REPLY_LEN, STATE_PROPERTIES, aircraft_xml, decode_reply,
    frames_per_step, init_xml, input_properties,
};
use sitl_core::sim::{ExternalBody, ExternalBodyError, ExternalBodyStep, StepLoads};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, ErrorKind, Read};
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

/// The bridge program, written next to the model at start.
const BRIDGE_PY: &str = include_str!("jsbsim/bridge.py");
/// What the bridge prints, with its UDP port, when it is ready for requests.
const READY: &str = "ready ";
/// Lines of the bridge's output kept for error reports.
const CONSOLE_LINES: usize = 30;

/// How to start JSBSim.
#[derive(Debug, Clone)]
pub struct Launch<'a> {
    /// A Python with the `jsbsim` module (the pinned PyPI `jsbsim==1.3.3`).
    pub python: &'a Path,
    /// The vehicle.
    pub airframe: &'a Airframe,
    /// The local NED origin: the rest position of the centre of mass.
    pub home: LatLonAlt,
    /// The start, in that frame.
    pub initial: BodyState,
    /// The physics rate (Hz): one request per step, each run as
    /// [`frames_per_step`] JSBSim frames.
    pub rate_hz: f64,
    /// How long the bridge may take to start.
    pub startup_timeout: Duration,
    /// How long one step may take before the run fails.
    pub step_timeout: Duration,
}

/// The link to a bridge that is up, stepped in lockstep: it is the rigid body, gravity and the
/// ground of [`sitl_core::sim::Simulator::step_with`].
pub struct Bridge {
    socket: UdpSocket,
    origin: LocalFrame,
    mass_kg: f64,
    rotors: usize,
    sequence: u64,
    step_timeout: Duration,
    request: Vec<u8>,
    rx: Vec<u8>,
}

impl Bridge {
    /// Talks to the bridge at `peer` on the loopback; positions are reported in the local NED
    /// frame of `origin`.
    pub fn connect(
        peer: SocketAddr,
        origin: LatLonAlt,
        airframe: &Airframe,
        step_timeout: Duration,
    ) -> Result<Self> {
        let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).context("binding a UDP port")?;
        socket
            .connect(peer)
            .with_context(|| format!("setting {peer} as the bridge's address"))?;
        // Short waits: the step's own deadline decides when to give up.
        socket.set_read_timeout(Some(Duration::from_millis(50)))?;
        Ok(Self {
            socket,
            origin: LocalFrame::new(origin),
            mass_kg: airframe.mass_kg,
            rotors: airframe.rotors.len(),
            sequence: 0,
            step_timeout,
            request: Vec::with_capacity(8 * (1 + input_properties(airframe.rotors.len()).len())),
            // One byte more than a reply: a longer datagram is refused, not cut to size.
            rx: vec![0; REPLY_LEN + 1],
        })
    }

    /// One step: the request out, its reply in. `alive` is asked while waiting, so that a bridge
    /// that has exited fails the step at once instead of at the deadline.
    fn step(
        &mut self,
        loads: &StepLoads,
        alive: &mut dyn FnMut() -> std::result::Result<(), String>,
    ) -> std::result::Result<ExternalBodyStep, String> {
        let deadline = Instant::now() + self.step_timeout;
        self.request.clear();
        BridgeInputs::from_loads(loads, self.rotors)
            .encode(self.sequence + 1, &mut self.request)
            .map_err(|e| format!("refused to send {e}"))?;
        self.sequence += 1;
        self.socket
            .send(&self.request)
            .map_err(|e| format!("sending request {}: {e}", self.sequence))?;
        let len = loop {
            match self.socket.recv(&mut self.rx) {
                Ok(len) => break len,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) =>
                {
                    alive()?;
                    if Instant::now() > deadline {
                        return Err(format!(
                            "no reply to request {} within {:?}",
                            self.sequence, self.step_timeout
                        ));
                    }
                }
                // The bridge's port is closed: it has gone.
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {
                    alive()?;
                    return Err(format!(
                        "request {} refused: the bridge is gone",
                        self.sequence
                    ));
                }
                Err(e) => return Err(format!("receiving reply {}: {e}", self.sequence)),
            }
        };
        let (sequence, state) =
            decode_reply(&self.rx[..len], self.mass_kg).map_err(|e| e.to_string())?;
        // Only the reply to this request can come: the ones before were all taken.
        if sequence != self.sequence {
            return Err(format!(
                "reply {sequence} to request {}: the bridge is out of step",
                self.sequence
            ));
        }
        Ok(state.body_step(&self.origin))
    }
}

impl ExternalBody for Bridge {
    fn advance(&mut self, loads: &StepLoads) -> Result<ExternalBodyStep, ExternalBodyError> {
        self.step(loads, &mut || Ok(()))
            .map_err(|why| ExternalBodyError(format!("JSBSim bridge: {why}")))
    }
}

/// A bridge process of our own with JSBSim in it, and the link to it.
pub struct Jsbsim {
    bridge: Bridge,
    child: Child,
    root: PathBuf,
    console: Arc<Mutex<VecDeque<String>>>,
}

/// Keeps the last lines of the bridge's stdout or stderr, and passes them on while someone
/// listens (the start-up); reads until the stream closes, so the bridge never blocks on a full
/// pipe.
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
        .map(|c| {
            c.iter()
                .filter(|l| !l.trim().is_empty())
                .cloned()
                .collect::<Vec<_>>()
                .join("\n  ")
        })
        .unwrap_or_default()
}

/// Stops the bridge: its standard input closes (it ends by itself), then, if it has not within
/// a few seconds, it is killed.
fn stop(child: &mut Child) {
    drop(child.stdin.take());
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        if matches!(child.try_wait(), Ok(Some(_))) {
            return;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// Why the bridge is not answering, if it has exited.
fn exited(child: &mut Child) -> std::result::Result<(), String> {
    match child.try_wait() {
        Ok(Some(status)) => Err(format!("the bridge exited ({status})")),
        _ => Ok(()),
    }
}

impl Jsbsim {
    /// Writes the model, its start file and the bridge to a temporary root, starts the bridge
    /// and connects; fails with the bridge's own words when it does not come up.
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
        let start = dir.join("start.xml");
        std::fs::write(&start, init_xml(l.airframe, &l.home, &l.initial))
            .context("writing JSBSim's start file")?;
        std::fs::write(
            dir.join(format!("{MODEL_NAME}.xml")),
            aircraft_xml(l.airframe),
        )
        .context("writing JSBSim's aircraft model")?;
        let program = root.join("bridge.py");
        std::fs::write(&program, BRIDGE_PY).context("writing the JSBSim bridge")?;
        let mut child = Command::new(l.python)
            .arg(&program)
            .arg("--root")
            .arg(root)
            .args(["--model", MODEL_NAME, "--initfile"])
            .arg(&start)
            .arg(format!("--rate={}", l.rate_hz))
            .arg(format!("--frames={}", frames_per_step(l.rate_hz)))
            .arg(format!(
                "--inputs={}",
                input_properties(l.airframe.rotors.len()).join(",")
            ))
            .arg(format!("--outputs={}", STATE_PROPERTIES.join(",")))
            .arg("--remove-root")
            // Its own process group: a Ctrl-C at the terminal reaches only `sitl`, which ends
            // its run cleanly and then stops the bridge (SIGTERM and SIGHUP too).
            .process_group(0)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| {
                format!(
                    "starting the JSBSim bridge with {} (a Python with the pinned PyPI \
                     jsbsim==1.3.3; name it with --jsbsim-python)",
                    l.python.display()
                )
            })?;
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
            anyhow::anyhow!("{why}; the JSBSim bridge said:\n  {}", tail(&console))
        };
        let deadline = Instant::now() + l.startup_timeout;
        let port = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok(line) => {
                    if let Some(port) = line.strip_prefix(READY) {
                        match port.trim().parse::<u16>() {
                            Ok(port) => break port,
                            Err(_) => {
                                let why = format!("the bridge announced a bad port: {line:?}");
                                return Err(fail(&mut child, why));
                            }
                        }
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let why = format!("the JSBSim bridge not ready within {:?}", l.startup_timeout);
                    return Err(fail(&mut child, why));
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let why = format!(
                        "the JSBSim bridge exited during start-up (does {} have the jsbsim \
                         module? The pinned PyPI jsbsim==1.3.3 installs it; name the Python with \
                         --jsbsim-python)",
                        l.python.display()
                    );
                    return Err(fail(&mut child, why));
                }
            }
        };
        // From here on nobody listens: the readers only keep the tail.
        drop(rx);
        let peer = SocketAddr::from((Ipv4Addr::LOCALHOST, port));
        match Bridge::connect(peer, l.home, l.airframe, l.step_timeout) {
            Ok(bridge) => Ok(Self {
                bridge,
                child,
                root: root.to_owned(),
                console,
            }),
            Err(e) => Err(fail(&mut child, format!("{e:#}"))),
        }
    }
}

impl ExternalBody for Jsbsim {
    fn advance(&mut self, loads: &StepLoads) -> Result<ExternalBodyStep, ExternalBodyError> {
        let child = &mut self.child;
        self.bridge
            .step(loads, &mut || exited(child))
            .map_err(|why| {
                ExternalBodyError(format!(
                    "JSBSim bridge: {why}; its output:\n  {}",
                    tail(&self.console)
                ))
            })
    }
}

impl Drop for Jsbsim {
    /// The bridge stops and its root goes.
    fn drop(&mut self) {
        stop(&mut self.child);
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

#[cfg(test)]
mod tests;
