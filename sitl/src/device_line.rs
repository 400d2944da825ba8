//! The serial line a simulated device talks on: a new pseudo-terminal pair (the far end's name
//! for the autopilot, that end held open until the autopilot opens it), or a real port; written
//! without waiting, what nobody reads dropped as a UART's bytes are.

use anyhow::{Context, Result};
use serialport::{SerialPort, TTYPort};
use std::io::Write;
use std::time::Duration;

/// The device's end of its line.
pub struct DeviceLine {
    port: TTYPort,
    _peer: Option<TTYPort>,
    name: String,
    /// Bytes nobody read (the autopilot not there yet).
    pub dropped: u64,
}

impl DeviceLine {
    /// `pty` for a new pseudo-terminal pair, else the port `device` at `baud`.
    pub fn open(device: &str, baud: u32) -> Result<Self> {
        let (port, peer, name) = if device == "pty" {
            let (mut ours, theirs) = TTYPort::pair().context("opening a pseudo-terminal pair")?;
            ours.set_timeout(Duration::ZERO)?;
            let name = theirs.name().context("the pseudo-terminal has no name")?;
            (ours, Some(theirs), name)
        } else {
            let port = serialport::new(device, baud)
                .timeout(Duration::ZERO)
                .open_native()
                .with_context(|| format!("opening {device}"))?;
            (port, None, device.to_owned())
        };
        Ok(Self {
            port,
            _peer: peer,
            name,
            dropped: 0,
        })
    }

    /// The device the autopilot opens.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The port, to read and to ask its settings.
    pub fn port(&mut self) -> &mut TTYPort {
        &mut self.port
    }

    /// Writes `bytes` without waiting; what the line cannot take now is dropped and counted.
    pub fn write(&mut self, bytes: &[u8]) -> Result<()> {
        match self.port.write(bytes) {
            Ok(k) => self.dropped += (bytes.len() - k) as u64,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                self.dropped += bytes.len() as u64;
            }
            Err(e) => return Err(e).with_context(|| format!("writing {}", self.name)),
        }
        Ok(())
    }
}
