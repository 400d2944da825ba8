//! The frames of every link: what the vehicle sends, encoded in its link's own sequence, signed
//! when signing is on, recorded in the telemetry log (link 0's, file transfers aside) and handed
//! to the link's transport; and what the links heard, recorded as it was framed.

use super::transport::{Frames, Inbound};
use super::unix_usec;
use crate::records::log_files::Tlog;
use gcs::signing::Signing;
use gcs::{COMPONENT_ID, LinkId, Outbox, Outgoing};
use hil::Encoder;
use mavlink::dialects::common::MavMessage;
use std::sync::{Arc, Mutex};

/// The sending side of every link, and the telemetry log.
pub(super) struct LinkOutput {
    /// One encoder (one sequence) per link, so that each ground station sees its link's
    /// sequence without gaps; at least one, for the telemetry log.
    encoders: Vec<Encoder>,
    frames: Frames,
    signing: Arc<Mutex<Signing>>,
    /// The MAVLink telemetry log, if one is kept.
    tlog: Option<Tlog>,
}

impl LinkOutput {
    /// `links` links of system `system_id`, their frames handed to `frames`.
    pub(super) fn new(
        system_id: u8,
        links: usize,
        frames: Frames,
        signing: Arc<Mutex<Signing>>,
        tlog: Option<Tlog>,
    ) -> Self {
        Self {
            encoders: (0..links.max(1))
                .map(|_| Encoder::with_ids(system_id, COMPONENT_ID))
                .collect(),
            frames,
            signing,
            tlog,
        }
    }

    /// Sends what `out` holds: a message for every link on each in its own sequence, a
    /// streamed one on its link.
    pub(super) fn send(&mut self, out: &mut Outbox) {
        if out.messages.is_empty() && out.streamed.is_empty() {
            return;
        }
        self.signing().tick(unix_usec());
        let links = self.encoders.len() as LinkId;
        let everywhere = out
            .messages
            .drain(..)
            .flat_map(|m| (0..links).map(move |l| (l, m.clone())));
        let one_link = out.streamed.drain(..);
        for (link, m) in everywhere.chain(one_link) {
            self.send_one(link, &m);
        }
    }

    /// Encodes, signs, records and hands over one message on `link`.
    fn send_one(&mut self, link: LinkId, m: &Outgoing) {
        let Some(encoder) = self.encoders.get_mut(usize::from(link)) else {
            return;
        };
        let mut bytes = Vec::with_capacity(64);
        match m {
            Outgoing::Message(m) => encoder.push(&mut bytes, m),
            Outgoing::Raw(id, payload) => encoder.push_raw(&mut bytes, *id, payload),
        }
        self.signing().sign(&mut bytes);
        // File transfers stay out of it: a log downloaded would grow the log.
        let transfer = matches!(
            m,
            Outgoing::Message(
                MavMessage::FILE_TRANSFER_PROTOCOL(_)
                    | MavMessage::LOG_DATA(_)
                    | MavMessage::LOG_ENTRY(_)
            )
        );
        if link == 0
            && !transfer
            && let Some(log) = self.tlog.as_mut()
        {
            log.record(unix_usec(), &bytes);
        }
        // No endpoint listening is not an error.
        let _ = self.frames.send((link, bytes.into()));
    }

    /// Records in the telemetry log what a link heard, each message framed again as its
    /// sender sent it (header and sequence kept; a signature is not).
    pub(super) fn record_heard(&mut self, i: &Inbound) {
        let Some(log) = self.tlog.as_mut() else {
            return;
        };
        let now = unix_usec();
        let mut frame = Vec::with_capacity(280);
        for (h, m) in &i.messages {
            frame.clear();
            Encoder::push_heard(&mut frame, h, m);
            log.record(now, &frame);
        }
        for raw in &i.unparsed {
            frame.clear();
            Encoder::push_raw_heard(&mut frame, &raw.header, raw.msg_id, &raw.payload);
            log.record(now, &frame);
        }
    }

    /// Writes the telemetry log's batch when due; a full disk stops the log, not the links.
    pub(super) fn ship_log(&mut self) {
        if let Some(log) = self.tlog.as_mut()
            && let Err(e) = log.ship_if_due(unix_usec())
        {
            tracing::error!(file = %log.path().display(), "telemetry log: {e}; logging stopped");
            self.tlog = None;
        }
    }

    /// Writes the rest of the telemetry log.
    pub(super) async fn finish(self) {
        let Some(log) = self.tlog else {
            return;
        };
        let path = log.path().to_owned();
        match tokio::task::spawn_blocking(move || log.finish()).await {
            Ok(Ok(())) => tracing::info!(file = %path.display(), "telemetry log written"),
            Ok(Err(e)) => tracing::error!(file = %path.display(), "telemetry log: {e}"),
            Err(e) => tracing::error!(file = %path.display(), "telemetry log: {e}"),
        }
    }

    fn signing(&self) -> std::sync::MutexGuard<'_, Signing> {
        self.signing.lock().unwrap_or_else(|e| e.into_inner())
    }
}
