//! Sensor links: where the sensor frames come from and where the actuator commands go. Every
//! link hands the flight loop typed frames ([`frames::LinkFrame`]) and takes typed commands
//! ([`ActuatorCommand`]); the bytes stay at its edge: HIL messages over UDP or a serial line,
//! ArduPilot's JSON, or none at all for the embedded simulator. The flight loop does not know
//! which one it talks to. The HIL sockets and serial line are `hil::transport`'s, the same the
//! simulator process uses on its end.

pub mod frames;
pub mod json_link;
pub mod sim;

use anyhow::{Context, Result, bail};
use frames::{FrameAssembler, Received};
use hil::transport::{Datagrams, LineRead, SerialLine};
use hil::{ActuatorCommand, Encoder};
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// A source of sensor frames that takes actuator commands back.
pub trait SensorLink {
    /// Waits up to `timeout` for input and appends the complete sensor frames (and the count of
    /// malformed input) to `into`. Returns false when nothing arrived in time.
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool>;
    /// Sends the answer back to whoever sent the last sensor frame.
    fn send(&mut self, command: &ActuatorCommand) -> io::Result<()>;
    /// What the link is, for messages.
    fn describe(&self) -> String;
    /// The clock that measures sensor silence (s): wall-clock time for a flight board in the
    /// real world. `None` for a simulator in lockstep, whose world (and so the vehicle's clock)
    /// stands still while its frames stop: nothing is overdue.
    fn silence_clock_s(&self) -> Option<f64>;
}

/// Monotonic wall-clock seconds since the first call.
pub fn wall_clock_s() -> f64 {
    static EPOCH: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    EPOCH.get_or_init(Instant::now).elapsed().as_secs_f64()
}

/// Where the sensors come from, as given on the command line.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// The embedded simulator.
    Embedded,
    /// A simulator process sending to this UDP address.
    Udp {
        /// Address to bind.
        addr: SocketAddr,
        /// The simulator waits for each answer (default): silence is a paused world.
        lockstep: bool,
    },
    /// A physics speaking ArduPilot's JSON interface at this UDP address
    /// ([`json_link`]).
    Json {
        /// The physics' address.
        addr: SocketAddr,
        /// Each rotor's servo channel (0-based); empty: rotor k on channel k.
        channels: Vec<usize>,
    },
    /// A flight board on a serial port.
    Serial {
        /// Device path.
        path: PathBuf,
        /// Baud rate.
        baud: u32,
        /// The other end is a simulator in lockstep, not a board in the real world (default
        /// false): silence is a paused world, not a sensor failure.
        lockstep: bool,
    },
}

/// Parses `key=value&…` options of a source URL with `apply` (true: the key is known).
pub(crate) fn parse_options(
    url: &str,
    query: &str,
    mut apply: impl FnMut(&str, &str) -> Result<bool>,
    known: &str,
) -> Result<()> {
    for kv in query.split('&').filter(|kv| !kv.is_empty()) {
        let Some((k, v)) = kv.split_once('=') else {
            bail!("{url:?}: option {kv:?} needs a value (known: {known})");
        };
        if !apply(k, v)? {
            bail!("{url:?}: unknown option {kv:?} (known: {known})");
        }
    }
    Ok(())
}

fn parse_bool(url: &str, key: &str, v: &str) -> Result<bool> {
    match v {
        "true" | "1" => Ok(true),
        "false" | "0" => Ok(false),
        _ => bail!("{url:?}: {key} must be true or false, got {v:?}"),
    }
}

pub use flight_core::sensors::mag_check::SIMULATED_MAG_ID;

