//! RC frames as a receiver writes them to a flight controller, for the simulator's receiver:
//! CRSF's `RC_CHANNELS_PACKED` and `LINK_STATISTICS` (TBS specification), SBUS's 25-byte frame
//! (Futaba). Channel values go in as pulse widths (µs).

/// 16 channels of 11 bits, least significant bit first (CRSF's and SBUS's packing).
fn pack(ticks: &[u16; 16], out: &mut Vec<u8>) {
    let (mut acc, mut bits) = (0u32, 0);
    for t in ticks {
        acc |= u32::from(t & 0x7FF) << bits;
        bits += 11;
        while bits >= 8 {
            out.push(acc as u8);
            acc >>= 8;
            bits -= 8;
        }
    }
}

/// A pulse width (µs) as CRSF's 11-bit value (992 at 1500 µs, 0.625 µs a step).
pub fn crsf_ticks(us: f64) -> u16 {
    ((us - 1500.0) / 0.625 + 992.0).round().clamp(0.0, 2047.0) as u16
}

/// A pulse width (µs) as SBUS's 11-bit value (200 at 1000 µs, 1800 at 2000 µs, as PX4 reads it).
pub fn sbus_ticks(us: f64) -> u16 {
    ((us - 875.0) / 0.625).round().clamp(0.0, 2047.0) as u16
}

fn crsf_frame(kind: u8, payload: &[u8], out: &mut Vec<u8>) {
    const CRC8: crc::Crc<u8> = crc::Crc::<u8>::new(&crc::CRC_8_DVB_S2);
    out.push(0xC8);
    out.push(payload.len() as u8 + 2);
    let start = out.len();
    out.push(kind);
    out.extend_from_slice(payload);
    let sum = CRC8.checksum(&out[start..]);
    out.push(sum);
}

/// CRSF `RC_CHANNELS_PACKED` of `us` (16 pulse widths).
pub fn crsf_channels(us: &[f64; 16], out: &mut Vec<u8>) {
    let ticks = us.map(crsf_ticks);
    let mut payload = Vec::with_capacity(22);
    pack(&ticks, &mut payload);
    crsf_frame(0x16, &payload, out);
}

/// CRSF `LINK_STATISTICS`: uplink RSSI (dBm, both antennas), link quality (%), SNR (dB), and
/// the downlink's RSSI (dBm) and link quality (%).
pub fn crsf_link_statistics(
    rssi_dbm: i16,
    quality: u8,
    snr_db: i8,
    down: (i16, u8),
    out: &mut Vec<u8>,
) {
    let dbm = |x: i16| x.unsigned_abs().min(255) as u8;
    let payload = [
        dbm(rssi_dbm),
        dbm(rssi_dbm),
        quality,
        snr_db as u8,
        0,
        2, // 150 Hz
        3, // 100 mW
        dbm(down.0),
        down.1,
        snr_db as u8,
    ];
    crsf_frame(0x14, &payload, out);
}

/// An SBUS frame of `us` (16 pulse widths), with the frame-lost and failsafe flags.
pub fn sbus_frame(us: &[f64; 16], frame_lost: bool, failsafe: bool, out: &mut Vec<u8>) {
    out.push(0x0F);
    pack(&us.map(sbus_ticks), out);
    out.push(u8::from(frame_lost) << 2 | u8::from(failsafe) << 3);
    out.push(0x00);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rc::crsf::CrsfReader;
    use crate::rc::sbus::SbusReader;
    use crate::rc::{RcEvent, RcLink};

    #[test]
    fn the_readers_read_back_what_the_simulated_receiver_writes() {
        let mut us = [1500.0; 16];
        us[0] = 1000.0;
        us[2] = 1900.0;
        us[15] = 2000.0;
        let mut bytes = Vec::new();
        crsf_channels(&us, &mut bytes);
        crsf_link_statistics(-70, 95, 8, (-80, 90), &mut bytes);
        let mut events = Vec::new();
        CrsfReader::default().receive(&bytes, &mut events);
        let RcEvent::Channels(c) = events[0] else {
            panic!("{events:?}")
        };
        assert_eq!(
            (c.channels[0], c.channels[2], c.channels[15]),
            (1000, 1900, 2000)
        );
        assert_eq!(
            events[1],
            RcEvent::Link(RcLink {
                rssi_dbm: -70,
                link_quality: 95,
                snr_db: 8,
                downlink_rssi_dbm: -80,
                downlink_link_quality: 90
            })
        );
        let mut frame = Vec::new();
        sbus_frame(&us, false, true, &mut frame);
        let mut events = Vec::new();
        SbusReader::default().receive(&frame, &mut events);
        let RcEvent::Channels(c) = events[0] else {
            panic!("{events:?}")
        };
        assert_eq!(
            (c.channels[0], c.channels[2], c.failsafe),
            (1000, 1900, true)
        );
    }
}
