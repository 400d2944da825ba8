//! MAVLink 2 message signing (<https://mavlink.io/en/guide/message_signing.html>), pure: the
//! links hand it each well-formed frame and their wall clock, it says whether the frame may act
//! and signs what the vehicle sends.
//!
//! A signed frame carries the incompatibility flag 0x01 and 13 bytes after its checksum: the
//! sender's link id, a 48-bit timestamp (10 µs units since 2015-01-01 UTC) and the first 6
//! bytes of SHA-256(secret key ‖ header ‖ payload ‖ checksum ‖ link id ‖ timestamp).
//!
//! With a key, signing is required: a frame acts only if its signature is right and its
//! timestamp is newer than the last one of its stream (system, component, link id) — a new
//! stream's may lag the vehicle's clock by at most one minute. Unsigned frames are refused but
//! for `RADIO_STATUS` and the `HEARTBEAT` of anything but a ground station, as the spec allows
//! (radios cannot sign; a ground station can, and its heartbeat keeps the link-loss failsafe
//! away, so it must). A link marked trusted (a USB cable) is exempt, as PX4's `MAV_SIGN_CFG` 1.
//! Without a key every frame is accepted and signatures are ignored.
//!
//! A timestamp more than a minute ahead of the vehicle's clock is refused too (once the wall
//! clock is believable), and the clock and
//! each stream's last timestamp outlive a restart ([`SigningMemory`], kept by the daemon), so a
//! frame captured before a restart cannot be replayed after it, as the spec asks.

mod memory;

pub use memory::{MemoryUnreadable, SigningMemory};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::fmt;

const STX_V2: u8 = 0xFD;
const V2_HEADER: usize = 10;
const CHECKSUM: usize = 2;
/// Link id, timestamp and signature.
pub const SIGNATURE_LEN: usize = 13;
const IFLAG_SIGNED: u8 = 0x01;
/// The Unix time of the signing epoch, 2015-01-01 00:00:00 UTC (s).
const EPOCH_2015_UNIX_S: u64 = 1_420_070_400;
/// How far a new stream's first timestamp may lag the vehicle's clock, and how far any
/// timestamp may lead it: one minute (10 µs units).
const NEW_STREAM_WINDOW: u64 = 60 * 100_000;
/// A wall clock before 2025-01-01 is not believed (a board without a real-time clock, before
/// network time): until one after it is seen, no timestamp is too far ahead, and the signed
/// frames set the vehicle's clock, as the spec suggests (10 µs units).
const BELIEVABLE_CLOCK: u64 = (1_735_689_600 - EPOCH_2015_UNIX_S) * 100_000;
/// Streams remembered; a new one beyond this replaces the one heard from least recently.
const MAX_STREAMS: usize = 256;
const HEARTBEAT_ID: u32 = 0;
const RADIO_STATUS_ID: u32 = 109;
const MAV_TYPE_GCS: u8 = 6;

/// A 32-byte signing key. Its `Debug` does not show it.
#[derive(Clone, PartialEq, Eq)]
pub struct SecretKey(pub [u8; 32]);

impl fmt::Debug for SecretKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SecretKey(…)")
    }
}

/// A signing key's text that is not 64 hexadecimal digits.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("a signing key is 64 hexadecimal digits (32 bytes), not {chars} characters")]
pub struct KeyNotHex {
    /// The characters given (white space around them not counted).
    pub chars: usize,
}

impl SecretKey {
    /// The key written as 64 hexadecimal digits (surrounding white space ignored).
    pub fn from_hex(text: &str) -> Result<Self, KeyNotHex> {
        let t = text.trim();
        if t.len() != 64 || !t.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(KeyNotHex { chars: t.len() });
        }
        let mut key = [0u8; 32];
        for (i, k) in key.iter_mut().enumerate() {
            *k = u8::from_str_radix(&t[2 * i..2 * i + 2], 16)
                .map_err(|_| KeyNotHex { chars: t.len() })?;
        }
        Ok(Self(key))
    }

    /// The key as 64 hexadecimal digits.
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// What [`Signing::check`] decided about a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Signed with the key, and new.
    Signed,
    /// Accepted without a signature (no key, a trusted link, or a message the spec lets through).
    Unsigned,
    /// Refused: no signature where one is required.
    RefusedUnsigned,
    /// Refused: the signature is not the key's.
    RefusedBadSignature,
    /// Refused: the timestamp is not newer than its stream's last, or a new stream's is more than
    /// a minute old (a replay).
    RefusedReplay,
    /// Refused: the timestamp is more than a minute ahead of the vehicle's clock (it would
    /// move the clock, and every stream's window, into the future).
    RefusedFuture,
}

