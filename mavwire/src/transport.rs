//! How the HIL bytes travel, for both ends of the link: UDP datagrams ([`Datagrams`]) or a
//! serial byte stream ([`SerialLine`]). Each end keeps its own policy on top (whom to answer,
//! when to reopen a port, what a silent line means); the sockets, timeouts and framing are
//! these, once.

use crate::{Decoded, StreamDecoder};
use std::io::{self, Read, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::path::Path;
use std::time::Duration;

/// A read that ended without data and without a fault: timed out, would block, interrupted by
/// a signal (Ctrl-C), or refused (an ICMP answer to an earlier send: the peer may come back).
pub fn nothing_yet(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock
            | io::ErrorKind::TimedOut
            | io::ErrorKind::Interrupted
            | io::ErrorKind::ConnectionRefused
    )
}

/// Whether a socket whose read timeout is `set` (zero: non-blocking; `None`: never set) can
/// wait for `timeout` as it is. A wait a little shorter than asked is fine (callers loop to
/// their deadline): the set timeout is kept while it is within [timeout / 2, timeout], which
/// saves two system calls a read.
pub fn timeout_kept(set: Option<Duration>, timeout: Duration) -> bool {
    match set {
        Some(t) if timeout.is_zero() => t.is_zero(),
        Some(t) => !t.is_zero() && t <= timeout && t * 2 >= timeout,
        None => false,
    }
}

/// A UDP socket that waits for one datagram at a time, with the read timeout set only when it
/// changes (two system calls per frame otherwise).
pub struct Datagrams {
    socket: UdpSocket,
    rx: Vec<u8>,
    /// The read mode as last set (zero: non-blocking).
    read_timeout: Option<Duration>,
}

impl Datagrams {
    /// Binds `addr`.
    pub fn bind(addr: impl ToSocketAddrs) -> io::Result<Self> {
        Ok(Self {
            socket: UdpSocket::bind(addr)?,
            rx: vec![0; 65_536],
            read_timeout: None,
        })
    }

