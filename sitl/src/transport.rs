//! How the HIL bytes travel between the simulator and the autopilot: UDP datagrams or a serial
//! byte stream, and the simulator's side of the link over either.

use crate::run::Summary;
use anyhow::{Context, Result};
use hil::{ActuatorCommand, Decoded, StreamDecoder};
use mavlink::dialects::common::MavMessage;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// How the HIL bytes travel: UDP datagrams, or a serial byte stream.
pub trait Transport {
    /// Sends one exchange's messages.
    fn send(&mut self, bytes: &[u8]) -> Result<()>;
    /// Waits up to `timeout` (zero: only what is already there) and appends what arrived to
    /// `into`. Returns false when nothing did.
    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> Result<bool>;
}

/// UDP to the autopilot's port.
pub struct UdpTransport {
    socket: UdpSocket,
    target: SocketAddr,
    rx: Vec<u8>,
    /// The socket's read mode as last set (zero: non-blocking), so that a lockstep exchange
    /// does not pay two extra system calls per receive.
    read_timeout: Option<Duration>,
}

impl UdpTransport {
    /// Binds `bind`, talking to `target`.
    pub fn new(bind: SocketAddr, target: SocketAddr) -> Result<Self> {
        let socket = UdpSocket::bind(bind).with_context(|| format!("binding {bind}"))?;
        // Connected: the kernel keeps the route, and only the autopilot's datagrams come in.
        socket
            .connect(target)
            .with_context(|| format!("setting {target} as the autopilot's address"))?;
        Ok(Self {
            socket,
            target,
            rx: vec![0; 65_536],
            read_timeout: None,
        })
    }

    /// Where the datagrams come from.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.socket.local_addr()?)
    }
}

fn quiet(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::TimedOut
            | std::io::ErrorKind::Interrupted
            | std::io::ErrorKind::ConnectionRefused
    )
}

impl Transport for UdpTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        match self.socket.send(bytes) {
            Ok(_) => Ok(()),
            // Nobody listening yet (ICMP port unreachable): keep going, the autopilot may start later.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => Ok(()),
            Err(e) => Err(e).with_context(|| format!("sending to {}", self.target)),
        }
    }

    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> Result<bool> {
        // A wait a little shorter than asked is fine (callers loop to their deadline): keep the
        // set timeout while it is within [timeout / 2, timeout].
        let keep = match self.read_timeout {
            Some(t) if timeout.is_zero() => t.is_zero(),
            Some(t) => !t.is_zero() && t <= timeout && t * 2 >= timeout,
            None => false,
        };
        if !keep {
            if timeout.is_zero() {
                self.socket.set_nonblocking(true)?;
            } else {
                self.socket.set_nonblocking(false)?;
                self.socket.set_read_timeout(Some(timeout))?;
            }
            self.read_timeout = Some(timeout);
        }
        match self.socket.recv(&mut self.rx) {
            Ok(len) => {
                hil::decode_into(&self.rx[..len], into);
                Ok(true)
            }
            Err(e) if quiet(&e) => Ok(false),
            Err(e) => Err(e).context("receiving HIL_ACTUATOR_CONTROLS"),
        }
    }
}

/// A serial line (or one end of a pseudo-terminal pair): the simulator plays the flight board.
pub struct SerialTransport {
    port: serialport::TTYPort,
    name: String,
    decoder: StreamDecoder,
    rx: Vec<u8>,
    /// The other end of a pair this process opened, kept open so the line stays up until the
    /// autopilot opens it by name.
    _peer: Option<serialport::TTYPort>,
}

impl SerialTransport {
    /// Opens `path` at `baud`, or, for `pty`, a new pseudo-terminal pair whose far end
    /// ([`SerialTransport::name`]) is for the autopilot.
    pub fn open(path: &str, baud: u32) -> Result<Self> {
        let (port, name, peer) = if path == "pty" {
            let (ours, theirs) =
                serialport::TTYPort::pair().context("opening a pseudo-terminal pair")?;
            let name =
                serialport::SerialPort::name(&theirs).context("the pseudo-terminal has no name")?;
            (ours, name, Some(theirs))
        } else {
            let port = serialport::new(path, baud)
                .timeout(Duration::from_millis(10))
                .open_native()
                .with_context(|| format!("opening serial port {path}"))?;
            (port, path.to_owned(), None)
        };
        Ok(Self {
            port,
            name,
            decoder: StreamDecoder::default(),
            rx: vec![0; 4096],
            _peer: peer,
        })
    }

    /// The device the autopilot opens.
    pub fn name(&self) -> &str {
        &self.name
    }
}

impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        use std::io::Write;
        self.port
            .write_all(bytes)
            .with_context(|| format!("writing to {}", self.name))
    }

    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> Result<bool> {
        use serialport::SerialPort;
        use std::io::Read;
        self.port.set_timeout(timeout)?;
        let before = into.messages.len();
        match self.port.read(&mut self.rx) {
            Ok(n) => {
                self.decoder.push(&self.rx[..n], into);
                Ok(into.messages.len() > before)
            }
            Err(e) if quiet(&e) => Ok(false),
            // No autopilot has the far end open yet (a pty's master reads EIO until then).
            Err(e) if e.raw_os_error() == Some(5) => {
                std::thread::sleep(timeout.min(Duration::from_millis(50)));
                Ok(false)
            }
            Err(e) => Err(e).with_context(|| format!("reading {}", self.name)),
        }
    }
}

/// The simulator's side of the HIL link over a transport.
pub(crate) struct Link {
    transport: Box<dyn Transport>,
    pub(crate) out: Vec<u8>,
    decoded: Decoded,
}

impl Link {
    pub(crate) fn new(transport: Box<dyn Transport>) -> Self {
        Self {
            transport,
            out: Vec::with_capacity(1024),
            decoded: Decoded::default(),
        }
    }

    /// Sends `out` (one exchange's messages).
    pub(crate) fn send(&mut self) -> Result<()> {
        self.transport.send(&self.out)
    }

    /// Counts what arrived; keeps the newest command (answering `time_usec`, if given).
    fn handle(
        &mut self,
        time_usec: Option<u64>,
        s: &mut Summary,
        latest: &mut Option<ActuatorCommand>,
    ) -> bool {
        s.malformed += self.decoded.malformed as u64;
        let mut matched = false;
        for (_, msg) in self.decoded.messages.drain(..) {
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
        self.decoded.malformed = 0;
        matched
    }

    /// Lockstep: waits up to `timeout` for the command answering `time_usec`.
    pub(crate) fn wait_for(
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
            self.transport.receive(deadline - now, &mut self.decoded)?;
            if self.handle(Some(time_usec), s, &mut latest) {
                return Ok(latest);
            }
        }
    }

    /// Real time: takes whatever arrived, keeping the newest command.
    pub(crate) fn drain(&mut self, s: &mut Summary) -> Result<Option<ActuatorCommand>> {
        let mut latest = None;
        while self.transport.receive(Duration::ZERO, &mut self.decoded)? {
            self.handle(None, s, &mut latest);
        }
        self.handle(None, s, &mut latest);
        Ok(latest)
    }
}
