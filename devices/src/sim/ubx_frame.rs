//! UBX framing as the simulated receiver writes and reads it, from u-blox's interface
//! description: `B5 62`, class, id, little-endian length, payload, and the 8-bit Fletcher
//! checksum over class to payload. Written here rather than with the `ublox` crate, which
//! builds only what a receiver is sent and parses only what it sends: the receiver's side is
//! the other way round (and the driver it talks to is checked against it, and both against
//! `pyubx2`, so no decoding is shared between the two ends).

/// The two sync characters.
pub const SYNC: [u8; 2] = [0xB5, 0x62];

/// The Fletcher checksum of `bytes` (class, id, length and payload).
pub fn checksum(bytes: &[u8]) -> [u8; 2] {
    let (mut a, mut b) = (0u8, 0u8);
    for x in bytes {
        a = a.wrapping_add(*x);
        b = b.wrapping_add(a);
    }
    [a, b]
}

/// Appends the frame of `class`/`id` with `payload` to `out`.
pub fn write(class: u8, id: u8, payload: &[u8], out: &mut Vec<u8>) {
    out.extend_from_slice(&SYNC);
    let start = out.len();
    out.extend_from_slice(&[class, id]);
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.extend_from_slice(payload);
    let ck = checksum(&out[start..]);
    out.extend_from_slice(&ck);
}

/// One frame read: class, id, payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UbxFrame {
    /// Message class.
    pub class: u8,
    /// Message id.
    pub id: u8,
    /// Payload.
    pub payload: Vec<u8>,
}

/// Reads frames out of a byte stream; what is not a whole frame with a good checksum is
/// skipped.
#[derive(Debug, Default)]
pub struct UbxReader {
    buf: Vec<u8>,
}

/// The largest payload the receiver takes (a `CFG-VALSET` of 64 items fits).
const MAX_PAYLOAD: usize = 1024;

impl UbxReader {
    /// Bytes in, whole frames out.
    pub fn push(&mut self, bytes: &[u8], frames: &mut Vec<UbxFrame>) {
        self.buf.extend_from_slice(bytes);
        loop {
            let Some(start) = self.buf.windows(2).position(|w| w == SYNC) else {
                // Keep a last 0xB5: it may be the first half of a sync.
                let keep = usize::from(self.buf.last() == Some(&SYNC[0]));
                self.buf.drain(..self.buf.len() - keep);
                return;
            };
            self.buf.drain(..start);
            if self.buf.len() < 6 {
                return;
            }
            let len = usize::from(u16::from_le_bytes([self.buf[4], self.buf[5]]));
            if len > MAX_PAYLOAD {
                self.buf.drain(..2);
                continue;
            }
            if self.buf.len() < 8 + len {
                return;
            }
            let ck = checksum(&self.buf[2..6 + len]);
            if ck == [self.buf[6 + len], self.buf[7 + len]] {
                frames.push(UbxFrame {
                    class: self.buf[2],
                    id: self.buf[3],
                    payload: self.buf[6..6 + len].to_vec(),
                });
                self.buf.drain(..8 + len);
            } else {
                self.buf.drain(..2);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_read_back_across_garbage_and_split_writes() {
        let mut stream = vec![0x00, 0xB5, 0x13];
        write(
            0x06,
            0x8A,
            &[0, 1, 0, 0, 1, 0, 0x52, 0x40, 0, 0xC2, 1, 0],
            &mut stream,
        );
        // A frame with a bad checksum is skipped.
        let mut bad = Vec::new();
        write(0x0A, 0x04, &[], &mut bad);
        *bad.last_mut().expect("a frame") ^= 0xFF;
        stream.extend(bad);
        write(0x0A, 0x04, &[], &mut stream);
        let mut reader = UbxReader::default();
        let mut frames = Vec::new();
        for chunk in stream.chunks(3) {
            reader.push(chunk, &mut frames);
        }
        assert_eq!(frames.len(), 2, "{frames:?}");
        assert_eq!(
            (frames[0].class, frames[0].id, frames[0].payload.len()),
            (0x06, 0x8A, 12)
        );
        assert_eq!((frames[1].class, frames[1].id), (0x0A, 0x04));
    }

    #[test]
    fn the_checksum_is_u_bloxs_example() {
        // UBX-MON-VER poll, as u-blox's documents and every driver write it.
        let mut poll = Vec::new();
        write(0x0A, 0x04, &[], &mut poll);
        assert_eq!(poll, [0xB5, 0x62, 0x0A, 0x04, 0x00, 0x00, 0x0E, 0x34]);
    }
}