/// `json://ADDRESS:PORT?channels=…` (`rest` after the scheme): the port offset by 10 ×
/// `instance`, the servo channel of each rotor.
fn parse_json(url: &str, rest: &str, instance: u16) -> Result<Source> {
    let (addr, query) = rest.split_once('?').unwrap_or((rest, ""));
    let mut a: SocketAddr = addr.parse().with_context(|| {
        format!("{url:?}: expected json://ADDRESS:PORT, e.g. json://127.0.0.1:9002")
    })?;
    let offset = instance
        .checked_mul(hil::json::JSON_INSTANCE_STRIDE)
        .and_then(|o| a.port().checked_add(o))
        .with_context(|| format!("{url:?}: instance {instance} pushes the port past 65535"))?;
    a.set_port(offset);
    let mut channels = Vec::new();
    parse_options(
        url,
        query,
        |k, v| {
            match k {
                "channels" => {
                    for c in v.split(',') {
                        let c: usize = c
                            .parse()
                            .ok()
                            .filter(|c| (1..=32).contains(c))
                            .with_context(|| {
                                format!("{url:?}: channels: {c:?} is not a servo channel 1-32")
                            })?;
                        if channels.contains(&(c - 1)) {
                            bail!("{url:?}: channels: {c} given twice");
                        }
                        channels.push(c - 1);
                    }
                }
                _ => return Ok(false),
            }
            Ok(true)
        },
        "channels",
    )?;
    Ok(Source::Json { addr: a, channels })
}

impl Source {
    /// The other end is a simulator: the embedded one, one over UDP, or one in lockstep on a
    /// serial line.
    pub fn is_simulator(&self) -> bool {
        match self {
            Self::Embedded | Self::Udp { .. } | Self::Json { .. } => true,
            Self::Serial { lockstep, .. } => *lockstep,
        }
    }

    /// Whether the source waits for each answer (its time is then the flight's clock).
    pub fn lockstep(&self) -> bool {
        match self {
            Self::Embedded | Self::Json { .. } => true,
            Self::Udp { lockstep, .. } | Self::Serial { lockstep, .. } => *lockstep,
        }
    }

    /// Presets what a simulator's sensors need (PX4's `param set-default` in its SITL start-up):
    /// the simulated magnetometer is calibrated by construction (`CAL_MAG0_ID`), unless the
    /// parameter file says otherwise. A ground station may still clear it.
    pub fn preset_params(&self, params: &mut flight_core::params::FlightParams) {
        if self.is_simulator() && params.attitude.mag_calibration_id == 0 {
            params.attitude.mag_calibration_id = SIMULATED_MAG_ID;
        }
    }
    /// Parses `sim`, `udp://HOST:PORT[?lockstep=false]`, `json://HOST:PORT[?channels=1,2,3,4]`
    /// or `serial:///dev/ttyX[?baud=N&lockstep=true]`; a UDP port is offset by `instance`, a
    /// JSON physics' by 10 `instance` (ArduPilot's instances).
    pub fn parse(url: &str, instance: u16) -> Result<Self> {
        if url == "sim" {
            return Ok(Self::Embedded);
        }
        if let Some(rest) = url.strip_prefix("udp://") {
            let (addr, query) = rest.split_once('?').unwrap_or((rest, ""));
            let mut a: SocketAddr = addr.parse().with_context(|| {
                format!("{url:?}: expected udp://ADDRESS:PORT, e.g. udp://0.0.0.0:4560")
            })?;
            if a.port() != 0 {
                // A port 0 is any free one (printed once bound), never offset.
                a.set_port(a.port().checked_add(instance).with_context(|| {
                    format!("{url:?}: instance {instance} pushes the port past 65535")
                })?);
            }
            let mut lockstep = true;
            parse_options(
                url,
                query,
                |k, v| {
                    match k {
                        "lockstep" => lockstep = parse_bool(url, k, v)?,
                        _ => return Ok(false),
                    }
                    Ok(true)
                },
                "lockstep",
            )?;
            return Ok(Self::Udp { addr: a, lockstep });
        }
        if let Some(rest) = url.strip_prefix("json://") {
            return parse_json(url, rest, instance);
        }
        if let Some(rest) = url.strip_prefix("serial://") {
            let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
            if path.is_empty() {
                bail!("{url:?}: expected serial:///dev/ttyUSB0?baud=921600");
            }
            let (mut baud, mut lockstep) = (921_600, false);
            parse_options(
                url,
                query,
                |k, v| {
                    match k {
                        "baud" => {
                            baud = v
                                .parse()
                                .ok()
                                .filter(|b| (1200..=12_000_000).contains(b))
                                .with_context(|| {
                                    format!("{url:?}: baud must be a rate within [1200, 12000000], got {v:?}")
                                })?
                        }
                        "lockstep" => lockstep = parse_bool(url, k, v)?,
                        _ => return Ok(false),
                    }
                    Ok(true)
                },
                "baud, lockstep",
            )?;
            return Ok(Self::Serial {
                path: PathBuf::from(path),
                baud,
                lockstep,
            });
        }
        bail!(
            "unknown sensor source {url:?}: give sim, udp://ADDRESS:PORT, json://ADDRESS:PORT or serial:///dev/ttyX?baud=N"
        )
    }
}

