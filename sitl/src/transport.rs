//! The simulator's side of the HIL link, over UDP datagrams, a serial byte stream or a TCP
//! connection (`crate::tcp`): the sockets and the serial line are `hil::transport`'s, the same
//! the autopilot uses on its end. The link also answers what an autopilot asks of its
//! simulator: PX4's `MAV_CMD_SET_MESSAGE_INTERVAL` for the ground truth.

use crate::run::Summary;
use anyhow::{Context, Result};
use hil::transport::{Datagrams, LineRead, SerialLine};
use hil::{ActuatorCommand, Decoded, Encoder};
use mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, HIL_STATE_QUATERNION_DATA, MavCmd, MavMessage, MavResult,
};
use mavlink::{MavHeader, MessageData};
use std::net::SocketAddr;
use std::path::Path;
use std::time::{Duration, Instant};

/// Whether an autopilot is on the other end of a transport.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Peer {
    /// Nobody connected (a listener's transport, waiting for a connection).
    Absent,
    /// An autopilot that has just connected: a new one, whose clock starts anew.
    New,
    /// The same autopilot as before, or a transport that cannot tell (UDP, serial).
    There,
}

/// How the HIL bytes travel: UDP datagrams, a serial byte stream, a TCP connection.
pub trait Transport {
    /// Whether an autopilot is there, waiting up to `timeout` for one to connect.
    fn peer(&mut self, _timeout: Duration) -> Result<Peer> {
        Ok(Peer::There)
    }
    /// Whether the autopilot has gone (closed its connection) and none has come yet.
    fn gone(&self) -> bool {
        false
    }
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
    /// Answers to the autopilot's requests, sent once the messages at hand are handled.
    replies: Vec<u8>,
    encoder: Encoder,
    /// The ground truth's interval the autopilot asked for, not yet taken
    /// ([`Link::take_state_interval`]): `Some(None)` to stop it.
    state_interval: Option<Option<u64>>,
    /// Messages heard since the autopilot connected.
    pub(crate) heard: u64,
}

impl Link {
    pub(crate) fn new(transport: Box<dyn Transport>) -> Self {
        Self {
            transport,
            out: Vec::with_capacity(1024),
            decoded: Decoded::default(),
            hand: None,
            replies: Vec::new(),
            encoder: hil::sim_encoder(),
            state_interval: None,
            heard: 0,
        }
    }

    /// Whether an autopilot is there, waiting up to `timeout` for one to connect; a new one
    /// has been heard from not at all.
    pub(crate) fn peer(&mut self, timeout: Duration) -> Result<Peer> {
        let peer = self.transport.peer(timeout)?;
        if peer == Peer::New {
            self.heard = 0;
        }
        Ok(peer)
    }

    /// Whether the autopilot has gone (closed its connection) and none has come yet.
    pub(crate) fn gone(&self) -> bool {
        self.transport.gone()
    }

    /// Listens up to `timeout` without sending: for the first word of an autopilot that has
    /// just connected (PX4 sends a `HEARTBEAT` to start the sensor stream). Returns whether it
    /// has been heard.
    pub(crate) fn listen(&mut self, timeout: Duration, s: &mut Summary) -> Result<bool> {
        let deadline = Instant::now() + timeout;
        while self.heard == 0 {
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            self.transport.receive(deadline - now, &mut self.decoded)?;
            let mut ignored = None;
            self.handle(None, s, &mut ignored)?;
        }
        Ok(self.heard > 0)
    }

    /// The ground truth's interval the autopilot asked for since the last call (µs; `None`
    /// inside: stop sending it).
    pub(crate) fn take_state_interval(&mut self) -> Option<Option<u64>> {
        self.state_interval.take()
    }

    /// Answers `MAV_CMD_SET_MESSAGE_INTERVAL` (param1 the message id, param2 the interval in
    /// µs, -1 to stop, 0 for the default): the ground truth's interval is the autopilot's to
    /// set; the sensor frames keep the exchange rate (`--hil-rate`), the other messages their
    /// sensors' rates.
    fn set_message_interval(&mut self, from: &MavHeader, c: &COMMAND_LONG_DATA) {
        let id = c.param1;
        let interval = c.param2;
        let result = if id != HIL_STATE_QUATERNION_DATA::ID as f32 {
            MavResult::MAV_RESULT_UNSUPPORTED
        } else if interval == -1.0 {
            self.state_interval = Some(None);
            MavResult::MAV_RESULT_ACCEPTED
        } else if interval == 0.0 {
            self.state_interval = Some(Some(hil::STATE_INTERVAL_USEC));
            MavResult::MAV_RESULT_ACCEPTED
        } else if interval.is_finite() && interval >= 1.0 {
            self.state_interval = Some(Some(interval as u64));
            MavResult::MAV_RESULT_ACCEPTED
        } else {
            MavResult::MAV_RESULT_DENIED
        };
        tracing::info!(
            message = id,
            interval_us = interval,
            ?result,
            "SET_MESSAGE_INTERVAL"
        );
        self.acknowledge(from, c.command, result);
    }

    fn acknowledge(&mut self, to: &MavHeader, command: MavCmd, result: MavResult) {
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result,
            target_system: u8::try_from(to.system_id).unwrap_or(0),
            target_component: to.component_id,
            ..Default::default()
        });
        self.encoder.push(&mut self.replies, &ack);
    }

    /// Sends `out` (one exchange's messages).
    pub(crate) fn send(&mut self) -> Result<()> {
        self.transport.send(&self.out)
    }

    /// Counts what arrived, answers requests; keeps the newest command (answering `time_usec`,
    /// if given).
    fn handle(
        &mut self,
        time_usec: Option<u64>,
        s: &mut Summary,
        latest: &mut Option<ActuatorCommand>,
    ) -> Result<bool> {
        s.malformed += self.decoded.malformed as u64;
        self.heard += self.decoded.messages.len() as u64;
        let mut matched = false;
        let mut messages = std::mem::take(&mut self.decoded.messages);
        for (header, msg) in messages.drain(..) {
            match msg {
                MavMessage::COMMAND_LONG(c)
                    if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL =>
                {
                    s.other_messages += 1;
                    self.set_message_interval(&header, &c);
                }
                MavMessage::COMMAND_LONG(c) => {
                    s.other_messages += 1;
                    self.acknowledge(&header, c.command, MavResult::MAV_RESULT_UNSUPPORTED);
                }
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
        self.decoded.messages = messages; // its allocation kept
        self.decoded.malformed = 0;
        if !self.replies.is_empty() {
            self.transport.send(&self.replies)?;
            self.replies.clear();
        }
        Ok(matched)
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
            if now >= deadline || self.transport.gone() {
                return Ok(None);
            }
            self.transport.receive(deadline - now, &mut self.decoded)?;
            if self.handle(Some(time_usec), s, &mut latest)? {
                return Ok(latest);
            }
        }
    }

    /// Real time: takes whatever arrived, keeping the newest command.
    pub(crate) fn drain(&mut self, s: &mut Summary) -> Result<Option<ActuatorCommand>> {
        let mut latest = None;
        while self.transport.receive(Duration::ZERO, &mut self.decoded)? {
            self.handle(None, s, &mut latest)?;
        }
        self.handle(None, s, &mut latest)?;
        Ok(latest)
    }
}
