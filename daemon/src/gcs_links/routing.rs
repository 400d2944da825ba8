//! What the links heard, routed by job: file transfers to the file services, `SETUP_SIGNING` to
//! signing, the shell (trusted links only while signing is on) and everything else to the
//! ground-station protocol.

use super::signing::setup_signing;
use super::transport::Inbound;
use gcs::signing::Signing;
use gcs::telemetry::Telemetry;
use gcs::{GroundStation, LinkId, Outbox, Outgoing};
use mavlink::dialects::common::MavMessage;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use vehicle_files::FileServices;

/// Messages of file transfers (FTP burst reads, log downloads) sent per poll: with a poll
/// every 10 ms, up to 12 800 a second, on the requester's link whatever its speed. Over
/// loopback UDP that is 1.7 MiB/s of FTP to pymavlink and 1.1 MiB/s of log download to MAVSDK
/// (the clients' own pace: tests/python/test_files.py).
const FILES_PER_POLL: usize = 128;

/// Where heard messages go.
pub(super) struct Router {
    system_id: u8,
    files: FileServices,
    /// What the file services have to send, by link.
    files_out: Vec<(LinkId, MavMessage)>,
    signing: Arc<Mutex<Signing>>,
    /// Where a key set by `SETUP_SIGNING` is kept.
    signing_key_file: Option<PathBuf>,
    start: Instant,
    /// Frames that did not parse.
    pub(super) malformed: u64,
}

impl Router {
    /// Routes for system `system_id`, with its file services and signing.
    pub(super) fn new(
        system_id: u8,
        files: FileServices,
        signing: Arc<Mutex<Signing>>,
        signing_key_file: Option<PathBuf>,
    ) -> Self {
        Self {
            system_id,
            files,
            files_out: Vec::new(),
            signing,
            signing_key_file,
            start: Instant::now(),
            malformed: 0,
        }
    }

    /// Seconds since the links started.
    pub(super) fn now_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Routes what one link delivered.
    pub(super) fn heard(
        &mut self,
        i: &Inbound,
        gcs: &mut GroundStation,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        self.malformed += i.malformed as u64;
        for (h, m) in &i.messages {
            match m {
                m if FileServices::handles(m) => {
                    let now = self.now_s();
                    self.files
                        .on_message(i.link, h, m, now, &mut self.files_out);
                }
                MavMessage::SETUP_SIGNING(d) if d.target_system == self.system_id => {
                    let key_file = self.signing_key_file.as_deref();
                    let (severity, text) = setup_signing(&self.signing, key_file, d, i.trusted);
                    out.say(severity, &text);
                }
                MavMessage::SERIAL_CONTROL(d) => {
                    // The shell: with signing on, on a trusted endpoint only.
                    let signing_on = self
                        .signing
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .active();
                    let allowed = i.trusted || !signing_on;
                    gcs.on_serial_control(i.link, h, d, allowed, t, out);
                }
                _ => gcs.on_link_message(i.link, h, m, t, out),
            }
        }
        for raw in &i.unparsed {
            gcs.on_unparsed(raw, out);
        }
    }

    /// Lets the file services go on with transfers in progress.
    pub(super) fn poll_files(&mut self) {
        let now = self.now_s();
        self.files.poll(now, FILES_PER_POLL, &mut self.files_out);
    }

    /// Moves what the file services have to send into `out`, each on its link.
    pub(super) fn files_to(&mut self, out: &mut Outbox) {
        out.streamed.extend(
            self.files_out
                .drain(..)
                .map(|(link, m)| (link, Outgoing::Message(m))),
        );
    }
}
