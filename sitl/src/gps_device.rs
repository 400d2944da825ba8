//! The simulator playing a GPS receiver on a serial port (`--gps-device`): a u-blox of a given
//! generation, or an NMEA-only receiver, on a new pseudo-terminal (its name printed as
//! `sitl gps: /dev/pts/N` for `autopilot --gps serial:///dev/pts/N`) or a real serial device.
//!
//! Each exchange it reads what the autopilot wrote and answers (the receiver's configuration
//! dialogue), and at each of the receiver's epochs writes the simulator's newest GPS fix as
//! the receiver would. The autopilot's end of a pseudo-terminal sets the line's baud, and the
//! simulator reads it back: bytes cross whole only when both ends are at one baud, and are
//! misread as a real UART would otherwise. The GPS sensor switched off in the scenario
//! (`sensor_off`, `sensor = "gps"`) is the receiver unplugged; switched on again, it is
//! plugged back in at its power-on defaults.

use crate::device_line::DeviceLine;
use anyhow::{Context, Result, bail};
use devices::gps::FixType;
use devices::sim::ublox_receiver::{ReceiverModel, UbloxReceiver};
use devices::sim::{NmeaReceiver, ReceiverFix, misread};
use serialport::SerialPort;
use sitl_core::sensors::{GpsFix, SensorHealth};
use std::io::Read;
use std::time::{SystemTime, UNIX_EPOCH};

/// The receiver played.
enum Played {
    Ublox(UbloxReceiver),
    Nmea(NmeaReceiver),
}

impl Played {
    fn baud(&self) -> u32 {
        match self {
            Self::Ublox(r) => r.baud(),
            Self::Nmea(r) => r.baud,
        }
    }

    fn period_s(&self) -> f64 {
        match self {
            Self::Ublox(r) => r.period_s(),
            Self::Nmea(r) => r.period_s,
        }
    }
}

/// The device.
pub struct GpsDevice {
    line: DeviceLine,
    played: Played,
    /// UTC at simulation time 0 (µs since the Unix epoch): the wall clock when the run began.
    utc_start_usec: u64,
    next_epoch_usec: u64,
    unplugged: bool,
    inbuf: Vec<u8>,
    out: Vec<u8>,
    wire: Vec<u8>,
}

impl GpsDevice {
    /// `MODEL[:DEVICE]`: `m8`, `m9`, `m10`, `f9p` or `nmea`, on `pty` (the default) or a device.
    pub fn open(spec: &str) -> Result<Self> {
        let (model, device) = spec.split_once(':').unwrap_or((spec, "pty"));
        let played = match (model, ReceiverModel::from_name(model)) {
            (_, Some(m)) => Played::Ublox(UbloxReceiver::new(m)),
            ("nmea", None) => Played::Nmea(NmeaReceiver::new(38_400, 5.0)),
            _ => bail!("--gps-device {spec:?}: the model is m8, m9, m10, f9p or nmea"),
        };
        let line = DeviceLine::open(device, played.baud())?;
        let utc_start_usec = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        Ok(Self {
            line,
            played,
            utc_start_usec,
            next_epoch_usec: 0,
            unplugged: false,
            inbuf: vec![0; 4096],
            out: Vec::new(),
            wire: Vec::new(),
        })
    }

    /// The device the autopilot opens.
    pub fn name(&self) -> &str {
        self.line.name()
    }

    /// The baud the autopilot's end is at: a pseudo-terminal's settings are shared by its two
    /// ends; a real port reports its own.
    fn line_baud(&mut self) -> u32 {
        self.line.port().baud_rate().unwrap_or(0)
    }

    /// One exchange: the autopilot's bytes read and answered, and `fix` (the simulator's GPS
    /// fix delivered in this frame) written when it starts an epoch of the receiver. `health`
    /// is the GPS sensor's: off is unplugged.
    pub fn step(&mut self, fix: Option<&GpsFix>, health: SensorHealth) -> Result<()> {
        let unplugged = health == SensorHealth::Off;
        if self.unplugged && !unplugged {
            if let Played::Ublox(r) = &mut self.played {
                r.restart();
            }
            tracing::info!(device = %self.line.name(), "GPS plugged in again, at its defaults");
        }
        self.unplugged = unplugged;
        let line = self.line_baud();
        let theirs = self.read()?;
        if unplugged {
            return Ok(());
        }
        self.out.clear();
        if let Played::Ublox(r) = &mut self.played {
            let ours = r.baud();
            if line == ours {
                r.receive(&theirs, &mut self.out);
            } else {
                self.wire.clear();
                misread(&theirs, line, ours, &mut self.wire);
                r.receive(&self.wire, &mut self.out);
            }
        }
        if let Some(f) = fix.filter(|f| f.time_usec >= self.next_epoch_usec) {
            let period_usec = (self.played.period_s() * 1e6) as u64;
            // Epochs on the receiver's grid, a fix in each (the simulator's GPS runs faster).
            self.next_epoch_usec = (f.time_usec / period_usec + 1) * period_usec - period_usec / 10;
            let rf = self.receiver_fix(f);
            match &mut self.played {
                Played::Ublox(r) => r.epoch(&rf, &mut self.out),
                Played::Nmea(r) => r.epoch(&rf, &mut self.out),
            }
        }
        self.write(line)
    }

    fn receiver_fix(&self, f: &GpsFix) -> ReceiverFix {
        // The simulator models accuracies, not satellite geometry: dilutions as the
        // accuracies over a 1.5 m range error.
        let dop = |acc: f64| (acc / 1.5).clamp(0.5, 99.0);
        ReceiverFix {
            time_utc_usec: self.utc_start_usec + f.time_usec,
            fix: match f.fix_type {
                0 | 1 => FixType::NoFix,
                2 => FixType::Fix2d,
                _ => FixType::Fix3d,
            },
            lat_deg: f.position.lat_deg,
            lon_deg: f.position.lon_deg,
            alt_msl_m: f.position.alt_m,
            vel_ned_m_s: f.vel_ned_m_s.into(),
            h_acc_m: f.h_acc_m,
            v_acc_m: f.v_acc_m,
            s_acc_m_s: f.s_acc_m_s,
            satellites: f.satellites,
            hdop: dop(f.h_acc_m),
            vdop: dop(f.v_acc_m),
            pdop: dop(f.h_acc_m.hypot(f.v_acc_m)),
        }
    }

    /// What the autopilot wrote since the last exchange.
    fn read(&mut self) -> Result<Vec<u8>> {
        let name = self.line.name().to_owned();
        let port = self.line.port();
        let n = match port.bytes_to_read() {
            Ok(n) => n as usize,
            Err(e) => return Err(e).with_context(|| format!("reading {name}")),
        };
        if n == 0 {
            return Ok(Vec::new());
        }
        let n = n.min(self.inbuf.len());
        match port.read(&mut self.inbuf[..n]) {
            Ok(k) => Ok(self.inbuf[..k].to_vec()),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(Vec::new()),
            Err(e) => Err(e).with_context(|| format!("reading {name}")),
        }
    }

    /// Writes the receiver's output as the autopilot's end, at baud `line`, reads it.
    fn write(&mut self, line: u32) -> Result<()> {
        if self.out.is_empty() {
            return Ok(());
        }
        let ours = self.played.baud();
        let bytes = if line == ours {
            &self.out
        } else {
            self.wire.clear();
            misread(&self.out, ours, line, &mut self.wire);
            &self.wire
        };
        self.line.write(bytes)
    }
}
