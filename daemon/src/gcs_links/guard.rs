//! Where every frame a ground-station link receives is checked before it is parsed (the
//! endpoint's allow-list, then signing), and what the sender's frames earn it.

use super::endpoint::LinkOptions;
use super::transport::Frame;
use gcs::LinkId;
use gcs::signing::{Signing, Verdict};
use hil::{Decoded, StreamDecoder};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// The checks of one endpoint.
#[derive(Debug, Clone)]
pub(super) struct Guard {
    /// The endpoint's options.
    pub(super) options: LinkOptions,
    /// The signing state every endpoint shares.
    pub(super) signing: Arc<Mutex<Signing>>,
    /// Frames from systems not on an allow-list (all endpoints).
    pub(super) not_allowed: Arc<AtomicU64>,
    /// The endpoint's link: what it hears is asked of this link's streams, and only this
    /// link's frames go out on it.
    pub(super) link: LinkId,
}

/// What a sender's frames showed: one accepted, one signed (or on a trusted link).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub(super) struct Heard {
    /// A frame was accepted.
    pub(super) accepted: bool,
    /// A frame was signed with the key, or came over a trusted link.
    pub(super) signed: bool,
}

impl Heard {
    /// Whether the sender earns the vehicle's answers (an answer slot, telemetry): a signed
    /// frame always; with signing off, any accepted one. An unsigned radio's or vehicle's
    /// heartbeat, which the spec lets through, earns nothing while signing is on: otherwise
    /// anyone could take the answer slots and hear the telemetry.
    pub(super) fn earns(self, signing_active: bool) -> bool {
        self.signed || (self.accepted && !signing_active)
    }
}

impl Guard {
    /// The frame if it goes out on this link.
    pub(super) fn ours<'a>(&self, frame: &'a Frame) -> Option<&'a [u8]> {
        (frame.0 == self.link).then_some(&frame.1[..])
    }

    /// Splits a datagram into `out`, checking each frame.
    pub(super) fn decode(&self, datagram: &[u8], out: &mut Decoded) -> Heard {
        let mut signing = self.signing.lock().unwrap_or_else(|e| e.into_inner());
        let mut heard = Heard::default();
        hil::decode_checked(datagram, out, &mut |f| {
            self.check(&mut signing, f, &mut heard)
        });
        heard
    }

    /// Adds a stream's bytes to `splitter`, checking each frame.
    pub(super) fn push(
        &self,
        splitter: &mut StreamDecoder,
        bytes: &[u8],
        out: &mut Decoded,
    ) -> Heard {
        let mut signing = self.signing.lock().unwrap_or_else(|e| e.into_inner());
        let mut heard = Heard::default();
        splitter.push_checked(bytes, out, &mut |f| self.check(&mut signing, f, &mut heard));
        heard
    }

    /// Signing is on.
    pub(super) fn signing_active(&self) -> bool {
        self.signing
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .active()
    }

    /// One frame judged on its own (the signing state locked for it alone).
    pub(super) fn check_one(&self, frame: &[u8]) -> bool {
        let mut signing = self.signing.lock().unwrap_or_else(|e| e.into_inner());
        self.check(&mut signing, frame, &mut Heard::default())
    }

    /// Whether `frame` (its checksum checked) may act; what it showed goes into `heard`.
    fn check(&self, signing: &mut Signing, frame: &[u8], heard: &mut Heard) -> bool {
        let system = if frame[0] == 0xFE { frame[3] } else { frame[5] };
        if !self.options.allowed_systems.is_empty()
            && !self.options.allowed_systems.contains(&system)
        {
            self.not_allowed.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        let verdict = signing.check(frame, self.options.trusted);
        heard.accepted |= verdict.accepted();
        heard.signed |= verdict == Verdict::Signed || (verdict.accepted() && self.options.trusted);
        verdict.accepted()
    }
}
