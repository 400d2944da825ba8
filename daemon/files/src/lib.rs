//! The vehicle's files over MAVLink: the FTP microservice ([`ftp`]) over a served directory and
//! PX4's `@MAV_LOG`, and the log download protocol ([`logs`]) over the flight logs. The host
//! hands it the messages of these protocols with the link each came on and polls it for what
//! to send, each message on the link of the request it answers.

pub mod ftp;
pub mod logs;

use ftp::paths::FtpRoot;
use ftp::payload::{FtpError, FtpPayload, PAYLOAD_LEN};
pub use ftp::virtual_dir::VirtualDir;
use ftp::{FtpServer, Replies, Requester};
pub use logs::FileSends;
use logs::LogService;
use mavlink::MavHeader;
use mavlink::dialects::common::{FILE_TRANSFER_PROTOCOL_DATA, MavMessage};
use std::path::PathBuf;

/// What the files' services serve.
#[derive(Debug, Clone, Default)]
pub struct FilesConfig {
    /// The directory FTP serves (none: every FTP request is refused).
    pub ftp_root: Option<PathBuf>,
    /// The flight logs' directory: `@MAV_LOG` and the log download.
    pub logs: Option<PathBuf>,
    /// FTP may change files, and `LOG_ERASE` remove logs.
    pub writable: bool,
    /// The files the vehicle is writing now (its logs): never changed or erased from outside.
    pub busy: Vec<PathBuf>,
    /// Files held in memory, served read-only beside the root (the component metadata).
    pub virtual_dir: VirtualDir,
}

/// The FTP and log download services of one vehicle.
#[derive(Debug)]
pub struct FileServices {
    system_id: u8,
    component_id: u8,
    ftp: Option<FtpServer>,
    logs: Option<LogService>,
    /// Files may be changed (FTP writes, log erase).
    writable: bool,
    replies: Replies,
}

impl FileServices {
    /// The services of vehicle `system_id` (component `component_id`). A root that cannot be
    /// made leaves FTP refusing every request (said in the log), not the vehicle grounded.
    pub fn new(system_id: u8, component_id: u8, config: &FilesConfig) -> Self {
        let ftp = config.ftp_root.as_ref().and_then(|root| {
            match FtpRoot::new(root, config.logs.as_deref(), config.writable) {
                Ok(mut r) => {
                    r.set_busy(&config.busy);
                    Some(FtpServer::new(r, config.virtual_dir.clone()))
                }
                Err(e) => {
                    tracing::warn!(root = %root.display(), "MAVLink FTP off: {e}");
                    None
                }
            }
        });
        let logs = config.logs.as_ref().map(|dir| {
            let mut l = LogService::new(dir);
            l.set_busy(&config.busy);
            l
        });
        Self {
            system_id,
            component_id,
            ftp,
            logs,
            writable: config.writable,
            replies: Vec::new(),
        }
    }

    /// Whether `m` is a message of these services.
    pub fn handles(m: &MavMessage) -> bool {
        matches!(
            m,
            MavMessage::FILE_TRANSFER_PROTOCOL(_)
                | MavMessage::LOG_REQUEST_LIST(_)
                | MavMessage::LOG_REQUEST_DATA(_)
                | MavMessage::LOG_REQUEST_END(_)
                | MavMessage::LOG_ERASE(_)
        )
    }

    /// Whether a message addressed to `(system, component)` is for this vehicle.
    fn for_us(&self, system: u8, component: u8) -> bool {
        (system == self.system_id || system == 0)
            && (component == self.component_id || component == 0)
    }

    /// Takes one message of these services that came on `link` at `now_s` (a monotonic
    /// clock, s); what it answers at once goes to `out`.
    pub fn on_message(
        &mut self,
        link: u8,
        header: &MavHeader,
        m: &MavMessage,
        now_s: f64,
        out: &mut FileSends,
    ) {
        match m {
            MavMessage::FILE_TRANSFER_PROTOCOL(f)
                if self.for_us(f.target_system, f.target_component) =>
            {
                let from = Requester {
                    link,
                    system: header.system_id as u8,
                    component: header.component_id,
                };
                let req = FtpPayload::decode(&f.payload);
                match self.ftp.as_mut() {
                    Some(ftp) => ftp.handle(from, &req, now_s, &mut self.replies),
                    None => self.replies.push((from, req.nak(FtpError::Fail))),
                }
            }
            MavMessage::LOG_REQUEST_LIST(r) if self.for_us(r.target_system, r.target_component) => {
                if let Some(logs) = self.logs.as_mut() {
                    logs.request_list(link, r.start, r.end, out);
                }
            }
            MavMessage::LOG_REQUEST_DATA(r) if self.for_us(r.target_system, r.target_component) => {
                if let Some(logs) = self.logs.as_mut() {
                    logs.request_data(link, r.id, r.ofs, r.count, out);
                }
            }
            MavMessage::LOG_REQUEST_END(r) if self.for_us(r.target_system, r.target_component) => {
                if let Some(logs) = self.logs.as_mut() {
                    logs.request_end();
                }
            }
            MavMessage::LOG_ERASE(r) if self.for_us(r.target_system, r.target_component) => {
                match self.logs.as_mut() {
                    Some(logs) if self.writable => logs.erase(),
                    Some(_) => tracing::warn!("log erase refused: read-only (--ftp-read-only)"),
                    None => {}
                }
            }
            _ => {}
        }
        self.drain_replies(out);
    }

    /// Up to `budget` messages of the transfers under way (a burst read, a log listing or
    /// download), and the FTP session's idle time-out.
    pub fn poll(&mut self, now_s: f64, budget: usize, out: &mut FileSends) {
        let before = out.len();
        if let Some(ftp) = self.ftp.as_mut() {
            ftp.poll(now_s, budget, &mut self.replies);
        }
        self.drain_replies(out);
        if let Some(logs) = self.logs.as_mut() {
            logs.poll(budget.saturating_sub(out.len() - before), out);
        }
    }

    fn drain_replies(&mut self, out: &mut FileSends) {
        for (to, p) in self.replies.drain(..) {
            let payload: [u8; PAYLOAD_LEN] = p.encode();
            out.push((
                to.link,
                MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
                    target_network: 0,
                    target_system: to.system,
                    target_component: to.component,
                    payload,
                }),
            ));
        }
    }
}
