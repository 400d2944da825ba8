use super::*;
use ::crsf::{LinkStatistics, Packet, PacketAddress, RcChannels};

fn channels_frame(ticks: [u16; 16]) -> Vec<u8> {
    Packet::RcChannels(RcChannels(ticks))
        .into_raw(PacketAddress::Controller)
        .data()
        .to_vec()
}

#[test]
fn channels_and_link_statistics_made_by_the_crate_read_back() {
    let mut ticks = [992u16; 16];
    ticks[0] = 172;
    ticks[1] = 1811;
    ticks[2] = 1234;
    let link = Packet::LinkStatistics(LinkStatistics {
        uplink_rssi_1: 62,
        uplink_rssi_2: 71,
        uplink_link_quality: 98,
        uplink_snr: -3,
        active_antenna: 0,
        rf_mode: 4,
        uplink_tx_power: 2,
        downlink_rssi: 80,
        downlink_link_quality: 97,
        downlink_snr: 5,
    })
    .into_raw(PacketAddress::Controller)
    .data()
    .to_vec();
    // Noise before it, an address byte in it.
    let mut stream = vec![0x00, 0x13, 0xC8];
    stream.extend(channels_frame(ticks));
    stream.extend(link);
    let mut reader = CrsfReader::default();
    let mut events = Vec::new();
    for piece in stream.chunks(5) {
        reader.receive(piece, &mut events);
    }
    assert_eq!(
        reader.counters().bad_frames,
        0,
        "{:?} {events:?}",
        reader.counters()
    );
    let RcEvent::Channels(rc) = events[0] else {
        panic!("{events:?}")
    };
    assert_eq!(&rc.channels[..4], &[988, 2012, 1651, 1500]);
    assert_eq!(
        events[1],
        RcEvent::Link(RcLink {
            rssi_dbm: -62,
            link_quality: 98,
            snr_db: -3,
            downlink_rssi_dbm: -80,
            downlink_link_quality: 97,
        })
    );
    assert_eq!(events.len(), 2);
}

#[test]
fn a_frame_too_short_for_its_type_or_with_a_bad_crc_is_counted_not_read() {
    // LINK_STATISTICS with a 1-byte payload and a good CRC: the crate would read past it.
    let crc = ::crc::Crc::<u8>::new(&::crc::CRC_8_DVB_S2);
    let short = [0xC8, 3, 0x14, 7, crc.checksum(&[0x14, 7])];
    let mut bad = channels_frame([992; 16]);
    bad[10] ^= 0x40;
    let mut reader = CrsfReader::default();
    let mut events = Vec::new();
    reader.receive(&short, &mut events);
    reader.receive(&bad, &mut events);
    reader.receive(&channels_frame([992; 16]), &mut events);
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(reader.counters().bad_frames, 2, "{:?}", reader.counters());
}

#[test]
fn telemetry_frames_carry_their_crc_and_big_endian_fields() {
    let mut out = Vec::new();
    telemetry::battery(16.4, 12.3, 450.0, 71, &mut out);
    assert_eq!(&out[..3], &[0xC8, 10, 0x08]);
    assert_eq!(&out[3..11], &[0, 164, 0, 123, 0, 1, 194, 71]);
    let crc = ::crc::Crc::<u8>::new(&::crc::CRC_8_DVB_S2);
    assert_eq!(out[11], crc.checksum(&out[2..11]));
    out.clear();
    telemetry::flight_mode("POSCTL", &mut out);
    assert_eq!(&out[3..10], b"POSCTL\0");
    assert_eq!(out[1] as usize, out.len() - 2);
}
