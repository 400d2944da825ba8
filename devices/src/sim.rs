//! The devices as the simulator plays them on its serial ports, pure like the drivers: a
//! u-blox receiver ([`ublox_receiver::UbloxReceiver`]) and an NMEA-only receiver
//! ([`NmeaReceiver`]), each fed the simulator's fix at its epochs and the autopilot's bytes.

pub mod nmea_sentences;
pub mod rc_frames;
pub mod ublox_receiver;
pub mod ubx_frame;

use crate::gps::FixType;

/// The fix a simulated receiver reports at an epoch: the simulator's GPS model's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverFix {
    /// The epoch's UTC time (µs since the Unix epoch).
    pub time_utc_usec: u64,
    /// The fix.
    pub fix: FixType,
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude above mean sea level (m).
    pub alt_msl_m: f64,
    /// Velocity north, east, down (m/s).
    pub vel_ned_m_s: [f64; 3],
    /// Horizontal accuracy, 1σ (m).
    pub h_acc_m: f64,
    /// Vertical accuracy, 1σ (m).
    pub v_acc_m: f64,
    /// Speed accuracy, 1σ (m/s).
    pub s_acc_m_s: f64,
    /// Satellites used.
    pub satellites: u8,
    /// Dilutions of precision: horizontal, vertical, position.
    pub hdop: f64,
    /// Vertical dilution.
    pub vdop: f64,
    /// Position dilution.
    pub pdop: f64,
}

/// A receiver that speaks NMEA 0183 only, at a fixed baud and rate, and reads nothing.
#[derive(Debug, Clone)]
pub struct NmeaReceiver {
    /// Its baud.
    pub baud: u32,
    /// Its epoch period (s).
    pub period_s: f64,
}

impl NmeaReceiver {
    /// A receiver at `baud`, `rate_hz` epochs a second.
    pub fn new(baud: u32, rate_hz: f64) -> Self {
        Self {
            baud,
            period_s: 1.0 / rate_hz.clamp(0.1, 20.0),
        }
    }

    /// One epoch's sentences (with `GST`), appended to `out`.
    pub fn epoch(&self, fix: &ReceiverFix, out: &mut Vec<u8>) {
        nmea_sentences::epoch(fix, true, out);
    }
}

/// What a UART set to the wrong baud reads of `bytes`: a faster reader sees each byte as
/// more than one, a slower one merges them, and the bits land in the wrong places. Not a model
/// of a line's waveform, only bytes that are as wrong as a real mismatch's (sync characters
/// and checksums almost never survive), deterministically.
pub fn misread(bytes: &[u8], sent_baud: u32, read_baud: u32, out: &mut Vec<u8>) {
    let ratio = f64::from(read_baud.max(1)) / f64::from(sent_baud.max(1));
    let mut phase = 0.0;
    for (k, b) in bytes.iter().enumerate() {
        phase += ratio;
        while phase >= 1.0 {
            phase -= 1.0;
            let shift = (k as u32 % 7) + 1;
            out.push((b ^ 0x5A).rotate_left(shift) | 0x80);
        }
    }
}
