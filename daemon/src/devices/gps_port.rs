//! A GPS receiver's serial port: opened (and opened again after it vanished), read without
//! waiting on every sensor frame, set to the baud its driver asks for, and written what the
//! driver says. Its solutions become the estimator's [`GpsMeasurement`]s, stamped with the
//! sensor frame they arrive with; the receiver's latency (measurement to the end of its
//! output, about 0.1 s for a u-blox at 5 Hz) is what the estimator's `EST_GPS_DELAY` takes
//! back, as EKF2's `EKF2_GPS_DELAY` does.

use super::GpsSpec;
use devices::gps::{GpsCounters, GpsDriver, GpsEvent, GpsSolution};
use flight_core::estimator::translation::{GpsDetails, GpsMeasurement};
use flight_core::math::geo::LatLonAlt;
use nalgebra::Vector3;
use serialport::{SerialPort, TTYPort};
use std::io::Read;
use std::io::Write;
use std::time::Duration;

/// How often a port that cannot be opened is tried again (s, sensor clock).
const REOPEN_S: f64 = 1.0;
/// The standard deviation of one metre of HDOP, for a receiver that states no accuracy
/// (NMEA without `GST`): a user equivalent range error of about 1.5 m, as single-frequency
/// receivers without corrections have.
const UERE_M: f64 = 1.5;

/// The port and its driver.
pub struct GpsPort {
    spec: GpsSpec,
    port: Option<TTYPort>,
    port_baud: u32,
    driver: GpsDriver,
    retry_at: f64,
    /// The last failure said, so that one is said once.
    said: Option<String>,
    events: Vec<GpsEvent>,
    out: Vec<u8>,
    buf: Vec<u8>,
}

impl GpsPort {
    /// The port of `spec`, opened at the first [`Self::poll`].
    pub fn new(spec: GpsSpec) -> Self {
        Self {
            driver: GpsDriver::new(spec.protocol, spec.baud, spec.rate_hz),
            port_baud: spec.baud,
            spec,
            port: None,
            retry_at: f64::NEG_INFINITY,
            said: None,
            events: Vec::new(),
            out: Vec::new(),
            buf: vec![0; 4096],
        }
    }

    /// What the port is, for messages.
    pub fn describe(&self) -> String {
        format!("GPS on {}", self.spec.path.display())
    }

    /// What the driver has counted.
    pub fn counters(&self) -> GpsCounters {
        self.driver.counters()
    }
}

impl Drop for GpsPort {
    /// What the port brought over the run, said once at its end.
    fn drop(&mut self) {
        let c = self.counters();
        tracing::info!(
            port = %self.spec.path.display(),
            bytes = c.bytes,
            frames = c.frames,
            refused = c.bad_frames,
            solutions = c.solutions,
            "GPS port closed"
        );
    }
}

impl GpsPort {
    /// At `t_s` (the sensor clock): reads what the port holds, runs the driver, writes what
    /// it asks for. Returns the newest solution read.
    pub fn poll(&mut self, t_s: f64) -> Option<GpsMeasurement> {
        self.open_if_due(t_s);
        let mut newest = None;
        if let Some(port) = self.port.as_mut() {
            match read_available(port, &mut self.buf) {
                Ok(0) => {}
                Ok(n) => self.driver.receive(t_s, &self.buf[..n], &mut self.events),
                Err(e) => self.lost(t_s, &format!("reading it: {e}")),
            }
        }
        self.out.clear();
        self.driver.poll(t_s, &mut self.out, &mut self.events);
        if let Some(port) = self.port.as_mut() {
            let result = if self.driver.baud() != self.port_baud {
                port.set_baud_rate(self.driver.baud())
                    .map(|()| self.port_baud = self.driver.baud())
                    .map_err(std::io::Error::from)
            } else {
                Ok(())
            }
            .and_then(|()| port.write_all(&self.out));
            if let Err(e) = result {
                self.lost(t_s, &format!("writing it: {e}"));
            }
        }
        for event in self.events.drain(..) {
            match event {
                GpsEvent::Solution(s) => newest = Some(measurement(&s)),
                other => say(&self.spec.path.display().to_string(), &other),
            }
        }
        newest
    }

    fn open_if_due(&mut self, t_s: f64) {
        if self.port.is_some() || t_s < self.retry_at {
            return;
        }
        self.retry_at = t_s + REOPEN_S;
        let path = self.spec.path.to_string_lossy();
        match serialport::new(path.as_ref(), self.driver.baud())
            .timeout(Duration::ZERO)
            .open_native()
        {
            Ok(port) => {
                self.port_baud = self.driver.baud();
                self.port = Some(port);
                self.said = None;
                tracing::info!(port = %path, baud = self.port_baud, "GPS port open");
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
            tracing::warn!(port = %self.spec.path.display(), "GPS: {what}");
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

/// Says what the driver said, once as it happens.
fn say(port: &str, event: &GpsEvent) {
    match event {
        GpsEvent::Found { baud } => tracing::info!(port, baud, "GPS found"),
        GpsEvent::Identified {
            software,
            hardware,
            protocol,
        } => tracing::info!(port, software, hardware, protocol, "u-blox receiver"),
        GpsEvent::Configured { interface } => tracing::info!(port, interface, "GPS configured"),
        GpsEvent::Refused { message, nak: true } => {
            tracing::warn!(port, message, "the GPS refused (ACK-NAK)")
        }
        GpsEvent::Refused {
            message,
            nak: false,
        } => {
            tracing::warn!(port, message, "the GPS did not answer")
        }
        GpsEvent::Silent => tracing::warn!(port, "GPS silent: no solution for a second"),
        GpsEvent::Lost => tracing::warn!(port, "GPS lost: looking for it at every baud"),
        GpsEvent::Solution(_) => {}
    }
}

/// A receiver's solution as the estimator takes it.
pub fn measurement(s: &GpsSolution) -> GpsMeasurement {
    let [n, e] = s.vel_ne_m_s.unwrap_or([0.0, 0.0]);
    GpsMeasurement {
        fix_type: s.fix.mavlink(),
        position: LatLonAlt {
            lat_deg: s.lat_deg,
            lon_deg: s.lon_deg,
            alt_m: s.alt_msl_m,
        },
        vel_ned_m_s: Vector3::new(n, e, s.vel_down_m_s.unwrap_or(0.0)),
        h_acc_m: s.h_acc_m.unwrap_or(s.hdop.unwrap_or(1.0) * UERE_M),
        satellites: s.satellites,
        details: GpsDetails {
            v_acc_m: s.v_acc_m,
            s_acc_m_s: s.s_acc_m_s,
            heading_acc_deg: s.heading_acc_deg,
            dop: s.hdop.zip(s.vdop),
            time_utc_usec: s.time_utc_usec,
            no_horizontal_velocity: s.vel_ne_m_s.is_none(),
            no_vertical_velocity: s.vel_down_m_s.is_none(),
        },
    }
}
