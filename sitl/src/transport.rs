//! The simulator's side of the HIL link, over UDP datagrams or a serial byte stream: the
//! sockets and the serial line are `hil::transport`'s, the same the autopilot uses on its end.

use crate::run::Summary;
use anyhow::{Context, Result};
use hil::transport::{Datagrams, LineRead, SerialLine};
use hil::{ActuatorCommand, Decoded};
use mavlink::dialects::common::MavMessage;
use std::net::SocketAddr;
use std::path::Path;
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
    socket: Datagrams,
    target: SocketAddr,
}

impl UdpTransport {
    /// Binds `bind`, talking to `target`.
    pub fn new(bind: SocketAddr, target: SocketAddr) -> Result<Self> {
        let socket = Datagrams::bind(bind).with_context(|| format!("binding {bind}"))?;
        // Connected: the kernel keeps the route, and only the autopilot's datagrams come in.
        socket
            .connect(target)
            .with_context(|| format!("setting {target} as the autopilot's address"))?;
        Ok(Self { socket, target })
    }

    /// Where the datagrams come from.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.socket.local_addr()?)
    }
}

impl Transport for UdpTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        match self.socket.send(bytes, None) {
            Ok(()) => Ok(()),
            // Nobody listening yet (ICMP port unreachable): keep going, the autopilot may start later.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => Ok(()),
            Err(e) => Err(e).with_context(|| format!("sending to {}", self.target)),
        }
    }

    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> Result<bool> {
        match self
            .socket
            .recv(timeout)
            .context("receiving HIL_ACTUATOR_CONTROLS")?
        {
            Some((datagram, _)) => {
                hil::decode_into(datagram, into);
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

/// A serial line (or one end of a pseudo-terminal pair): the simulator plays the flight board.
pub struct SerialTransport {
    line: SerialLine,
}

impl SerialTransport {
    /// Opens `path` at `baud`, or, for `pty`, a new pseudo-terminal pair whose far end
    /// ([`SerialTransport::name`]) is for the autopilot.
    pub fn open(path: &str, baud: u32) -> Result<Self> {
        let line = if path == "pty" {
            SerialLine::pseudo_terminal().context("opening a pseudo-terminal pair")?
        } else {
            SerialLine::open(Path::new(path), baud)
                .with_context(|| format!("opening serial port {path}"))?
        };
        Ok(Self { line })
    }

    /// The device the autopilot opens.
    pub fn name(&self) -> &str {
        self.line.name()
    }
}

impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        self.line
            .write_all(bytes)
            .with_context(|| format!("writing to {}", self.line.name()))
    }

    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> Result<bool> {
        let before = into.messages.len();
        match self.line.read_into(timeout, into) {
            Ok(LineRead::Bytes(_)) => Ok(into.messages.len() > before),
            Ok(LineRead::Nothing | LineRead::Closed) => Ok(false),
            // No autopilot has the far end open yet (a pty's master reads EIO until then).
            Err(e) if e.raw_os_error() == Some(5) => {
                std::thread::sleep(timeout.min(Duration::from_millis(50)));
                Ok(false)
            }
            Err(e) => Err(e).with_context(|| format!("reading {}", self.line.name())),
        }
    }
}

/// The simulator's side of the HIL link over a transport.
pub(crate) struct Link {
    transport: Box<dyn Transport>,
    pub(crate) out: Vec<u8>,
    decoded: Decoded,
    /// A calibration's request to the hand, for the command that follows it.
    hand: Option<hil::HandRequest>,
}

impl Link {
    pub(crate) fn new(transport: Box<dyn Transport>) -> Self {
        Self {
            transport,
            out: Vec::with_capacity(1024),
            decoded: Decoded::default(),
            hand: None,
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
                    let hand = self.hand.take().unwrap_or_default();
                    let cmd = hil::actuator_command(&m).with_hand(hand);
                    match time_usec {
                        Some(t) if cmd.time_usec != t => s.stale += 1,
                        _ => {
                            *latest = Some(cmd);
                            matched = true;
                        }
                    }
                }
                m => match hil::HandRequest::from_message(&m) {
                    Some(hand) => self.hand = Some(hand),
                    None => s.other_messages += 1,
                },
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
