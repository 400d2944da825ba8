//! MAVLink 1/2 framing without per-frame allocation: the HIL link exchanges four or five frames
//! per tick, thousands of times a second, so framing and checksums are done here with a
//! table-driven CRC and stack buffers. Payload (de)serialisation stays the `mavlink` crate's
//! (`Message::ser` / `Message::parse`); tests check both directions byte for byte against it.
//!
//! Frame layouts (<https://mavlink.io/en/guide/serialization.html>):
//! v1 `FE len seq sys comp id payload crc16`, v2 `FD len incompat compat seq sys comp id×3
//! payload crc16 [signature×13]`; the CRC is X.25 (CRC-16/MCRF4XX) over everything after the
//! start byte, then the message's CRC_EXTRA byte.

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion, Message};

const STX_V1: u8 = 0xFE;
const STX_V2: u8 = 0xFD;
const V1_HEADER: usize = 6; // start byte included
const V2_HEADER: usize = 10;
const CHECKSUM: usize = 2;
const SIGNATURE: usize = 13;
/// The only incompatibility flag this link understands: the frame is signed (the signature is
/// carried, not checked: the HIL link is a cable or loopback, signing is the ground link's job).
const IFLAG_SIGNED: u8 = 0x01;
/// Longest MAVLink 2 frame: header, 255 payload bytes, checksum, signature.
pub const MAX_FRAME: usize = V2_HEADER + 255 + CHECKSUM + SIGNATURE;

/// X.25 CRC tables (polynomial 0x1021 reflected = 0x8408) for slicing by 8: `CRC_TABLES[0]` is
/// the byte-at-a-time table, `CRC_TABLES[k][b]` the CRC of byte `b` followed by `k` zero bytes.
/// Built at compile time.
const CRC_TABLES: [[u16; 256]; 8] = {
    let mut t = [[0u16; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut crc = i as u16;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0x8408
            } else {
                crc >> 1
            };
            bit += 1;
        }
        t[0][i] = crc;
        i += 1;
    }
    let mut k = 1;
    while k < 8 {
        let mut i = 0;
        while i < 256 {
            let prev = t[k - 1][i];
            t[k][i] = (prev >> 8) ^ t[0][(prev & 0xFF) as usize];
            i += 1;
        }
        k += 1;
    }
    t
};

/// One byte into the running X.25 CRC.
fn crc_byte(crc: u16, b: u8) -> u16 {
    (crc >> 8) ^ CRC_TABLES[0][((crc ^ b as u16) & 0xFF) as usize]
}

/// The MAVLink checksum of `data` followed by the message's `extra_crc` byte: eight bytes per
/// step (slicing by 8), the rest one at a time.
pub fn checksum(data: &[u8], extra_crc: u8) -> u16 {
    let t = &CRC_TABLES;
    let mut chunks = data.chunks_exact(8);
    let mut crc = 0xFFFFu16;
    for c in &mut chunks {
        let lo = (crc as u8 ^ c[0]) as usize;
        let hi = ((crc >> 8) as u8 ^ c[1]) as usize;
        crc = t[7][lo]
            ^ t[6][hi]
            ^ t[5][c[2] as usize]
            ^ t[4][c[3] as usize]
            ^ t[3][c[4] as usize]
            ^ t[2][c[5] as usize]
            ^ t[1][c[6] as usize]
            ^ t[0][c[7] as usize];
    }
    let crc = chunks
        .remainder()
        .iter()
        .fold(crc, |crc, &b| crc_byte(crc, b));
    crc_byte(crc, extra_crc)
}

/// Encodes messages as MAVLink 2 frames with a running sequence number.
#[derive(Debug)]
pub struct Encoder {
    system_id: u8,
    component_id: u8,
    sequence: u8,
}

impl Encoder {
    /// An encoder speaking as `system_id`/`component_id` (the autopilot: its system id, 1).
    pub fn with_ids(system_id: u8, component_id: u8) -> Self {
        Self {
            system_id,
            component_id,
            sequence: 0,
        }
    }

    /// Appends `msg` as one MAVLink 2 frame to `out` (trailing zero payload bytes truncated, as
    /// MAVLink 2 requires).
    pub fn push(&mut self, out: &mut Vec<u8>, msg: &MavMessage) {
        let mut frame = [0u8; V2_HEADER + 255 + CHECKSUM];
        let len = msg.ser(MavlinkVersion::V2, &mut frame[V2_HEADER..V2_HEADER + 255]);
        self.finish(out, &mut frame, len, msg.message_id());
    }