/// How long the simulator a UDP link is bound to must be silent before frames from another
/// address are taken (a simulator restarted on another port).
const REBIND_AFTER: Duration = Duration::from_secs(2);

/// A simulator process on UDP: binds the autopilot's port and the first simulator heard. Frames
/// from any other address are counted and dropped (no other host takes over the vehicle's
/// senses), until that simulator has been silent for [`REBIND_AFTER`]; a simulator restarted
/// on the same address is the same peer.
pub struct UdpLink {
    socket: Datagrams,
    peer: Option<SocketAddr>,
    /// When the bound simulator was last heard.
    peer_heard: Option<std::time::Instant>,
    /// Frames dropped for coming from elsewhere.
    foreign: u64,
    lockstep: bool,
    /// Answers dropped because the socket's buffer was full (non-blocking).
    dropped: u64,
    frames: FrameAssembler,
    encoder: Encoder,
    tx: Vec<u8>,
}

impl UdpLink {
    /// Binds `addr`; `lockstep`: the simulator waits for each answer, sent as `system_id`.
    pub fn bind(addr: SocketAddr, lockstep: bool, system_id: u8) -> Result<Self> {
        let socket = Datagrams::bind(addr).with_context(|| {
            format!("binding the simulator port {addr} (is another autopilot using it? try -i N)")
        })?;
        Ok(Self {
            socket,
            peer: None,
            peer_heard: None,
            foreign: 0,
            lockstep,
            dropped: 0,
            frames: FrameAssembler::default(),
            encoder: Encoder::with_ids(system_id, 1),
            tx: Vec::with_capacity(128),
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
}

impl SensorLink for UdpLink {
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        // A zero timeout reads without waiting (the deadline-paced loop).
        let Some((datagram, from)) = self.socket.recv(timeout)? else {
            return Ok(false);
        };
        let now = std::time::Instant::now();
        if self.peer != Some(from) {
            let bound_live = self
                .peer_heard
                .is_some_and(|t| now.duration_since(t) < REBIND_AFTER);
            if bound_live {
                self.foreign += 1;
                if self.foreign.is_power_of_two() {
                    tracing::warn!(from = %from, simulator = ?self.peer, dropped = self.foreign, "sensor frames from another address dropped");
                }
                // Nothing arrived from the simulator (the caller reads on to its deadline).
                return Ok(false);
            }
            tracing::info!(simulator = %from, "sensor frames arriving");
            self.peer = Some(from);
        }
        self.peer_heard = Some(now);
        self.frames
            .absorb_bytes(into, |d| hil::decode_into(datagram, d));
        Ok(true)
    }

    fn send(&mut self, command: &ActuatorCommand) -> io::Result<()> {
        let Some(peer) = self.peer else {
            return Ok(());
        };
        encode(&mut self.encoder, &mut self.tx, command);
        match self.socket.send(&self.tx, Some(peer)) {
            // The simulator went away; it may come back.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => Ok(()),
            // Non-blocking and the buffer is full: this answer is lost, the next one goes.
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                self.dropped += 1;
                if self.dropped.is_power_of_two() {
                    tracing::warn!(
                        dropped = self.dropped,
                        "UDP send buffer full: answers dropped"
                    );
                }
                Ok(())
            }
            r => r,
        }
    }

    fn describe(&self) -> String {
        match self.socket.local_addr() {
            Ok(a) => format!("udp://{a}"),
            Err(_) => "udp".into(),
        }
    }

    fn silence_clock_s(&self) -> Option<f64> {
        (!self.lockstep).then(wall_clock_s)
    }
}

/// A flight board on a serial line: MAVLink frames in a byte stream. A port that is missing or
/// vanishes is reopened with backoff (0.1 s doubling to 2 s); meanwhile the link reports
/// silence, as for any sensor that stops.
pub struct SerialLink {
    path: PathBuf,
    baud: u32,
    port: Option<SerialLine>,
    frames: FrameAssembler,
    encoder: Encoder,
    tx: Vec<u8>,
    retry_at: Instant,
    backoff: Duration,
    lockstep: bool,
    /// Answers dropped because the output buffer was full.
    dropped: u64,
}

impl SerialLink {
    /// Opens `path` at `baud`; a port that cannot be opened now is an error (a typo should stop
    /// the daemon), one that vanishes later is retried. `lockstep`: the other end is a
    /// simulator that waits for each answer. Answers go out as `system_id`.
    pub fn open(path: PathBuf, baud: u32, lockstep: bool, system_id: u8) -> Result<Self> {
        let port = SerialLine::open(&path, baud)
            .with_context(|| format!("opening serial port {}", path.display()))?;
        Ok(Self {
            path,
            baud,
            port: Some(port),
            frames: FrameAssembler::default(),
            encoder: Encoder::with_ids(system_id, 1),
            tx: Vec::with_capacity(128),
            retry_at: Instant::now(),
            backoff: Duration::from_millis(100),
            lockstep,
            dropped: 0,
        })
    }

