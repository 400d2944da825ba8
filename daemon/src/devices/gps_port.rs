//! A GPS receiver's serial port: opened (and opened again after it vanished), read without
//! waiting on every sensor frame, set to the baud its driver asks for, and written what the
//! driver says. Its solutions become the estimator's [`GpsMeasurement`]s, stamped with the
//! sensor frame they arrive with; the receiver's latency (measurement to the end of its
//! output, about 0.1 s for a u-blox at 5 Hz) is what the estimator's `EST_GPS_DELAY` takes
//! back, as EKF2's `EKF2_GPS_DELAY` does.

use super::GpsSpec;
use super::serial_device::DevicePort;
use devices::gps::{GpsCounters, GpsDriver, GpsEvent, GpsSolution};
use flight_core::estimator::translation::{GpsDetails, GpsMeasurement};
use flight_core::math::geo::LatLonAlt;
use nalgebra::Vector3;
use serialport::{Parity, StopBits};

/// The standard deviation of one metre of HDOP, for a receiver that states no accuracy
/// (NMEA without `GST`): a user equivalent range error of about 1.5 m, as single-frequency
/// receivers without corrections have.
const UERE_M: f64 = 1.5;

/// The port and its driver.
pub struct GpsPort {
    port: DevicePort,
    driver: GpsDriver,
    events: Vec<GpsEvent>,
    out: Vec<u8>,
}

impl GpsPort {
    /// The port of `spec`, opened at the first [`Self::poll`].
    pub fn new(spec: GpsSpec) -> Self {
        Self {
            driver: GpsDriver::new(spec.protocol, spec.baud, spec.rate_hz),
            port: DevicePort::new("GPS", spec.path, spec.baud, Parity::None, StopBits::One),
            events: Vec::new(),
            out: Vec::new(),
        }
    }

    /// What the port is, for messages.
    pub fn describe(&self) -> String {
        format!("GPS on {}", self.port.path())
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
            port = %self.port.path(),
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
        let bytes = self.port.read(t_s);
        if !bytes.is_empty() {
            self.driver.receive(t_s, bytes, &mut self.events);
        }
        self.out.clear();
        self.driver.poll(t_s, &mut self.out, &mut self.events);
        self.port.write(t_s, self.driver.baud(), &self.out);
        let mut newest = None;
        let path = self.port.path();
        for event in self.events.drain(..) {
            match event {
                GpsEvent::Solution(s) => newest = Some(measurement(&s)),
                other => say(&path, &other),
            }
        }
        newest
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
