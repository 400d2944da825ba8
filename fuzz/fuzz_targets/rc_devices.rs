//! What an RC receiver's serial port can bring: any bytes, in any pieces, into the CRSF and the
//! SBUS readers. No panic; every channel a pulse width in range; no more frames than the bytes
//! could hold.
#![no_main]

use devices::rc::RcEvent;
use devices::rc::crsf::CrsfReader;
use devices::rc::sbus::SbusReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|pieces: Vec<Vec<u8>>| {
    let (mut crsf, mut sbus) = (CrsfReader::default(), SbusReader::default());
    let mut events = Vec::new();
    let mut total = 0;
    for piece in pieces.iter().take(256) {
        total += piece.len();
        crsf.receive(piece, &mut events);
        sbus.receive(piece, &mut events);
    }
    for e in &events {
        if let RcEvent::Channels(c) = e {
            assert!(
                c.channels.iter().all(|us| (800..=2200).contains(us)),
                "{c:?}"
            );
        }
    }
    // A CRSF frame is at least 4 bytes, an SBUS frame 25.
    let frames = crsf.counters().frames + sbus.counters().frames;
    assert!(
        frames as usize <= total / 4 + 1,
        "{frames} frames from {total} bytes"
    );
});