    fn lost(&mut self, e: &dyn std::fmt::Display) {
        tracing::error!(port = %self.path.display(), "serial link lost: {e}; reopening");
        self.port = None; // its decoder, holding part of a frame, with it
        self.backoff = Duration::from_millis(100);
        self.retry_at = Instant::now() + self.backoff;
    }
}

impl SensorLink for SerialLink {
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        let Some(port) = self.port.as_mut() else {
            let now = Instant::now();
            if now < self.retry_at {
                std::thread::sleep(timeout.min(self.retry_at - now));
                return Ok(false);
            }
            match SerialLine::open(&self.path, self.baud) {
                Ok(p) => {
                    tracing::info!(port = %self.path.display(), "serial link back");
                    self.port = Some(p);
                }
                Err(e) => {
                    tracing::debug!(port = %self.path.display(), "still no serial port: {e}");
                    self.backoff = (self.backoff * 2).min(Duration::from_secs(2));
                    self.retry_at = now + self.backoff;
                }
            }
            return Ok(false);
        };
        let mut read = Ok(LineRead::Nothing);
        let any = self
            .frames
            .absorb_bytes(into, |d| read = port.read_into(timeout, d));
        match read {
            Ok(LineRead::Bytes(_) | LineRead::Nothing) => Ok(any),
            // The other side closed (a pty whose simulator exited).
            Ok(LineRead::Closed) => {
                self.lost(&"end of stream");
                Ok(false)
            }
            Err(e) => {
                self.lost(&e);
                Ok(false)
            }
        }
    }

    fn send(&mut self, command: &ActuatorCommand) -> io::Result<()> {
        let Some(port) = self.port.as_mut() else {
            return Ok(());
        };
        encode(&mut self.encoder, &mut self.tx, command);
        match port.write_all(&self.tx) {
            Ok(()) => {}
            // The deadline-paced loop writes without waiting: a full output buffer loses this
            // answer (the board's parser skips a partial frame), not the port.
            Err(e) if hil::transport::nothing_yet(&e) => {
                self.dropped += 1;
                if self.dropped.is_power_of_two() {
                    tracing::warn!(port = %self.path.display(), dropped = self.dropped, "serial output full: answers dropped");
                }
            }
            Err(e) => self.lost(&e),
        }
        Ok(())
    }

    fn describe(&self) -> String {
        format!("serial://{}?baud={}", self.path.display(), self.baud)
    }

