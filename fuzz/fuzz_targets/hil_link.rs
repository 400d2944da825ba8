//! What a simulator or flight board sends the vehicle: MAVLink HIL frames, in datagrams or split
//! across reads of a serial line at any point, and the JSON physics interface's lines. No
//! panic.
#![no_main]

use hil::{Decoded, StreamDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = hil::decode(data);
    // The same bytes as a serial line, cut where the first byte says.
    let cut = data
        .first()
        .map_or(0, |&c| usize::from(c) % (data.len() + 1));
    let mut splitter = StreamDecoder::default();
    let mut out = Decoded::default();
    splitter.push_checked(&data[..cut], &mut out, &mut |_| true);
    splitter.push_checked(&data[cut..], &mut out, &mut |_| true);
    let _ = hil::json::PhysicsState::parse_latest(data);
});