    /// Appends `msg` as one MAVLink 2 frame from the sender `header` names, with its sequence
    /// number: a message heard, framed again for a log (unsigned; this encoder's own sequence is
    /// left alone).
    pub fn push_heard(out: &mut Vec<u8>, header: &MavHeader, msg: &MavMessage) {
        let mut frame = [0u8; V2_HEADER + 255 + CHECKSUM];
        let len = msg.ser(MavlinkVersion::V2, &mut frame[V2_HEADER..V2_HEADER + 255]);
        Self::heard_as(header).finish(out, &mut frame, len, msg.message_id());
    }

    /// [`Encoder::push_heard`] for a message given as its id and payload bytes.
    pub fn push_raw_heard(out: &mut Vec<u8>, header: &MavHeader, msg_id: u32, payload: &[u8]) {
        Self::heard_as(header).push_raw(out, msg_id, payload);
    }

    fn heard_as(header: &MavHeader) -> Self {
        Self {
            system_id: header.system_id as u8,
            component_id: header.component_id,
            sequence: header.sequence,
        }
    }

    /// Appends a message given as its id and payload bytes (for payloads the dialect cannot
    /// express, such as an acknowledgement of a command id it does not know); trailing zero
    /// bytes are truncated, a payload over 255 bytes is cut.
    pub fn push_raw(&mut self, out: &mut Vec<u8>, msg_id: u32, payload: &[u8]) {
        let mut frame = [0u8; V2_HEADER + 255 + CHECKSUM];
        let payload = &payload[..payload.len().min(255)];
        frame[V2_HEADER..V2_HEADER + payload.len()].copy_from_slice(payload);
        let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
        self.finish(out, &mut frame, len, msg_id);
    }

    /// Writes the header and checksum around the `len` payload bytes in `frame` and appends it.
    fn finish(&mut self, out: &mut Vec<u8>, frame: &mut [u8], len: usize, msg_id: u32) {
        let id = msg_id.to_le_bytes();
        frame[..V2_HEADER].copy_from_slice(&[
            STX_V2,
            len as u8,
            0, // incompat flags
            0, // compat flags
            self.sequence,
            self.system_id,
            self.component_id,
            id[0],
            id[1],
            id[2],
        ]);
        let end = V2_HEADER + len;
        let crc = checksum(&frame[1..end], MavMessage::extra_crc(msg_id));
        frame[end..end + CHECKSUM].copy_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&frame[..end + CHECKSUM]);
        self.sequence = self.sequence.wrapping_add(1);
    }
}

/// Length of the frame starting at `b[0]` if its header is complete; `Err` if `b[0]` is not a
/// start byte or the frame carries an incompatibility flag this link does not understand.
fn frame_len(b: &[u8]) -> Result<Option<usize>, ()> {
    match b.first() {
        None => Ok(None),
        Some(&STX_V1) => Ok(b.get(1).map(|&len| V1_HEADER + len as usize + CHECKSUM)),
        Some(&STX_V2) => {
            let (Some(&len), Some(&incompat)) = (b.get(1), b.get(2)) else {
                return Ok(None);
            };
            if incompat & !IFLAG_SIGNED != 0 {
                return Err(()); // MAVLink 2: discard a frame with an unknown incompat flag
            }
            let signature = if incompat & IFLAG_SIGNED != 0 {
                SIGNATURE
            } else {
                0
            };
            Ok(Some(V2_HEADER + len as usize + CHECKSUM + signature))
        }
        Some(_) => Err(()),
    }
}

/// A frame whose checksum is right but whose payload the dialect cannot parse (an enum value
/// it does not know, such as a command id from a newer dialect).
#[derive(Debug, Clone, PartialEq)]
pub struct RawMessage {
    /// The sender.
    pub header: MavHeader,
    /// Message id.
    pub msg_id: u32,
    /// Payload bytes as received (MAVLink 2 truncates trailing zeros).
    pub payload: Vec<u8>,
}

/// What one frame held (lives for one frame on the stack: the size difference is harmless).
#[allow(clippy::large_enum_variant)]
enum Frame {
    Message(MavHeader, MavMessage),
    Unparsed(RawMessage),
    /// Well-formed, but the link's check refused it.
    Refused,
    Bad,
}

