use super::*;

/// A frame as a receiver writes it: 16 channels of 11 bits, least significant bit first.
fn frame(ticks: [u16; 16], flags: u8) -> [u8; 25] {
    let mut f = [0u8; 25];
    f[0] = 0x0F;
    let mut bit = 0;
    for t in ticks {
        for k in 0..11 {
            if t >> k & 1 == 1 {
                f[1 + bit / 8] |= 1 << (bit % 8);
            }
            bit += 1;
        }
    }
    f[23] = flags;
    f
}

#[test]
fn channels_and_flags_read_back_across_garbage_and_pieces() {
    let mut ticks = [1000u16; 16];
    ticks[0] = 200;
    ticks[1] = 1800;
    let mut stream = vec![0xAA, 0x0F, 0x01];
    stream.extend(frame(ticks, 0));
    stream.extend(frame(ticks, 0x04)); // frame lost
    stream.extend(frame(ticks, 0x08)); // failsafe
    let mut reader = SbusReader::default();
    let mut events = Vec::new();
    for piece in stream.chunks(7) {
        reader.receive(piece, &mut events);
    }
    let frames: Vec<_> = events
        .iter()
        .map(|e| match e {
            RcEvent::Channels(c) => *c,
            RcEvent::Link(_) => panic!("{e:?}"),
        })
        .collect();
    assert!(frames.len() >= 3, "{frames:?}");
    let last = &frames[frames.len() - 3..];
    assert_eq!(&last[0].channels[..3], &[1000, 2000, 1500]);
    assert_eq!((last[0].frame_lost, last[0].failsafe), (false, false));
    assert_eq!((last[1].frame_lost, last[1].failsafe), (true, false));
    assert_eq!((last[2].frame_lost, last[2].failsafe), (false, true));
}
