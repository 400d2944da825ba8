//! SBUS (Futaba; FrSky and most other receivers too): 100 000 baud, 8 data bits, even parity,
//! 2 stop bits, and inverted on the wire (idle low): a flight board's UART either inverts it
//! in hardware (STM32F7/H7 have the option) or needs an inverter in front (a transistor, or
//! the receiver's uninverted pad). Frames of 25 bytes, `0x0F`, 16 channels of 11 bits, a
//! flags byte (channels 17 and 18, frame lost, failsafe), `0x00`, every 7 or 14 ms, decoded by
//! the [`sbus-rs`](https://crates.io/crates/sbus-rs) crate's streaming parser.

use super::{MAX_CHANNELS, RcCounters, RcEvent, RcInput};
use sbus_rs::StreamingParser;

/// SBUS's serial rate.
pub const BAUD: u32 = 100_000;

/// A channel's 11-bit SBUS value as a pulse width (µs): 200…1800 are 1000…2000 µs, as PX4's
/// SBUS decoder scales them (Futaba's and FrSky's receivers send 172…1811 for their full
/// 988…2012 µs).
pub fn ticks_to_us(ticks: u16) -> u16 {
    (875.0 + f64::from(ticks) * 0.625)
        .round()
        .clamp(0.0, 3000.0) as u16
}

/// The reader.
#[derive(Debug, Default)]
pub struct SbusReader {
    parser: StreamingParser,
    counters: RcCounters,
}

impl SbusReader {
    /// What the reader has counted.
    pub fn counters(&self) -> RcCounters {
        self.counters
    }

    /// Bytes from the port; the frames they complete pushed on `events`.
    pub fn receive(&mut self, bytes: &[u8], events: &mut Vec<RcEvent>) {
        self.counters.bytes += bytes.len() as u64;
        for &b in bytes {
            match self.parser.push_byte(b) {
                Ok(Some(p)) => {
                    self.counters.frames += 1;
                    let mut channels = [0u16; MAX_CHANNELS];
                    for (c, t) in channels.iter_mut().zip(p.channels) {
                        *c = ticks_to_us(t);
                    }
                    events.push(RcEvent::Channels(RcInput {
                        channels,
                        count: MAX_CHANNELS as u8,
                        frame_lost: p.flags.frame_lost,
                        failsafe: p.flags.failsafe,
                    }));
                }
                Ok(None) => {}
                Err(_) => self.counters.bad_frames += 1,
            }
        }
    }
}

#[cfg(test)]
mod tests;
