//! Sensor links: where the sensor frames come from and where the actuator commands go. The
//! embedded simulator, a simulator process over UDP and a flight board on a serial line all carry
//! the same HIL messages; the flight loop does not know which one it talks to.

use anyhow::{Context, Result, bail};
use hil::{Decoded, StreamDecoder};
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A source of HIL sensor messages that takes `HIL_ACTUATOR_CONTROLS` back.
pub trait SensorLink {
    /// Waits up to `timeout` for messages and appends them (and the count of malformed frames)
    /// to `into`. Returns false when nothing arrived in time.
    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> io::Result<bool>;
    /// Sends the answer (MAVLink frames) back to whoever sent the last sensor frame.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// What the link is, for messages.
    fn describe(&self) -> String;
}

/// Where the sensors come from, as given on the command line.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// The embedded simulator.
    Embedded,
    /// A simulator process sending to this UDP address.
    Udp(SocketAddr),
    /// A flight board on a serial port.
    Serial {
        /// Device path.
        path: PathBuf,
        /// Baud rate.
        baud: u32,
    },
}

impl Source {
    /// Parses `sim`, `udp://HOST:PORT` or `serial:///dev/ttyX?baud=N`; a UDP port is offset by
    /// `instance`.
    pub fn parse(url: &str, instance: u16) -> Result<Self> {
        if url == "sim" {
            return Ok(Self::Embedded);
        }
        if let Some(addr) = url.strip_prefix("udp://") {
            let mut a: SocketAddr = addr.parse().with_context(|| {
                format!("{url:?}: expected udp://ADDRESS:PORT, e.g. udp://0.0.0.0:4560")
            })?;
            a.set_port(a.port().checked_add(instance).with_context(|| {
                format!("{url:?}: instance {instance} pushes the port past 65535")
            })?);
            return Ok(Self::Udp(a));
        }
        if let Some(rest) = url.strip_prefix("serial://") {
            let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
            if path.is_empty() {
                bail!("{url:?}: expected serial:///dev/ttyUSB0?baud=921600");
            }
            let mut baud = 921_600;
            for kv in query.split('&').filter(|kv| !kv.is_empty()) {
                match kv.split_once('=') {
                    Some(("baud", v)) => {
                        baud = v
                            .parse()
                            .ok()
                            .filter(|b| (1200..=12_000_000).contains(b))
                            .with_context(|| {
                                format!("{url:?}: baud must be a rate within [1200, 12000000], got {v:?}")
                            })?;
                    }
                    _ => bail!("{url:?}: unknown option {kv:?} (known: baud)"),
                }
            }
            return Ok(Self::Serial {
                path: PathBuf::from(path),
                baud,
            });
        }
        bail!(
            "unknown sensor source {url:?}: give sim, udp://ADDRESS:PORT or serial:///dev/ttyX?baud=N"
        )
    }
}

