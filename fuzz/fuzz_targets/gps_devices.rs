//! What a GPS's serial port can bring: any bytes, in any pieces, at any times, into the u-blox
//! and the NMEA drivers, and any bytes from an autopilot into the simulated u-blox. No panic,
//! solutions no more than whole frames, and what a driver writes bounded.
#![no_main]

use arbitrary::Arbitrary;
use devices::gps::{GpsDriver, GpsEvent, GpsProtocol};
use devices::sim::ublox_receiver::{ReceiverModel, UbloxReceiver};
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Piece {
    /// Milliseconds since the last piece.
    dt_ms: u16,
    bytes: Vec<u8>,
}

/// Frames the fuzzer should meet often: a NAV-PVT header, an ACK, a MON-VER, an NMEA start.
const SEEDS: [&[u8]; 4] = [
    &[0xB5, 0x62, 0x01, 0x07, 0x5C, 0x00],
    &[0xB5, 0x62, 0x05, 0x01, 0x02, 0x00, 0x06, 0x8A],
    &[0xB5, 0x62, 0x0A, 0x04],
    b"$GNGGA,120000.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*",
];

fuzz_target!(|input: (u8, Vec<Piece>)| {
    let (choice, pieces) = input;
    let protocol = if choice % 2 == 0 {
        GpsProtocol::Ublox
    } else {
        GpsProtocol::Nmea
    };
    let mut driver = GpsDriver::new(protocol, 115_200, f64::from(choice % 12));
    let model = [
        ReceiverModel::M8,
        ReceiverModel::M9,
        ReceiverModel::M10,
        ReceiverModel::F9p,
    ][usize::from(choice / 2 % 4)];
    let mut receiver = UbloxReceiver::new(model);
    let (mut t, mut events, mut out) = (0.0, Vec::new(), Vec::new());
    for piece in pieces.into_iter().take(256) {
        t += f64::from(piece.dt_ms) * 1e-3;
        let mut bytes = piece.bytes;
        if let Some(seed) = SEEDS.get(usize::from(piece.dt_ms % 16)) {
            bytes.splice(0..0, seed.iter().copied());
        }
        driver.receive(t, &bytes, &mut events);
        out.clear();
        driver.poll(t, &mut out, &mut events);
        assert!(out.len() <= 4096, "{} bytes written at once", out.len());
        assert!(driver.baud() > 0);
        let mut answer = Vec::new();
        receiver.receive(&bytes, &mut answer);
        assert!(
            answer.len() <= 64 * (bytes.len() / 8 + 1),
            "{} answering {}",
            answer.len(),
            bytes.len()
        );
    }
    let c = driver.counters();
    let solutions = events
        .iter()
        .filter(|e| matches!(e, GpsEvent::Solution(_)))
        .count() as u64;
    assert_eq!(solutions, c.solutions);
    assert!(c.solutions <= c.frames, "{c:?}");
});
