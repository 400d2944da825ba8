//! CRSF, the serial protocol of ExpressLRS and TBS Crossfire receivers (420 000 baud, 8N1):
//! frames of `[address][length][type][payload][CRC-8/DVB-S2 over type and payload]`, decoded
//! here: `RC_CHANNELS_PACKED` (16 channels of 11 bits, least significant first, 172…1811 for
//! 988…2012 µs) and `LINK_STATISTICS`.
//!
//! Not with the [`crsf`](https://crates.io/crates/crsf) crate's parser (2.0.1), measured: it
//! takes 64 bytes off its buffer for every frame, whatever the frame's length, so the frames
//! behind one in the same read are lost; it reads a payload shorter than its type's past its
//! end (a panic on a line's garbage); and an invalid length byte costs it the next frame's
//! start. Its encoder makes the frames the tests read back.
//!
//! [`telemetry`] writes what a CRSF receiver sends on to the transmitter: battery, attitude,
//! GPS and flight mode, as the TBS specification lays them out (big-endian).

use super::{MAX_CHANNELS, RcCounters, RcEvent, RcInput, RcLink};

/// CRSF's serial rate.
pub const BAUD: u32 = 420_000;
const TYPE_LINK_STATISTICS: u8 = 0x14;
const TYPE_RC_CHANNELS: u8 = 0x16;
const RC_PAYLOAD: usize = 22;
const LINK_PAYLOAD: usize = 10;
/// Addresses a frame starts with: flight controller, handset, transmitter module, receiver.
const ADDRESSES: [u8; 4] = [0xC8, 0xEA, 0xEE, 0xEC];
/// The longest frame, address and length included.
const MAX_FRAME: usize = 64;

/// CRSF's check.
const CRC8: ::crc::Crc<u8> = ::crc::Crc::<u8>::new(&::crc::CRC_8_DVB_S2);

/// A channel's 11-bit CRSF value as a pulse width (µs): 992 is 1500 µs, 0.625 µs a step
/// (TBS's `TICKS_TO_US`).
pub fn ticks_to_us(ticks: u16) -> u16 {
    (1500.0 + (f64::from(ticks) - 992.0) * 0.625)
        .round()
        .clamp(0.0, 3000.0) as u16
}

/// The reader.
#[derive(Debug, Default)]
pub struct CrsfReader {
    buf: Vec<u8>,
    counters: RcCounters,
}

impl CrsfReader {
    /// What the reader has counted.
    pub fn counters(&self) -> RcCounters {
        self.counters
    }

    /// Bytes from the port; what they decode to pushed on `events`.
    pub fn receive(&mut self, bytes: &[u8], events: &mut Vec<RcEvent>) {
        self.counters.bytes += bytes.len() as u64;
        self.buf.extend_from_slice(bytes);
        let mut at = 0;
        while let Some(start) = self.buf[at..].iter().position(|b| ADDRESSES.contains(b)) {
            at += start;
            let Some(&len) = self.buf.get(at + 1) else {
                break;
            };
            let len = usize::from(len);
            if !(2..=MAX_FRAME - 2).contains(&len) {
                at += 1;
                continue;
            }
            let Some(frame) = self.buf.get(at..at + 2 + len) else {
                break;
            };
            let (body, crc) = frame[2..].split_at(len - 1);
            if CRC8.checksum(body) != crc[0] {
                // Not a frame after all (an address byte in the noise), or a damaged one.
                self.counters.bad_frames += 1;
                at += 1;
                continue;
            }
            match decode(body[0], &body[1..]) {
                Some(e) => {
                    self.counters.frames += 1;
                    events.extend(e);
                }
                None => self.counters.bad_frames += 1,
            }
            at += 2 + len;
        }
        // Keep what may be the start of a frame; drop the rest.
        let keep_from = if self.buf.len() - at > MAX_FRAME {
            self.buf.len()
        } else {
            at
        };
        self.buf.drain(..keep_from);
    }
}