/// Parses one whole frame (`frame.len()` is its length): checksum, then the link's `check`,
/// then payload.
fn parse_frame(frame: &[u8], check: &mut dyn FnMut(&[u8]) -> bool) -> Frame {
    let (version, header_len, msgid) = if frame[0] == STX_V1 {
        (MavlinkVersion::V1, V1_HEADER, frame[5] as u32)
    } else {
        let id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
        (MavlinkVersion::V2, V2_HEADER, id)
    };
    let payload_end = header_len + frame[1] as usize;
    let crc = checksum(&frame[1..payload_end], MavMessage::extra_crc(msgid));
    let sent = u16::from_le_bytes([frame[payload_end], frame[payload_end + 1]]);
    if crc != sent {
        return Frame::Bad;
    }
    if !check(frame) {
        return Frame::Refused;
    }
    let (seq, sys, comp) = if version == MavlinkVersion::V1 {
        (frame[2], frame[3], frame[4])
    } else {
        (frame[4], frame[5], frame[6])
    };
    let header = MavHeader {
        system_id: sys.into(),
        component_id: comp,
        sequence: seq,
    };
    let payload = &frame[header_len..payload_end];
    match MavMessage::parse(version, msgid, payload) {
        Ok(msg) => Frame::Message(header, msg),
        Err(_) => Frame::Unparsed(RawMessage {
            header,
            msg_id: msgid,
            payload: payload.to_vec(),
        }),
    }
}

/// What one datagram held.
#[derive(Debug, Default, PartialEq)]
pub struct Decoded {
    /// Well-formed messages with their headers.
    pub messages: Vec<(MavHeader, MavMessage)>,
    /// Frames or runs of bytes that were not a valid message (bad CRC, truncated, unknown id,
    /// garbage between frames, a payload that does not parse).
    pub malformed: u32,
    /// Keep the frames whose checksum is right but whose payload does not parse in
    /// `unparsed` (they are counted in `malformed` either way). Off by default: a sensor link
    /// has no use for them.
    pub keep_unparsed: bool,
    /// Those frames, when kept.
    pub unparsed: Vec<RawMessage>,
    /// Well-formed frames the link's check refused ([`decode_checked`]: a signature, an
    /// allow-list); not counted in `malformed`.
    pub refused: u32,
}

/// Splits a datagram into MAVLink 1/2 frames; each bad frame or run of junk counts once.
pub fn decode(datagram: &[u8]) -> Decoded {
    let mut out = Decoded::default();
    decode_into(datagram, &mut out);
    out
}

/// [`decode`], appending to `out` (no allocation once `out` has grown to a datagram's worth).
pub fn decode_into(datagram: &[u8], out: &mut Decoded) {
    decode_checked(datagram, out, &mut |_| true);
}

/// [`decode_into`], handing each frame whose checksum is right to `check` (the whole frame,
/// signature included) before its payload is parsed; a frame it refuses is counted in
/// `out.refused` and dropped.
pub fn decode_checked(datagram: &[u8], out: &mut Decoded, check: &mut dyn FnMut(&[u8]) -> bool) {
    Splitter::default().split(datagram, true, out, check);
}

/// Splits a byte stream (a serial line) into MAVLink frames, keeping a partial frame until the
/// rest of it arrives. Each bad frame or run of junk counts once, as in [`decode`].
#[derive(Debug, Default)]
pub struct StreamDecoder {
    buf: Vec<u8>,
    splitter: Splitter,
}

impl StreamDecoder {
    /// Adds the bytes just read; appends every complete message to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut Decoded) {
        self.push_checked(bytes, out, &mut |_| true);
    }

    /// [`StreamDecoder::push`] with a check of each well-formed frame, as [`decode_checked`].
    pub fn push_checked(
        &mut self,
        bytes: &[u8],
        out: &mut Decoded,
        check: &mut dyn FnMut(&[u8]) -> bool,
    ) {
        self.buf.extend_from_slice(bytes);
        let used = self.splitter.split(&self.buf, false, out, check);
        self.buf.drain(..used);
    }

    /// Bytes held back waiting for the rest of a frame.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }
}

/// The frame splitter shared by datagrams and streams.
#[derive(Debug, Default)]
struct Splitter {
    /// Inside a run of junk that has been counted.
    in_junk: bool,
    /// Bytes left of a bad frame that has been counted: start bytes inside it are not new errors.
    shadow: usize,
}

