//! A device's serial port at the edge: opened at the device's settings, opened again every
//! second after it vanished (a USB device unplugged), read without waiting, written, its baud
//! changed; what went wrong said once.

use serialport::{DataBits, Parity, SerialPort, StopBits, TTYPort};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::Duration;

/// How often a port that cannot be opened is tried again (s, sensor clock).
const REOPEN_S: f64 = 1.0;

/// The port.
pub struct DevicePort {
    /// What the device is, for messages ("GPS", "RC receiver").
    what: &'static str,
    path: PathBuf,
    baud: u32,
    parity: Parity,
    stop_bits: StopBits,
    port: Option<TTYPort>,
    retry_at: f64,
    said: Option<String>,
    buf: Vec<u8>,
}

impl DevicePort {
    /// The `what` on `path`, at `baud` 8 data bits, `parity`, `stop_bits` (opened when first
    /// read).
    pub fn new(
        what: &'static str,
        path: PathBuf,
        baud: u32,
        parity: Parity,
        stop_bits: StopBits,
    ) -> Self {
        Self {
            what,
            path,
            baud,
            parity,
            stop_bits,
            port: None,
            retry_at: f64::NEG_INFINITY,
            said: None,
            buf: vec![0; 4096],
        }
    }

    /// Its path, for messages.
    pub fn path(&self) -> String {
        self.path.display().to_string()
    }

    /// What the port holds at `t_s` (opening it first when due); empty when nothing.
    pub fn read(&mut self, t_s: f64) -> &[u8] {
        self.open_if_due(t_s);
        let Some(port) = self.port.as_mut() else {
            return &[];
        };
        match read_available(port, &mut self.buf) {
            Ok(n) => &self.buf[..n],
            Err(e) => {
                self.lost(t_s, &format!("reading it: {e}"));
                &[]
            }
        }
    }

    /// Sets the port to `baud` (when it differs) and writes `bytes`.
    pub fn write(&mut self, t_s: f64, baud: u32, bytes: &[u8]) {
        let Some(port) = self.port.as_mut() else {
            return;
        };
        let result = if baud != self.baud {
            port.set_baud_rate(baud)
                .map(|()| self.baud = baud)
                .map_err(std::io::Error::from)
        } else {
            Ok(())
        }
        .and_then(|()| port.write_all(bytes));
        if let Err(e) = result {
            self.lost(t_s, &format!("writing it: {e}"));
        }
    }

    fn open_if_due(&mut self, t_s: f64) {
        if self.port.is_some() || t_s < self.retry_at {
            return;
        }
        self.retry_at = t_s + REOPEN_S;
        let path = self.path.to_string_lossy().into_owned();
        match serialport::new(&path, self.baud)
            .data_bits(DataBits::Eight)
            .parity(self.parity)
            .stop_bits(self.stop_bits)
            .timeout(Duration::ZERO)
            .open_native()
        {
            Ok(port) => {
                self.port = Some(port);
                self.said = None;
                tracing::info!(port = %path, baud = self.baud, "{} port open", self.what);
            }
            Err(e) => self.say_once(format!("cannot open it ({e}): trying again every second")),
        }
    }

    fn lost(&mut self, t_s: f64, why: &str) {
        self.port = None;
        self.retry_at = t_s + REOPEN_S;
        self.say_once(format!("port lost {why}"));
    }

    fn say_once(&mut self, what: String) {
        if self.said.as_deref() != Some(what.as_str()) {
            tracing::warn!(port = %self.path.display(), "{}: {what}", self.what);
            self.said = Some(what);
        }
    }
}

/// Reads what `port` holds now, without waiting: 0 when nothing.
fn read_available(port: &mut TTYPort, buf: &mut [u8]) -> std::io::Result<usize> {
    let n = port.bytes_to_read().map_err(std::io::Error::from)? as usize;
    if n == 0 {
        return Ok(0);
    }
    let n = n.min(buf.len());
    match port.read(&mut buf[..n]) {
        Ok(0) => Err(std::io::Error::new(
            std::io::ErrorKind::UnexpectedEof,
            "the device closed",
        )),
        Ok(n) => Ok(n),
        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(0),
        Err(e) => Err(e),
    }
}
