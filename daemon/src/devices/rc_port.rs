//! An RC receiver's serial port: CRSF (ExpressLRS, TBS Crossfire) at 420 000 baud 8N1, or
//! SBUS at 100 000 baud 8E2 (inverted on the wire: a UART that inverts, or an inverter in
//! front of it). Read on every sensor frame; the newest frame of channels goes to the
//! autopilot with the link's last statistics.

use super::serial_device::DevicePort;
use crate::links::parse_options;
use anyhow::{Result, bail};
use devices::rc::crsf::{self, CrsfReader};
use devices::rc::sbus::{self, SbusReader};
use devices::rc::{RcCounters, RcEvent, RcInput, RcLink};
use flight_core::autopilot::VehicleState;
use flight_core::commander::rc_input::{RcFrame, RcLinkQuality};
use serialport::{Parity, StopBits};
use std::path::PathBuf;

/// The protocols an RC port can speak.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RcProtocol {
    /// CRSF.
    Crsf,
    /// SBUS.
    Sbus,
}

/// An RC receiver on a serial port, as `serial:///dev/ttyX?protocol=crsf|sbus` gives it.
#[derive(Debug, Clone, PartialEq)]
pub struct RcSpec {
    /// The port.
    pub path: PathBuf,
    /// The protocol.
    pub protocol: RcProtocol,
}

impl RcSpec {
    /// Parses the URL.
    pub fn parse(url: &str) -> Result<Self> {
        let Some(rest) = url.strip_prefix("serial://") else {
            bail!("--rc {url:?}: expected serial:///dev/ttyX?protocol=crsf (or sbus)");
        };
        let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
        if path.is_empty() {
            bail!("--rc {url:?}: no device path");
        }
        let mut protocol = RcProtocol::Crsf;
        let url = format!("--rc {url}");
        parse_options(
            &url,
            query,
            |k, v| {
                protocol = match (k, v) {
                    ("protocol", "crsf") => RcProtocol::Crsf,
                    ("protocol", "sbus") => RcProtocol::Sbus,
                    _ => return Ok(false),
                };
                Ok(true)
            },
            "protocol=crsf, protocol=sbus",
        )?;
        Ok(Self {
            path: PathBuf::from(path),
            protocol,
        })
    }
}

enum Reader {
    Crsf(CrsfReader),
    Sbus(SbusReader),
}

/// The port and its reader.
pub struct RcPort {
    port: DevicePort,
    baud: u32,
    reader: Reader,
    link: Option<RcLinkQuality>,
    events: Vec<RcEvent>,
    /// When telemetry last went to the transmitter (s, sensor time).
    told_at: f64,
    out: Vec<u8>,
}

/// How often a CRSF receiver is given the vehicle's telemetry (s): 5 Hz, as PX4's `crsf_rc`.
const TELEMETRY_S: f64 = 0.2;

impl RcPort {
    /// The port of `spec`, opened at the first [`Self::poll`].
    pub fn new(spec: RcSpec) -> Self {
        let (baud, parity, stop, reader) = match spec.protocol {
            RcProtocol::Crsf => (
                crsf::BAUD,
                Parity::None,
                StopBits::One,
                Reader::Crsf(CrsfReader::default()),
            ),
            RcProtocol::Sbus => (
                sbus::BAUD,
                Parity::Even,
                StopBits::Two,
                Reader::Sbus(SbusReader::default()),
            ),
        };
        Self {
            port: DevicePort::new("RC receiver", spec.path, baud, parity, stop),
            baud,
            reader,
            link: None,
            events: Vec::new(),
            told_at: f64::NEG_INFINITY,
            out: Vec::new(),
        }
    }

    /// What the port is, for messages.
    pub fn describe(&self) -> String {
        format!("RC receiver on {}", self.port.path())
    }

    fn counters(&self) -> RcCounters {
        match &self.reader {
            Reader::Crsf(r) => r.counters(),
            Reader::Sbus(r) => r.counters(),
        }
    }