impl Splitter {
    /// Appends the messages of `buf` to `out`; returns the bytes used: all of a `whole` buffer
    /// (a datagram: a frame running past its end is truncated), all but an incomplete frame at
    /// the end of a stream's buffer.
    fn split(
        &mut self,
        buf: &[u8],
        whole: bool,
        out: &mut Decoded,
        check: &mut dyn FnMut(&[u8]) -> bool,
    ) -> usize {
        let mut i = 0;
        while i < buf.len() {
            let rest = &buf[i..];
            match frame_len(rest) {
                Ok(Some(len)) if len <= rest.len() || whole => {
                    let frame = rest
                        .get(..len)
                        .map_or(Frame::Bad, |f| parse_frame(f, check));
                    let good = !matches!(frame, Frame::Bad);
                    match frame {
                        Frame::Message(h, m) => out.messages.push((h, m)),
                        Frame::Unparsed(raw) => {
                            out.malformed += 1;
                            if out.keep_unparsed {
                                out.unparsed.push(raw);
                            }
                        }
                        Frame::Refused => out.refused += 1,
                        Frame::Bad => {}
                    }
                    if good {
                        self.in_junk = false;
                        self.shadow = 0;
                        i += len;
                        continue;
                    }
                    // Bad checksum or payload, or truncated: count it once, resynchronise on
                    // the next byte.
                    if self.shadow == 0 {
                        out.malformed += 1;
                        self.shadow = len;
                    }
                    self.in_junk = true;
                }
                Ok(_) => return i, // the rest of the frame is not here (yet)
                Err(()) => {
                    if !self.in_junk && self.shadow == 0 {
                        out.malformed += 1;
                    }
                    self.in_junk = true;
                }
            }
            i += 1;
            self.shadow = self.shadow.saturating_sub(1);
        }
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::{HEARTBEAT_DATA, HIL_ACTUATOR_CONTROLS_DATA, MavModeFlag};
    use proptest::prelude::*;

    fn header(seq: u8) -> MavHeader {
        MavHeader {
            system_id: 7,
            component_id: 25,
            sequence: seq,
        }
    }

    fn messages() -> impl Strategy<Value = MavMessage> {
        let controls = (
            any::<u64>(),
            proptest::array::uniform16(-2.0f32..2.0),
            any::<bool>(),
        )
            .prop_map(|(t, c, armed)| {
                MavMessage::HIL_ACTUATOR_CONTROLS(HIL_ACTUATOR_CONTROLS_DATA {
                    time_usec: t,
                    controls: c,
                    mode: if armed {
                        MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
                    } else {
                        MavModeFlag::empty()
                    },
                    ..Default::default()
                })
            });
        let heartbeat = (any::<u32>(), any::<u8>()).prop_map(|(mode, version)| {
            MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: mode,
                mavlink_version: version,
                ..Default::default()
            })
        });
        prop_oneof![controls, heartbeat]
    }

    #[test]
    fn checksum_is_the_x25_crc() {
        // CRC-16/MCRF4XX check value of "123456789" is 0x6F91; MAVLink then adds CRC_EXTRA.
        let without_extra = b"123456789".iter().fold(0xFFFF, |c, &b| crc_byte(c, b));
        assert_eq!(without_extra, 0x6F91);
    }

    proptest! {
        /// Slicing by 8 is the byte-at-a-time CRC, whatever the length.
        #[test]
        fn checksum_matches_the_mavlink_crate(
            data in proptest::collection::vec(any::<u8>(), 0..300), extra in any::<u8>()
        ) {
            prop_assert_eq!(checksum(&data, extra), mavlink::calculate_crc(&data, extra));
        }

        /// Our frames are the `mavlink` crate's frames, byte for byte, and read back as sent.
        #[test]
        fn frames_match_the_mavlink_crate(msg in messages(), seq in any::<u8>()) {
            let mut ours = Vec::new();
            let mut enc = Encoder::with_ids(7, 25);
            enc.sequence = seq;
            enc.push(&mut ours, &msg);
            let mut theirs = Vec::new();
            mavlink::write_v2_msg(&mut theirs, header(seq), &msg).unwrap();
            prop_assert_eq!(&ours, &theirs);
            let d = decode(&ours);
            prop_assert_eq!(d.malformed, 0);
            prop_assert_eq!(&d.messages, &vec![(header(seq), msg.clone())]);
            // MAVLink 1 input too.
            let mut v1 = Vec::new();
            mavlink::write_v1_msg(&mut v1, header(seq), &msg).unwrap();
            prop_assert_eq!(decode(&v1).messages.len(), 1);
        }

        /// Arbitrary bytes never panic either decoder.
        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let _ = decode(&bytes);
            StreamDecoder::default().push(&bytes, &mut Decoded::default());
        }

        /// Valid frames damaged every way a link damages them — cut short, a byte changed, the
        /// signed flag set or cleared, the length byte changed, runs of start bytes — never
        /// panic, and a stream never holds back more than one frame's worth of bytes however it
        /// is fed. (Whether a damaged frame is caught is the 16-bit checksum's business: a run
        /// of junk can pass it one time in 65 536, so that is not asserted here.)
        #[test]
        fn damaged_frames_never_panic_and_streams_stay_bounded(
            msgs in proptest::collection::vec(messages(), 1..8),
            damage in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..5), 1..12),
            piece in 1usize..300,
        ) {
            let mut enc = Encoder::with_ids(1, 25);
            let mut bytes = Vec::new();
            for m in &msgs {
                enc.push(&mut bytes, m);
            }
            for (at, value, how) in &damage {
                let i = at.index(bytes.len());
                match how {
                    0 => bytes.truncate(i.max(1)),
                    1 => bytes[i] ^= value | 1,
                    2 => bytes[i] = 0xFD,
                    3 => bytes.splice(i..i, std::iter::repeat_n(0xFD, (*value % 16) as usize)).for_each(drop),
                    _ => bytes.insert(i, *value),
                }
            }
            let d = decode(&bytes);
            prop_assert!(d.messages.len() <= bytes.len() / 12, "more messages than could fit");
            let mut s = StreamDecoder::default();
            let mut out = Decoded::default();
            for chunk in bytes.chunks(piece) {
                s.push(chunk, &mut out);
                prop_assert!(s.pending() < MAX_FRAME, "{} bytes held back", s.pending());
            }
        }

        /// Good frames between runs of junk all come out, each run counts once, and a stream
        /// read in pieces of any size sees what the datagram decoder sees.
        #[test]
        fn good_frames_survive_junk(
            parts in proptest::collection::vec(
                (messages(), proptest::collection::vec(0u8..0xFD, 0..40)), 1..6),
            piece in 1usize..80,
        ) {
            let mut enc = Encoder::with_ids(1, 25);
            let mut bytes = Vec::new();
            let mut runs = 0;
            for (msg, junk) in &parts {
                enc.push(&mut bytes, msg);
                bytes.extend_from_slice(junk);
                runs += usize::from(!junk.is_empty());
            }
            let d = decode(&bytes);
            let sent: Vec<&MavMessage> = parts.iter().map(|(m, _)| m).collect();
            let got: Vec<&MavMessage> = d.messages.iter().map(|(_, m)| m).collect();
            prop_assert_eq!(&got, &sent);
            prop_assert_eq!(d.malformed as usize, runs);
            let mut s = StreamDecoder::default();
            let mut out = Decoded::default();
            for chunk in bytes.chunks(piece) {
                s.push(chunk, &mut out);
            }
            prop_assert_eq!(out, d);
        }
    }

    #[test]
    fn unknown_incompat_flags_and_unknown_ids_are_refused() {
        let mut frame = Vec::new();
        Encoder::with_ids(1, 25).push(
            &mut frame,
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        );
        let mut flagged = frame.clone();
        flagged[2] = 0x02;
        assert_eq!(decode(&flagged).messages.len(), 0);
        let mut unknown = frame.clone();
        unknown[9] = 0x7F; // message id 0x7F0000
        let d = decode(&unknown);
        assert_eq!((d.messages.len(), d.malformed), (0, 1));
    }

    #[test]
    fn a_check_sees_each_well_formed_frame_whole_and_its_refusals_are_counted_apart() {
        let mut bytes = Vec::new();
        let mut enc = Encoder::with_ids(1, 25);
        for mode in 0..4 {
            let hb = HEARTBEAT_DATA {
                custom_mode: mode,
                ..Default::default()
            };
            enc.push(&mut bytes, &MavMessage::HEARTBEAT(hb));
        }
        bytes.extend_from_slice(&[0xFD, 3, 0]); // junk
        let frame_len = (bytes.len() - 3) / 4;
        let mut seen = Vec::new();
        let mut check = |f: &[u8]| {
            seen.push(f.len());
            f[4].is_multiple_of(2) // even sequence numbers only
        };
        let mut d = Decoded::default();
        decode_checked(&bytes, &mut d, &mut check);
        assert_eq!(seen, [frame_len; 4]);
        assert_eq!((d.messages.len(), d.refused, d.malformed), (2, 2, 1));
        // The same through a stream, a byte at a time.
        let mut s = StreamDecoder::default();
        let mut d = Decoded::default();
        for b in &bytes {
            s.push_checked(std::slice::from_ref(b), &mut d, &mut |f| {
                !f[4].is_multiple_of(2)
            });
        }
        assert_eq!((d.messages.len(), d.refused), (2, 2));
    }
}
