//! GPS receivers on a serial port: what a solution holds whatever the protocol
//! ([`GpsSolution`]), what a driver says ([`GpsEvent`]), and one driver per protocol behind
//! [`GpsDriver`]: [`ubx::UbloxDriver`] (UBX) and [`nmea0183::NmeaDriver`] (NMEA 0183).

mod baud_scan;
pub mod nmea0183;
mod ublox_config;
pub mod ubx;
mod utc;

pub use baud_scan::BaudScan;

/// A receiver's fix, in MAVLink's `GPS_FIX_TYPE` terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixType {
    /// A receiver that talks but has no position.
    NoFix,
    /// Latitude and longitude only.
    Fix2d,
    /// Latitude, longitude and altitude.
    Fix3d,
    /// A 3D fix with differential corrections (SBAS or DGPS).
    Dgps,
    /// RTK with float ambiguities.
    RtkFloat,
    /// RTK with fixed ambiguities.
    RtkFixed,
}

impl FixType {
    /// The `GPS_FIX_TYPE` number (1 no fix … 6 RTK fixed).
    pub fn mavlink(self) -> u8 {
        match self {
            Self::NoFix => 1,
            Self::Fix2d => 2,
            Self::Fix3d => 3,
            Self::Dgps => 4,
            Self::RtkFloat => 5,
            Self::RtkFixed => 6,
        }
    }
}

/// One navigation solution, whatever protocol carried it. What a protocol does not say is
/// `None` (NMEA has no vertical velocity, and its accuracies only with GST).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsSolution {
    /// The fix.
    pub fix: FixType,
    /// Latitude (deg, WGS-84).
    pub lat_deg: f64,
    /// Longitude (deg, WGS-84).
    pub lon_deg: f64,
    /// Altitude above mean sea level (m).
    pub alt_msl_m: f64,
    /// Velocity over the ground, north and east (m/s).
    pub vel_ne_m_s: Option<[f64; 2]>,
    /// Velocity down (m/s): u-blox says it, NMEA does not.
    pub vel_down_m_s: Option<f64>,
    /// Horizontal position accuracy, 1σ (m).
    pub h_acc_m: Option<f64>,
    /// Vertical position accuracy, 1σ (m).
    pub v_acc_m: Option<f64>,
    /// Speed accuracy, 1σ (m/s).
    pub s_acc_m_s: Option<f64>,
    /// Heading (of motion) accuracy, 1σ (deg).
    pub heading_acc_deg: Option<f64>,
    /// Satellites used in the solution.
    pub satellites: u8,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Vertical dilution of precision.
    pub vdop: Option<f64>,
    /// The solution's UTC time (µs since the Unix epoch), when the receiver knows it fully.
    pub time_utc_usec: Option<u64>,
}

/// What a driver says as it reads its receiver. The edge logs each once, as it happens.
#[derive(Debug, Clone, PartialEq)]
pub enum GpsEvent {
    /// A navigation solution.
    Solution(GpsSolution),
    /// Valid frames at this baud: the receiver is found.
    Found {
        /// The port's baud.
        baud: u32,
    },
    /// A u-blox receiver answered `MON-VER`.
    Identified {
        /// Its software version.
        software: String,
        /// Its hardware version.
        hardware: String,
        /// Its protocol version (`PROTVER`), when it says.
        protocol: Option<f64>,
    },
    /// The receiver took its configuration.
    Configured {
        /// Through which interface: `CFG-VALSET` (generation 9 on) or `CFG-PRT/MSG/RATE`.
        interface: &'static str,
    },
    /// The receiver refused a configuration message (`ACK-NAK`), or never acknowledged it.
    Refused {
        /// The message.
        message: &'static str,
        /// NAK'd (else unanswered after every retry).
        nak: bool,
    },
    /// Nothing valid from the receiver for [`SILENT_S`]: a lost GPS.
    Silent,
    /// Nothing valid for [`LOST_S`]: the baud scan starts again (the receiver may have been
    /// unplugged, or restarted at its default baud and configuration).
    Lost,
}

/// Silence after which a driver says [`GpsEvent::Silent`] (s): five epochs at 5 Hz.
pub const SILENT_S: f64 = 1.0;
/// Silence after which a driver scans the bauds again (s).
pub const LOST_S: f64 = 3.0;

/// What a driver has counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpsCounters {
    /// Bytes read.
    pub bytes: u64,
    /// Frames or sentences decoded whole, checksum good.
    pub frames: u64,
    /// Frames or sentences refused: bad checksum, wrong length, fields out of range.
    pub bad_frames: u64,
    /// Solutions given.
    pub solutions: u64,
}

/// An NMEA sentence's checksum (`*hh`, the exclusive or of what lies between `$` and `*`)
/// holds.
pub(crate) fn nmea_checksum_ok(sentence: &[u8]) -> bool {
    let text = sentence.trim_ascii_end();
    let Some(star) = text.iter().rposition(|b| *b == b'*') else {
        return false;
    };
    let (Some(body), Some(hex)) = (text.get(1..star), text.get(star + 1..)) else {
        return false;
    };
    let sum = body.iter().fold(0u8, |a, b| a ^ b);
    hex.len() == 2
        && std::str::from_utf8(hex)
            .ok()
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            == Some(sum)
}

/// The protocols a GPS port can speak.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GpsProtocol {
    /// u-blox's UBX, configured by the driver.
    #[default]
    Ublox,
    /// NMEA 0183 as the receiver sends it unconfigured.
    Nmea,
}

/// A GPS driver of either protocol, with one interface.
#[derive(Debug)]
pub enum GpsDriver {
    /// u-blox.
    Ublox(Box<ubx::UbloxDriver>),
    /// NMEA 0183.
    Nmea(Box<nmea0183::NmeaDriver>),
}

impl GpsDriver {
    /// A driver for `protocol`; `baud` is where the scan starts (and, for u-blox, the baud
    /// the receiver is switched to); `rate_hz` the navigation rate asked of a u-blox.
    pub fn new(protocol: GpsProtocol, baud: u32, rate_hz: f64) -> Self {
        match protocol {
            GpsProtocol::Ublox => Self::Ublox(Box::new(ubx::UbloxDriver::new(baud, rate_hz))),
            GpsProtocol::Nmea => Self::Nmea(Box::new(nmea0183::NmeaDriver::new(baud))),
        }
    }

    /// The baud the port must be at now.
    pub fn baud(&self) -> u32 {
        match self {
            Self::Ublox(d) => d.baud(),
            Self::Nmea(d) => d.baud(),
        }
    }

    /// Bytes read from the port at `t_s` (the sensor clock, s); events pushed on `events`.
    pub fn receive(&mut self, t_s: f64, bytes: &[u8], events: &mut Vec<GpsEvent>) {
        match self {
            Self::Ublox(d) => d.receive(t_s, bytes, events),
            Self::Nmea(d) => d.receive(t_s, bytes, events),
        }
    }

    /// The clock moved to `t_s`: what to write to the port now is appended to `out`, and
    /// events (silence, a new scan) pushed on `events`.
    pub fn poll(&mut self, t_s: f64, out: &mut Vec<u8>, events: &mut Vec<GpsEvent>) {
        match self {
            Self::Ublox(d) => d.poll(t_s, out, events),
            Self::Nmea(d) => d.poll(t_s, events),
        }
    }

    /// What the driver has counted.
    pub fn counters(&self) -> GpsCounters {
        match self {
            Self::Ublox(d) => d.counters(),
            Self::Nmea(d) => d.counters(),
        }
    }
}