impl Verdict {
    /// The frame may act.
    pub fn accepted(self) -> bool {
        matches!(self, Verdict::Signed | Verdict::Unsigned)
    }
}

/// Frames refused, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Refusals {
    /// Unsigned where a signature is required.
    pub unsigned: u64,
    /// Wrongly signed.
    pub bad_signature: u64,
    /// Replayed or too old.
    pub replayed: u64,
    /// Timestamped too far ahead.
    pub future: u64,
}

/// The signing state of the vehicle: its key, its clock and the streams it has accepted.
#[derive(Debug, Default)]
pub struct Signing {
    key: Option<SecretKey>,
    /// The vehicle's signing clock (10 µs since 2015): never goes back.
    timestamp: u64,
    /// (system, component, link id) → (last timestamp, when last accepted in `accepted`).
    streams: HashMap<(u8, u8, u8), (u64, u64)>,
    accepted: u64,
    /// The link id the vehicle signs with.
    link_id: u8,
    /// The wall clock has been seen after 2025: timestamps far ahead of the vehicle's clock
    /// are refused from then on.
    wall_clock_believed: bool,
    /// Frames refused so far.
    pub refused: Refusals,
}

impl Signing {
    /// Signing with `key` (none: off).
    pub fn new(key: Option<SecretKey>) -> Self {
        Self {
            key,
            ..Self::default()
        }
    }

    /// Signing is on.
    pub fn active(&self) -> bool {
        self.key.is_some()
    }

    /// A new key (`SETUP_SIGNING`): an all-zero key turns signing off. The clock moves on to
    /// `initial_timestamp` if that is later; streams heard under the old key are forgotten.
    pub fn set_key(&mut self, key: SecretKey, initial_timestamp: u64) {
        self.key = (key.0 != [0; 32]).then_some(key);
        self.timestamp = self.timestamp.max(initial_timestamp);
        self.streams.clear();
    }

    /// The signing clock follows the wall clock (`unix_usec`), never going back.
    pub fn tick(&mut self, unix_usec: u64) {
        let now = (unix_usec / 10).saturating_sub(EPOCH_2015_UNIX_S * 100_000);
        self.wall_clock_believed |= now >= BELIEVABLE_CLOCK;
        self.timestamp = self.timestamp.max(now);
    }

    /// The vehicle's signing clock (10 µs since 2015).
    pub fn timestamp(&self) -> u64 {
        self.timestamp
    }

    /// Signed frames accepted so far: the streams' timestamps (the memory worth keeping)
    /// change when this does.
    pub fn accepted_count(&self) -> u64 {
        self.accepted
    }

    /// What must outlive a restart: the clock and each stream's last timestamp.
    pub fn memory(&self) -> SigningMemory {
        let mut streams: Vec<_> = self.streams.iter().map(|(k, v)| (*k, v.0)).collect();
        streams.sort_unstable();
        SigningMemory {
            timestamp: self.timestamp,
            streams,
        }
    }

    /// Takes up what an earlier run remembered: its clock (if later) and its streams, whose
    /// next frames must be newer than their last.
    pub fn remember(&mut self, m: &SigningMemory) {
        self.timestamp = self.timestamp.max(m.timestamp);
        for &(stream, last) in m.streams.iter().take(MAX_STREAMS) {
            let known = self.streams.entry(stream).or_insert((last, 0));
            known.0 = known.0.max(last);
        }
    }

    /// Decides about one well-formed frame (its checksum checked) received on a link that is
    /// `trusted` or not, and counts a refusal.
    pub fn check(&mut self, frame: &[u8], trusted: bool) -> Verdict {
        let verdict = self.verdict(frame, trusted);
        match verdict {
            Verdict::RefusedUnsigned => self.refused.unsigned += 1,
            Verdict::RefusedBadSignature => self.refused.bad_signature += 1,
            Verdict::RefusedReplay => self.refused.replayed += 1,
            Verdict::RefusedFuture => self.refused.future += 1,
            Verdict::Signed | Verdict::Unsigned => {}
        }
        verdict
    }