    fn silence_clock_s(&self) -> Option<f64> {
        (!self.lockstep).then(wall_clock_s)
    }
}

/// `command` as bytes in `tx`: a calibration's `CAL_POSE` if it has one, then
/// `HIL_ACTUATOR_CONTROLS`.
fn encode(encoder: &mut Encoder, tx: &mut Vec<u8>, command: &ActuatorCommand) {
    tx.clear();
    for msg in command.messages() {
        encoder.push(tx, &msg);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A simulator's magnetometer is calibrated by construction; a board's is not until its
    /// owner calibrates it, and a calibration in the parameter file is kept.
    #[test]
    fn a_simulator_source_presets_the_magnetometer_calibration() {
        use flight_core::params::FlightParams;
        let preset = |url: &str, id: u32| {
            let mut p = FlightParams::default();
            p.attitude.mag_calibration_id = id;
            Source::parse(url, 0).unwrap().preset_params(&mut p);
            p.attitude.mag_calibration_id
        };
        assert_eq!(preset("sim", 0), SIMULATED_MAG_ID);
        assert_eq!(
            preset("udp://127.0.0.1:4560?lockstep=false", 0),
            SIMULATED_MAG_ID
        );
        assert_eq!(
            preset("serial:///dev/ttyACM0?lockstep=1", 0),
            SIMULATED_MAG_ID
        );
        assert_eq!(preset("serial:///dev/ttyACM0", 0), 0, "a board");
        assert_eq!(preset("sim", 42), 42);
    }

    #[test]
    fn sources_parse_with_clear_errors() {
        assert_eq!(Source::parse("sim", 3).unwrap(), Source::Embedded);
        assert_eq!(
            Source::parse("udp://0.0.0.0:4560", 2).unwrap(),
            Source::Udp {
                addr: "0.0.0.0:4562".parse().unwrap(),
                lockstep: true
            }
        );
        assert_eq!(
            Source::parse("udp://127.0.0.1:4560?lockstep=false", 0).unwrap(),
            Source::Udp {
                addr: "127.0.0.1:4560".parse().unwrap(),
                lockstep: false
            }
        );
        assert_eq!(
            Source::parse("serial:///dev/ttyUSB0?baud=57600", 0).unwrap(),
            Source::Serial {
                path: "/dev/ttyUSB0".into(),
                baud: 57_600,
                lockstep: false
            }
        );
        assert_eq!(
            Source::parse("serial:///dev/ttyACM0?lockstep=1", 0).unwrap(),
            Source::Serial {
                path: "/dev/ttyACM0".into(),
                baud: 921_600,
                lockstep: true
            }
        );
        // ArduPilot's instances: the JSON port 10 apart.
        assert_eq!(
            Source::parse("json://127.0.0.1:9002?channels=3,1,4,2", 2).unwrap(),
            Source::Json {
                addr: "127.0.0.1:9022".parse().unwrap(),
                channels: vec![2, 0, 3, 1]
            }
        );
        assert!(
            Source::parse("json://127.0.0.1:9002", 0)
                .unwrap()
                .lockstep()
        );
        for (bad, says) in [
            ("json://localhost", "expected json://ADDRESS:PORT"),
            ("json://127.0.0.1:9002?channels=1,1", "given twice"),
            ("json://127.0.0.1:9002?channels=0", "not a servo channel"),
            ("json://127.0.0.1:65530", "past 65535"),
            ("udp://nowhere", "expected udp://ADDRESS:PORT"),
            ("udp://0.0.0.0:65535", "past 65535"),
            ("serial://?baud=9600", "expected serial:///dev/"),
            ("serial:///dev/ttyS0?baud=fast", "baud must be"),
            ("serial:///dev/ttyS0?parity=odd", "unknown option"),
            ("serial:///dev/ttyS0?lockstep", "needs a value"),
            ("udp://0.0.0.0:4560?lockstep=maybe", "true or false"),
            ("tcp://1.2.3.4:5", "unknown sensor source"),
        ] {
            let e = format!("{:#}", Source::parse(bad, 1).unwrap_err());
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
