//! The HIL link over TCP, with the simulator listening: PX4's simulator interface, whose stock
//! start-up (`px4-rc.mavlinksim`) runs `simulator_mavlink start -c $((4560 + instance))`, a TCP
//! client that connects to the simulator and exchanges MAVLink frames over the stream
//! (`src/modules/simulation/simulator_mavlink/SimulatorMavlink.cpp`).
//!
//! One autopilot at a time: a second connection waits until the first has closed. An autopilot
//! that closes its end (PX4 stopped) leaves the listener waiting for the next one.

use crate::transport::{Peer, Transport};
use anyhow::{Context, Result};
use hil::transport::{nothing_yet, timeout_kept};
use hil::{Decoded, StreamDecoder};
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::{Duration, Instant};

/// How often a listener with nobody connected looks again for a connection.
const ACCEPT_POLL: Duration = Duration::from_millis(10);

/// A TCP listener and the autopilot connected to it.
pub struct TcpTransport {
    listener: TcpListener,
    stream: Option<TcpStream>,
    /// The stream's read timeout as last set (zero: non-blocking).
    read_timeout: Option<Duration>,
    /// A connection accepted and not yet reported by [`Transport::peer`].
    fresh: bool,
    decoder: StreamDecoder,
    rx: Vec<u8>,
}

impl TcpTransport {
    /// Listens on `addr`.
    pub fn listen(addr: SocketAddr) -> Result<Self> {
        let listener =
            TcpListener::bind(addr).with_context(|| format!("listening on TCP {addr}"))?;
        listener
            .set_nonblocking(true)
            .context("making the TCP listener non-blocking")?;
        Ok(Self {
            listener,
            stream: None,
            read_timeout: None,
            fresh: false,
            decoder: StreamDecoder::default(),
            rx: vec![0; 16 * 1024],
        })
    }

    /// The address listened on.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.listener.local_addr()?)
    }

    /// Takes a waiting connection, if there is one.
    fn accept(&mut self) -> Result<bool> {
        match self.listener.accept() {
            Ok((stream, from)) => {
                // Every exchange is a few small frames that the other end waits for.
                stream.set_nodelay(true).context("setting TCP_NODELAY")?;
                stream
                    .set_nonblocking(false)
                    .context("making the TCP stream blocking")?;
                tracing::info!(%from, "autopilot connected over TCP");
                self.stream = Some(stream);
                self.read_timeout = None;
                self.decoder = StreamDecoder::default();
                self.fresh = true;
                Ok(true)
            }
            Err(e) if nothing_yet(&e) => Ok(false),
            Err(e) => Err(e).context("accepting a TCP connection"),
        }
    }

    /// The autopilot went away: listen for the next one.
    fn closed(&mut self, why: &str) {
        tracing::warn!("the autopilot's TCP connection ended ({why}); listening for the next one");
        self.stream = None;
    }
}

impl Transport for TcpTransport {
    fn peer(&mut self, timeout: Duration) -> Result<Peer> {
        let deadline = Instant::now() + timeout;
        while self.stream.is_none() {
            if self.accept()? {
                break;
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(Peer::Absent);
            }
            std::thread::sleep(ACCEPT_POLL.min(deadline - now));
        }
        Ok(if std::mem::take(&mut self.fresh) {
            Peer::New
        } else {
            Peer::There
        })
    }

    fn gone(&self) -> bool {
        self.stream.is_none()
    }

    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        let Some(stream) = self.stream.as_mut() else {
            return Ok(()); // nobody to tell
        };
        match stream.write_all(bytes) {
            Ok(()) => Ok(()),
            Err(e) if is_gone(&e) => {
                self.closed(&e.to_string());
                Ok(())
            }
            Err(e) => Err(e).context("writing to the autopilot's TCP connection"),
        }
    }

    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> Result<bool> {
        let Some(stream) = self.stream.as_mut() else {
            return Ok(false);
        };
        if !timeout_kept(self.read_timeout, timeout) {
            if timeout.is_zero() {
                stream.set_nonblocking(true)?;
            } else {
                stream.set_nonblocking(false)?;
                stream.set_read_timeout(Some(timeout))?;
            }
            self.read_timeout = Some(timeout);
        }
        let before = into.messages.len();
        match stream.read(&mut self.rx) {
            Ok(0) => {
                self.closed("closed by the autopilot");
                Ok(false)
            }
            Ok(n) => {
                self.decoder.push(&self.rx[..n], into);
                Ok(into.messages.len() > before)
            }
            Err(e) if nothing_yet(&e) => Ok(false),
            Err(e) if is_gone(&e) => {
                self.closed(&e.to_string());
                Ok(false)
            }
            Err(e) => Err(e).context("reading the autopilot's TCP connection"),
        }
    }
}

/// A connection the other end has reset or abandoned.
fn is_gone(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionReset
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::BrokenPipe
            | io::ErrorKind::UnexpectedEof
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use hil::Encoder;

    fn frame(time_usec: u64) -> Vec<u8> {
        let mut out = Vec::new();
        let msg = hil::actuator_controls(time_usec, &[0.5; 4], true);
        Encoder::with_ids(1, 1).push(&mut out, &msg);
        out
    }

    #[test]
    fn nobody_connected_is_absent_and_a_connection_is_new_once() {
        let mut t = TcpTransport::listen("127.0.0.1:0".parse().unwrap()).unwrap();
        assert_eq!(t.peer(Duration::ZERO).unwrap(), Peer::Absent);
        t.send(b"dropped: nobody to tell").unwrap();
        let _client = TcpStream::connect(t.local_addr().unwrap()).unwrap();
        assert_eq!(t.peer(Duration::from_secs(5)).unwrap(), Peer::New);
        assert_eq!(t.peer(Duration::ZERO).unwrap(), Peer::There);
    }

    #[test]
    fn a_frame_split_across_writes_is_one_message_and_a_closed_end_is_listened_again() {
        let mut t = TcpTransport::listen("127.0.0.1:0".parse().unwrap()).unwrap();
        let mut client = TcpStream::connect(t.local_addr().unwrap()).unwrap();
        assert_eq!(t.peer(Duration::from_secs(5)).unwrap(), Peer::New);
        let bytes = frame(4000);
        let (head, tail) = bytes.split_at(7);
        let mut got = Decoded::default();
        client.write_all(head).unwrap();
        client.flush().unwrap();
        // Half a frame is no message, however long it is waited for.
        while t.decoder.pending() < head.len() {
            assert!(!t.receive(Duration::from_secs(5), &mut got).unwrap());
        }
        client.write_all(tail).unwrap();
        while got.messages.is_empty() {
            t.receive(Duration::from_secs(5), &mut got).unwrap();
        }
        assert_eq!((got.messages.len(), got.malformed), (1, 0));

        drop(client);
        while t.stream.is_some() {
            t.receive(Duration::from_secs(5), &mut got).unwrap();
        }
        assert_eq!(t.peer(Duration::ZERO).unwrap(), Peer::Absent);
        let mut again = TcpStream::connect(t.local_addr().unwrap()).unwrap();
        assert_eq!(t.peer(Duration::from_secs(5)).unwrap(), Peer::New);
        again.write_all(&frame(8000)).unwrap();
        got.messages.clear();
        while got.messages.is_empty() {
            t.receive(Duration::from_secs(5), &mut got).unwrap();
        }
        assert_eq!(got.messages.len(), 1, "the next autopilot is heard");
    }
}