    /// At `t_s` (the sensor clock): the newest frame of channels the port brought.
    pub fn poll(&mut self, t_s: f64) -> Option<RcFrame> {
        let bytes = self.port.read(t_s);
        match &mut self.reader {
            Reader::Crsf(r) => r.receive(bytes, &mut self.events),
            Reader::Sbus(r) => r.receive(bytes, &mut self.events),
        }
        let mut newest = None;
        for e in self.events.drain(..) {
            match e {
                RcEvent::Channels(c) => newest = Some(c),
                RcEvent::Link(l) => self.link = Some(quality(&l)),
            }
        }
        newest.map(|c: RcInput| RcFrame {
            channels: c.channels,
            count: c.count,
            failsafe: c.failsafe,
            link: self.link,
        })
    }
}

impl RcPort {
    /// Whether the transmitter is due its telemetry at `t_s`.
    pub fn telemetry_due(&self, t_s: f64) -> bool {
        matches!(self.reader, Reader::Crsf(_)) && t_s - self.told_at >= TELEMETRY_S
    }

    /// At `t_s`, every [`TELEMETRY_S`]: the vehicle's battery, attitude, GPS and flight mode
    /// to a CRSF receiver, which sends them on to the transmitter's screen (SBUS is one-way).
    pub fn tell(&mut self, t_s: f64, v: &VehicleState) {
        if !self.telemetry_due(t_s) {
            return;
        }
        self.told_at = t_s;
        use crsf::telemetry;
        self.out.clear();
        let b = &v.battery;
        telemetry::battery(
            v.battery_v,
            b.current_a.unwrap_or(0.0),
            b.consumed_mah.unwrap_or(0.0),
            b.remaining
                .map_or(0, |r| (r * 100.0).round().clamp(0.0, 100.0) as u8),
            &mut self.out,
        );
        if let Some(a) = v.estimate.and_then(|e| e.attitude) {
            let (roll, pitch, yaw) = a.q.euler_angles();
            telemetry::attitude(pitch, roll, yaw, &mut self.out);
        }
        if let Some(g) = v.gps {
            let vel = g.vel_ned_m_s;
            let heading = vel.y.atan2(vel.x).to_degrees();
            let p = &g.position;
            let (speed, sats) = (vel.xy().norm(), g.satellites);
            telemetry::gps(
                p.lat_deg,
                p.lon_deg,
                speed,
                heading,
                p.alt_m,
                sats,
                &mut self.out,
            );
        }
        telemetry::flight_mode(v.status.mode.name(), &mut self.out);
        self.port.write(t_s, self.baud, &self.out);
    }
}

fn quality(l: &RcLink) -> RcLinkQuality {
    RcLinkQuality {
        rssi_dbm: l.rssi_dbm,
        quality_pct: l.link_quality,
        snr_db: l.snr_db,
        downlink_quality_pct: l.downlink_link_quality,
    }
}

impl Drop for RcPort {
    /// What the port brought over the run, said once at its end.
    fn drop(&mut self) {
        let c = self.counters();
        tracing::info!(
            port = %self.port.path(),
            bytes = c.bytes,
            frames = c.frames,
            refused = c.bad_frames,
            "RC receiver port closed"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_rc_url_gives_its_port_and_protocol_and_a_bad_one_says_why() {
        let s = RcSpec::parse("serial:///dev/ttyS2?protocol=sbus").expect("valid");
        assert_eq!(
            (s.path, s.protocol),
            (PathBuf::from("/dev/ttyS2"), RcProtocol::Sbus)
        );
        let s = RcSpec::parse("serial:///dev/ttyACM1").expect("valid");
        assert_eq!(s.protocol, RcProtocol::Crsf);
        for (bad, says) in [
            ("/dev/ttyS2", "expected serial://"),
            ("serial://", "no device path"),
            ("serial:///dev/x?protocol=ppm", "unknown option"),
        ] {
            let e = RcSpec::parse(bad).expect_err(bad).to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
