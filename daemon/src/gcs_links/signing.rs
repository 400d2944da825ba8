//! Signing on the links' side: `SETUP_SIGNING` (the key from a trusted link, kept in its file),
//! the keeper of signing's memory (the streams' timestamps, written beside the key so that a
//! frame captured before a restart is a replay after it), and the report of refused frames.

use crate::records::signing_file;
use gcs::signing::{Refusals, SecretKey, Signing, SigningMemory};
use mavlink::dialects::common::MavSeverity;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// `SETUP_SIGNING` (<https://mavlink.io/en/guide/message_signing.html>): only from a trusted
/// link; the key is used at once and saved (mode 0600) where the daemon was told to keep it;
/// an all-zero key turns signing off (and removes the file). Returns what to tell the sender.
pub(super) fn setup_signing(
    signing: &Mutex<Signing>,
    key_file: Option<&std::path::Path>,
    data: &mavlink::dialects::common::SETUP_SIGNING_DATA,
    trusted: bool,
) -> (MavSeverity, String) {
    if !trusted {
        tracing::warn!("SETUP_SIGNING refused: it came over a link not marked trusted");
        return (
            MavSeverity::MAV_SEVERITY_WARNING,
            "SETUP_SIGNING refused: link not trusted".into(),
        );
    }
    let key = SecretKey(data.secret_key);
    let on = key.0 != [0; 32];
    let saved = match key_file {
        Some(path) if on => {
            crate::records::param_file::write_private(path, &format!("{}\n", key.to_hex()))
        }
        Some(path) => match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                Err(anyhow::Error::from(e).context(format!("removing {}", path.display())))
            }
            _ => Ok(()),
        },
        None => Ok(()),
    };
    let mut s = signing.lock().unwrap_or_else(|e| e.into_inner());
    s.set_key(key, data.initial_timestamp);
    let state = if s.active() {
        "signing on"
    } else {
        "signing off"
    };
    drop(s);
    match saved {
        Ok(()) => {
            tracing::info!(
                file = ?key_file,
                "SETUP_SIGNING from a trusted link: MAVLink {state}"
            );
            (MavSeverity::MAV_SEVERITY_INFO, format!("MAVLink {state}"))
        }
        Err(e) => {
            tracing::error!("SETUP_SIGNING: MAVLink {state}, but the key is not kept: {e:#}");
            (
                MavSeverity::MAV_SEVERITY_ERROR,
                format!("MAVLink {state}; key not saved"),
            )
        }
    }
}

/// Keeps signing's memory in its file, off the links' task: handed the memory whenever a signed
/// frame has been accepted since, it writes at most once a second, and the last one at the end
/// (a reboot or a shutdown).
pub(super) struct MemoryKeeper {
    memory: watch::Sender<Option<SigningMemory>>,
    writer: tokio::task::JoinHandle<()>,
    /// Signed frames accepted when the memory was last handed on.
    handed: Option<u64>,
}

impl MemoryKeeper {
    /// A keeper writing beside `key_file` (none: nowhere to keep it).
    pub(super) fn new(key_file: Option<&std::path::Path>) -> Option<Self> {
        let path = signing_file::memory_path(key_file?);
        let (memory, rx) = watch::channel(None);
        Some(Self {
            memory,
            writer: tokio::spawn(write_memory(path, rx)),
            handed: None,
        })
    }

    /// Hands the memory on if a signed frame was accepted since the last time.
    pub(super) fn note(&mut self, signing: &Mutex<Signing>) {
        let s = signing.lock().unwrap_or_else(|e| e.into_inner());
        let count = s.accepted_count();
        if !s.active() || self.handed == Some(count) {
            return;
        }
        self.handed = Some(count);
        let m = s.memory();
        drop(s);
        self.memory.send_replace(Some(m));
    }

    /// Hands on the last memory and waits until it is written.
    pub(super) async fn finish(mut self, signing: &Mutex<Signing>) {
        self.note(signing);
        drop(self.memory);
        let _ = self.writer.await;
    }
}

/// Writes each memory handed on (the latest, at most once a second); a failure is logged.
async fn write_memory(
    path: std::path::PathBuf,
    mut memory: watch::Receiver<Option<SigningMemory>>,
) {
    while memory.changed().await.is_ok() {
        let Some(m) = memory.borrow_and_update().clone() else {
            continue;
        };
        let p = path.clone();
        match tokio::task::spawn_blocking(move || signing_file::save_memory(&p, &m)).await {
            Ok(Ok(())) => {}
            Ok(Err(e)) => tracing::error!("signing timestamps not saved: {e:#}"),
            Err(e) => tracing::error!("signing timestamps not saved: {e}"),
        }
        if !memory.has_changed().unwrap_or(false) {
            tokio::time::sleep(Duration::from_secs(1)).await;
        }
    }
}

/// How often refused frames are reported in the log.
const REFUSALS_REPORT: Duration = Duration::from_secs(5);

/// Signing seen from the links' task: its memory kept in its file, and the frames it (and the
/// endpoints' allow-lists) refused reported in the log when their counts change.
pub(super) struct SigningWatch {
    signing: Arc<Mutex<Signing>>,
    memory: Option<MemoryKeeper>,
    /// Frames refused by the endpoints' `sysids` lists.
    not_allowed: Arc<AtomicU64>,
    reported: (Refusals, u64),
    next_report: Instant,
}

impl SigningWatch {
    /// Watches `signing` (its memory kept beside `key_file`) and the allow-lists' count.
    pub(super) fn new(
        signing: Arc<Mutex<Signing>>,
        key_file: Option<&std::path::Path>,
        not_allowed: Arc<AtomicU64>,
    ) -> Self {
        Self {
            signing,
            memory: MemoryKeeper::new(key_file),
            not_allowed,
            reported: Default::default(),
            next_report: Instant::now(),
        }
    }

    /// The refusals so far: signing's, and the allow-lists'.
    pub(super) fn refused(&self) -> (Refusals, u64) {
        (
            self.signing
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .refused,
            self.not_allowed.load(Ordering::Relaxed),
        )
    }

    /// Hands signing's memory on, and reports the refusals when due and changed.
    pub(super) fn tick(&mut self) {
        if let Some(m) = self.memory.as_mut() {
            m.note(&self.signing);
        }
        if Instant::now() < self.next_report {
            return;
        }
        self.next_report = Instant::now() + REFUSALS_REPORT;
        let now = self.refused();
        if now != self.reported {
            self.reported = now;
            let (r, n) = now;
            tracing::warn!(
                unsigned = r.unsigned,
                bad_signature = r.bad_signature,
                replayed = r.replayed,
                future = r.future,
                not_on_allow_list = n,
                "frames refused so far"
            );
        }
    }

    /// Writes the last memory.
    pub(super) async fn finish(&mut self) {
        if let Some(m) = self.memory.take() {
            m.finish(&self.signing).await;
        }
    }
}