    /// Talks to `peer` only: the kernel keeps the route, and only its datagrams come in.
    pub fn connect(&self, peer: SocketAddr) -> io::Result<()> {
        self.socket.connect(peer)
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Waits up to `timeout` (zero: only what is already there) for a datagram: its bytes and
    /// sender, or `None` when nothing came ([`nothing_yet`]).
    pub fn recv(&mut self, timeout: Duration) -> io::Result<Option<(&[u8], SocketAddr)>> {
        if !timeout_kept(self.read_timeout, timeout) {
            self.socket.set_nonblocking(timeout.is_zero())?;
            if !timeout.is_zero() {
                self.socket.set_read_timeout(Some(timeout))?;
            }
            self.read_timeout = Some(timeout);
        }
        match self.socket.recv_from(&mut self.rx) {
            Ok((len, from)) => Ok(Some((&self.rx[..len], from))),
            Err(e) if nothing_yet(&e) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Sends `bytes` to `to`, or to the connected peer.
    pub fn send(&self, bytes: &[u8], to: Option<SocketAddr>) -> io::Result<()> {
        match to {
            Some(to) => self.socket.send_to(bytes, to),
            None => self.socket.send(bytes),
        }
        .map(|_| ())
    }
}

/// What a read from a serial line gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineRead {
    /// These many bytes, decoded into the caller's [`Decoded`].
    Bytes(usize),
    /// Nothing within the timeout ([`nothing_yet`]).
    Nothing,
    /// End of stream: the other side closed (a pseudo-terminal whose peer exited).
    Closed,
}

/// A serial line (or one end of a pseudo-terminal pair) carrying MAVLink frames in a byte
/// stream, split into messages as they complete.
pub struct SerialLine {
    port: serialport::TTYPort,
    name: String,
    decoder: StreamDecoder,
    rx: Vec<u8>,
    /// The other end of a pair this process opened, kept open so the line stays up until the
    /// peer opens it by name.
    _peer: Option<serialport::TTYPort>,
}

impl SerialLine {
    /// Opens the device at `path` at `baud`.
    pub fn open(path: &Path, baud: u32) -> serialport::Result<Self> {
        let port = serialport::new(path.to_string_lossy(), baud)
            .timeout(Duration::from_millis(10))
            .open_native()?;
        Ok(Self::with(port, path.display().to_string(), None))
    }

    /// A new pseudo-terminal pair: this end here, the far end ([`SerialLine::name`]) for the
    /// peer to open.
    pub fn pseudo_terminal() -> serialport::Result<Self> {
        let (ours, theirs) = serialport::TTYPort::pair()?;
        let name = serialport::SerialPort::name(&theirs).ok_or_else(|| {
            serialport::Error::new(
                serialport::ErrorKind::Unknown,
                "the pseudo-terminal has no name",
            )
        })?;
        Ok(Self::with(ours, name, Some(theirs)))
    }

    fn with(port: serialport::TTYPort, name: String, peer: Option<serialport::TTYPort>) -> Self {
        Self {
            port,
            name,
            decoder: StreamDecoder::default(),
            rx: vec![0; 4096],
            _peer: peer,
        }
    }

    /// The device: the one opened, or the far end of a pseudo-terminal pair.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Waits up to `timeout` for bytes and appends the messages they complete to `into`.
    pub fn read_into(&mut self, timeout: Duration, into: &mut Decoded) -> io::Result<LineRead> {
        self.read_into_checked(timeout, into, &mut |_| true)
    }

    /// [`SerialLine::read_into`], keeping only the frames `check` passes (after the read: the
    /// check is not held while the line waits), as [`StreamDecoder::push_checked`].
    pub fn read_into_checked(
        &mut self,
        timeout: Duration,
        into: &mut Decoded,
        check: &mut dyn FnMut(&[u8]) -> bool,
    ) -> io::Result<LineRead> {
        serialport::SerialPort::set_timeout(&mut self.port, timeout)?;
        match self.port.read(&mut self.rx) {
            Ok(0) => Ok(LineRead::Closed),
            Ok(n) => {
                self.decoder.push_checked(&self.rx[..n], into, check);
                Ok(LineRead::Bytes(n))
            }
            Err(e) if nothing_yet(&e) => Ok(LineRead::Nothing),
            Err(e) => Err(e),
        }
    }

    /// Writes `bytes` whole.
    pub fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_datagram_arrives_whole_and_silence_is_none() {
        let mut a = Datagrams::bind("127.0.0.1:0").unwrap();
        let b = Datagrams::bind("127.0.0.1:0").unwrap();
        assert_eq!(a.recv(Duration::ZERO).unwrap(), None, "nothing sent yet");
        b.send(b"frame", Some(a.local_addr().unwrap())).unwrap();
        let (bytes, from) = a.recv(Duration::from_secs(5)).unwrap().unwrap();
        assert_eq!((bytes, from), (&b"frame"[..], b.local_addr().unwrap()));
    }

    #[test]
    fn a_pseudo_terminal_carries_a_message_split_across_reads() {
        let mut ours = SerialLine::pseudo_terminal().unwrap();
        let mut theirs = SerialLine::open(Path::new(ours.name()), 921_600).unwrap();
        let mut frame = Vec::new();
        let msg = mavlink::dialects::common::MavMessage::HEARTBEAT(Default::default());
        crate::Encoder::with_ids(1, 1).push(&mut frame, &msg);
        let (head, tail) = frame.split_at(5);
        let mut got = Decoded::default();
        theirs.write_all(head).unwrap();
        let mut tail_sent = false;
        for _ in 0..100 {
            let read = ours.read_into(Duration::from_millis(50), &mut got).unwrap();
            assert_ne!(read, LineRead::Closed);
            if !got.messages.is_empty() {
                break;
            }
            if !tail_sent {
                assert!(got.messages.is_empty(), "half a frame is no message");
                theirs.write_all(tail).unwrap();
                tail_sent = true;
            }
        }
        assert_eq!((got.messages.len(), got.malformed), (1, 0));
    }
}