/// A read that ended without data and without a fault: timed out, would block, or interrupted
/// by a signal (Ctrl-C).
fn nothing_yet(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// A simulator process on UDP: binds the autopilot's port, answers whoever sent the last frame.
pub struct UdpLink {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    rx: Vec<u8>,
}

impl UdpLink {
    /// Binds `addr`.
    pub fn bind(addr: SocketAddr) -> Result<Self> {
        let socket = UdpSocket::bind(addr).with_context(|| {
            format!("binding the simulator port {addr} (is another autopilot using it? try -i N)")
        })?;
        Ok(Self {
            socket,
            peer: None,
            rx: vec![0; 65_536],
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
}

impl SensorLink for UdpLink {
    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> io::Result<bool> {
        self.socket
            .set_read_timeout(Some(timeout.max(Duration::from_micros(1))))?;
        match self.socket.recv_from(&mut self.rx) {
            Ok((len, from)) => {
                if self.peer != Some(from) {
                    tracing::info!(simulator = %from, "sensor frames arriving");
                    self.peer = Some(from);
                }
                let d = hil::decode(&self.rx[..len]);
                into.messages.extend(d.messages);
                into.malformed += d.malformed;
                Ok(true)
            }
            // Connection refused: an ICMP answer to an earlier send; the simulator may come back.
            Err(e) if nothing_yet(&e) || e.kind() == io::ErrorKind::ConnectionRefused => Ok(false),
            Err(e) => Err(e),
        }
    }

    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let Some(peer) = self.peer else {
            return Ok(());
        };
        match self.socket.send_to(bytes, peer) {
            // The simulator went away; it may come back.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => Ok(()),
            r => r.map(|_| ()),
        }
    }

    fn describe(&self) -> String {
        match self.socket.local_addr() {
            Ok(a) => format!("udp://{a}"),
            Err(_) => "udp".into(),
        }
    }
}

/// A flight board on a serial line: MAVLink frames in a byte stream. A port that is missing or
/// vanishes is reopened with backoff (0.1 s doubling to 2 s); meanwhile the link reports
/// silence, as for any sensor that stops.
pub struct SerialLink {
    path: PathBuf,
    baud: u32,
    port: Option<serialport::TTYPort>,
    decoder: StreamDecoder,
    rx: Vec<u8>,
    retry_at: Instant,
    backoff: Duration,
}

impl SerialLink {
    /// Opens `path` at `baud`; a port that cannot be opened now is an error (a typo should stop
    /// the daemon), one that vanishes later is retried.
    pub fn open(path: PathBuf, baud: u32) -> Result<Self> {
        let port = Self::open_port(&path, baud)
            .with_context(|| format!("opening serial port {}", path.display()))?;
        Ok(Self {
            path,
            baud,
            port: Some(port),
            decoder: StreamDecoder::default(),
            rx: vec![0; 4096],
            retry_at: Instant::now(),
            backoff: Duration::from_millis(100),
        })
    }

    fn open_port(path: &Path, baud: u32) -> serialport::Result<serialport::TTYPort> {
        serialport::new(path.to_string_lossy(), baud)
            .timeout(Duration::from_millis(10))
            .open_native()
    }

    fn lost(&mut self, e: &dyn std::fmt::Display) {
        tracing::error!(port = %self.path.display(), "serial link lost: {e}; reopening");
        self.port = None;
        self.decoder = StreamDecoder::default();
        self.backoff = Duration::from_millis(100);
        self.retry_at = Instant::now() + self.backoff;
    }
}

impl SensorLink for SerialLink {
    fn receive(&mut self, timeout: Duration, into: &mut Decoded) -> io::Result<bool> {
        use std::io::Read;
        let Some(port) = self.port.as_mut() else {
            let now = Instant::now();
            if now < self.retry_at {
                std::thread::sleep(timeout.min(self.retry_at - now));
                return Ok(false);
            }
            match Self::open_port(&self.path, self.baud) {
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
        serialport::SerialPort::set_timeout(port, timeout)?;
        let before = into.messages.len();
        match port.read(&mut self.rx) {
            // End of file: the other side closed (a pty whose simulator exited).
            Ok(0) => {
                self.lost(&"end of stream");
                Ok(false)
            }
            Ok(n) => {
                self.decoder.push(&self.rx[..n], into);
                Ok(into.messages.len() > before)
            }
            Err(e) if nothing_yet(&e) => Ok(false),
            Err(e) => {
                self.lost(&e);
                Ok(false)
            }
        }
    }

    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        use std::io::Write;
        let Some(port) = self.port.as_mut() else {
            return Ok(());
        };
        if let Err(e) = port.write_all(bytes) {
            self.lost(&e);
        }
        Ok(())
    }

    fn describe(&self) -> String {
        format!("serial://{}?baud={}", self.path.display(), self.baud)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_parse_with_clear_errors() {
        assert_eq!(Source::parse("sim", 3).unwrap(), Source::Embedded);
        assert_eq!(
            Source::parse("udp://0.0.0.0:4560", 2).unwrap(),
            Source::Udp("0.0.0.0:4562".parse().unwrap())
        );
        assert_eq!(
            Source::parse("serial:///dev/ttyUSB0?baud=57600", 0).unwrap(),
            Source::Serial {
                path: "/dev/ttyUSB0".into(),
                baud: 57_600
            }
        );
        assert_eq!(
            Source::parse("serial:///dev/ttyACM0", 0).unwrap(),
            Source::Serial {
                path: "/dev/ttyACM0".into(),
                baud: 921_600
            }
        );
        for (bad, says) in [
            ("udp://nowhere", "expected udp://ADDRESS:PORT"),
            ("udp://0.0.0.0:65535", "past 65535"),
            ("serial://?baud=9600", "expected serial:///dev/"),
            ("serial:///dev/ttyS0?baud=fast", "baud must be"),
            ("serial:///dev/ttyS0?parity=odd", "unknown option"),
            ("tcp://1.2.3.4:5", "unknown sensor source"),
        ] {
            let e = format!("{:#}", Source::parse(bad, 1).unwrap_err());
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