    fn verdict(&mut self, frame: &[u8], trusted: bool) -> Verdict {
        let Some(key) = &self.key else {
            return Verdict::Unsigned;
        };
        let v2 = frame.first() == Some(&STX_V2) && frame.len() >= V2_HEADER + CHECKSUM;
        let signed = v2 && frame[2] & IFLAG_SIGNED != 0;
        if !signed {
            return if trusted || unsigned_allowed(frame) {
                Verdict::Unsigned
            } else {
                Verdict::RefusedUnsigned
            };
        }
        let Some(signed_part) = frame.len().checked_sub(6) else {
            return Verdict::RefusedBadSignature;
        };
        if frame.len() < V2_HEADER + CHECKSUM + SIGNATURE_LEN
            || signature(key, &frame[..signed_part]) != frame[signed_part..]
        {
            return Verdict::RefusedBadSignature;
        }
        let block = &frame[frame.len() - SIGNATURE_LEN..];
        let link_id = block[0];
        let mut ts = [0u8; 8];
        ts[..6].copy_from_slice(&block[1..7]);
        let timestamp = u64::from_le_bytes(ts);
        let stream = (frame[5], frame[6], link_id);
        if self.wall_clock_believed && timestamp > self.timestamp + NEW_STREAM_WINDOW {
            return Verdict::RefusedFuture;
        }
        let fresh = match self.streams.get(&stream) {
            Some(&(last, _)) => timestamp > last,
            None => timestamp + NEW_STREAM_WINDOW >= self.timestamp,
        };
        if !fresh {
            return Verdict::RefusedReplay;
        }
        if !self.streams.contains_key(&stream)
            && self.streams.len() >= MAX_STREAMS
            && let Some(oldest) = self
                .streams
                .iter()
                .min_by_key(|(_, (_, used))| *used)
                .map(|(k, _)| *k)
        {
            self.streams.remove(&oldest);
        }
        self.accepted += 1;
        self.streams.insert(stream, (timestamp, self.accepted));
        self.timestamp = self.timestamp.max(timestamp);
        Verdict::Signed
    }

    /// Signs `frame`, one unsigned MAVLink 2 frame as `mavwire::Encoder` writes it: sets the
    /// signed flag, recomputes the checksum over the new header, appends link id, timestamp
    /// and signature. Without a key, or for a frame that is not an unsigned MAVLink 2 frame,
    /// nothing changes.
    pub fn sign(&mut self, frame: &mut Vec<u8>) {
        let Some(key) = &self.key else {
            return;
        };
        if frame.first() != Some(&STX_V2) || frame.len() < V2_HEADER + CHECKSUM {
            return;
        }
        let payload_end = V2_HEADER + frame[1] as usize;
        if frame.len() != payload_end + CHECKSUM || frame[2] & IFLAG_SIGNED != 0 {
            return;
        }
        frame[2] |= IFLAG_SIGNED;
        let msg_id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
        use mavlink::Message;
        let extra = mavlink::dialects::common::MavMessage::extra_crc(msg_id);
        let crc = mavwire::checksum(&frame[1..payload_end], extra);
        frame[payload_end..].copy_from_slice(&crc.to_le_bytes());
        frame.push(self.link_id);
        frame.extend_from_slice(&self.timestamp.to_le_bytes()[..6]);
        let sig = signature(key, frame);
        frame.extend_from_slice(&sig);
        self.timestamp += 1;
    }
}

/// The first 6 bytes of SHA-256(key ‖ `signed`), `signed` being the frame up to the signature.
fn signature(key: &SecretKey, signed: &[u8]) -> [u8; 6] {
    let digest = Sha256::new()
        .chain_update(key.0)
        .chain_update(signed)
        .finalize();
    let mut s = [0u8; 6];
    s.copy_from_slice(&digest[..6]);
    s
}

/// The unsigned frames the spec lets through: `RADIO_STATUS`, and a `HEARTBEAT` of anything but
/// a ground station.
fn unsigned_allowed(frame: &[u8]) -> bool {
    let (msg_id, payload) = match frame.first() {
        Some(&STX_V2) if frame.len() >= V2_HEADER => (
            u32::from_le_bytes([frame[7], frame[8], frame[9], 0]),
            frame.get(V2_HEADER..V2_HEADER + frame[1] as usize),
        ),
        // MAVLink 1: `FE len seq sys comp id payload crc`.
        _ if frame.len() >= 6 => (frame[5] as u32, frame.get(6..6 + frame[1] as usize)),
        _ => return false,
    };
    let payload = payload.unwrap_or_default();
    match msg_id {
        RADIO_STATUS_ID => true,
        // HEARTBEAT: custom_mode (u32), then type (MAVLink 2 truncates a zero to nothing).
        HEARTBEAT_ID => payload.get(4).copied().unwrap_or(0) != MAV_TYPE_GCS,
        _ => false,
    }
}

#[cfg(test)]
mod tests;