/// A checked frame's type and payload: `Some(None)` for a type not read here, `None` for a
/// payload of the wrong length for its type.
fn decode(kind: u8, payload: &[u8]) -> Option<Option<RcEvent>> {
    match kind {
        TYPE_RC_CHANNELS => {
            let p: &[u8; RC_PAYLOAD] = payload.try_into().ok()?;
            let mut channels = [0u16; MAX_CHANNELS];
            for (k, c) in channels.iter_mut().enumerate() {
                let bit = k * 11;
                let word = u32::from(p[bit / 8])
                    | u32::from(p[bit / 8 + 1]) << 8
                    | u32::from(*p.get(bit / 8 + 2).unwrap_or(&0)) << 16;
                *c = ticks_to_us((word >> (bit % 8) & 0x7FF) as u16);
            }
            Some(Some(RcEvent::Channels(RcInput {
                channels,
                count: MAX_CHANNELS as u8,
                frame_lost: false,
                failsafe: false,
            })))
        }
        TYPE_LINK_STATISTICS => {
            let p: &[u8; LINK_PAYLOAD] = payload.try_into().ok()?;
            Some(Some(RcEvent::Link(RcLink {
                rssi_dbm: -i16::from(p[0].min(p[1])),
                link_quality: p[2],
                snr_db: p[3] as i8,
                downlink_rssi_dbm: -i16::from(p[7]),
                downlink_link_quality: p[8],
            })))
        }
        // A device ping, parameters, another's telemetry: not for the flight controller.
        _ => Some(None),
    }
}

/// Frames a receiver sends on to the transmitter (TBS CRSF specification, big-endian; the
/// address is the flight controller's, 0xC8, as receivers forward them).
pub mod telemetry {
    const ADDRESS: u8 = 0xC8;

    fn frame(kind: u8, payload: &[u8], out: &mut Vec<u8>) {
        out.push(ADDRESS);
        out.push(payload.len() as u8 + 2);
        let start = out.len();
        out.push(kind);
        out.extend_from_slice(payload);
        let sum = super::CRC8.checksum(&out[start..]);
        out.push(sum);
    }

    /// Battery (0x08): voltage (V), current (A), used capacity (mAh), remaining (%).
    pub fn battery(volts: f64, amps: f64, used_mah: f64, remaining_pct: u8, out: &mut Vec<u8>) {
        let mut p = Vec::with_capacity(8);
        p.extend(((volts * 10.0).round().clamp(0.0, 65535.0) as u16).to_be_bytes());
        p.extend(((amps * 10.0).round().clamp(0.0, 65535.0) as u16).to_be_bytes());
        p.extend(&(used_mah.round().clamp(0.0, 16_777_215.0) as u32).to_be_bytes()[1..]);
        p.push(remaining_pct.min(100));
        frame(0x08, &p, out);
    }

    /// Attitude (0x1E): pitch, roll, yaw (rad), in 1/10 000 rad.
    pub fn attitude(pitch: f64, roll: f64, yaw: f64, out: &mut Vec<u8>) {
        let mut p = Vec::with_capacity(6);
        for a in [pitch, roll, yaw] {
            p.extend(((a * 10_000.0).round().clamp(-32768.0, 32767.0) as i16).to_be_bytes());
        }
        frame(0x1E, &p, out);
    }

    /// GPS (0x02): latitude, longitude (deg), ground speed (m/s), heading (deg), altitude
    /// (m), satellites.
    pub fn gps(
        lat: f64,
        lon: f64,
        speed: f64,
        heading: f64,
        alt: f64,
        sats: u8,
        out: &mut Vec<u8>,
    ) {
        let mut p = Vec::with_capacity(15);
        p.extend(((lat * 1e7).round() as i32).to_be_bytes());
        p.extend(((lon * 1e7).round() as i32).to_be_bytes());
        // km/h × 10, centidegrees, metres + 1000.
        p.extend(((speed * 36.0).round().clamp(0.0, 65535.0) as u16).to_be_bytes());
        p.extend(((heading.rem_euclid(360.0) * 100.0).round() as u16).to_be_bytes());
        p.extend(((alt + 1000.0).round().clamp(0.0, 65535.0) as u16).to_be_bytes());
        p.push(sats);
        frame(0x02, &p, out);
    }

    /// Flight mode (0x21): the mode's name, NUL-terminated (at most 15 characters).
    pub fn flight_mode(name: &str, out: &mut Vec<u8>) {
        let mut p: Vec<u8> = name.bytes().filter(|b| *b != 0).take(15).collect();
        p.push(0);
        frame(0x21, &p, out);
    }
}

#[cfg(test)]
mod tests;
