//! Log download (`LOG_REQUEST_LIST`, `LOG_ENTRY`, `LOG_REQUEST_DATA`, `LOG_DATA`,
//! `LOG_ERASE`, `LOG_REQUEST_END`) over the vehicle's ULog flight logs: numbered from 0, oldest
//! first, each with its exact size and the UTC time it began; any range of a log downloads in
//! 90-byte pieces at the pace the host allows, and a request at or past the end is answered
//! with an empty piece (which MAVProxy takes as the end).

use mavlink::dialects::common::{LOG_DATA_DATA, LOG_ENTRY_DATA, MavMessage};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Bytes a `LOG_DATA` carries.
const PIECE: usize = 90;

/// One flight log as listed.
#[derive(Debug, Clone, PartialEq)]
pub struct LogFileEntry {
    /// Its file.
    pub path: PathBuf,
    /// Its size when listed (bytes): what a download delivers.
    pub size: u64,
    /// When it began (s since the Unix epoch; 0 if unknown).
    pub utc_s: u32,
}

/// The flight logs (`*.ulg`) in `dir`, oldest first: by name, which starts with the start
/// time (`2026-11-24_23-49-55.ulg`, then `…-2.ulg` for a second run in that second).
pub fn list(dir: &Path) -> Vec<LogFileEntry> {
    let Ok(read) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut logs: Vec<LogFileEntry> = read
        .filter_map(|e| e.ok())
        .filter(|e| e.path().extension().is_some_and(|x| x == "ulg"))
        .filter_map(|e| {
            let meta = e.metadata().ok().filter(|m| m.is_file())?;
            let began = meta.created().or_else(|_| meta.modified()).ok();
            let utc_s = began
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0, |d| u32::try_from(d.as_secs()).unwrap_or(u32::MAX));
            Some(LogFileEntry {
                path: e.path(),
                size: meta.len(),
                utc_s,
            })
        })
        .collect();
    logs.sort_by_key(|l| order_key(&l.path));
    logs
}

/// Sorts a run's logs by start time, then by the `-N` of a later run in the same second
/// (bytes, not characters: any name sorts, none can fail).
fn order_key(path: &Path) -> (Vec<u8>, usize, Vec<u8>) {
    let stem = path.file_stem().map_or(&[][..], |s| s.as_encoded_bytes());
    // The start time is the first 19 bytes (`YYYY-MM-DD_HH-MM-SS`).
    let (time, rest) = stem.split_at(stem.len().min(19));
    (time.to_vec(), rest.len(), rest.to_vec())
}

/// A download under way.
#[derive(Debug)]
struct Transfer {
    link: u8,
    id: u16,
    file: File,
    offset: u64,
    end: u64,
}

/// The log download service of one vehicle.
#[derive(Debug)]
pub struct LogService {
    dir: PathBuf,
    /// The logs as last listed (ids index it).
    listed: Vec<LogFileEntry>,
    /// Entries still to send: (link, next id, last id).
    listing: Option<(u8, u16, u16)>,
    transfer: Option<Transfer>,
    /// Files the vehicle is writing now: never erased.
    busy: Vec<PathBuf>,
}

/// Messages to send, each on its link.
pub type FileSends = Vec<(u8, MavMessage)>;

impl LogService {
    /// The service of the logs in `dir`.
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_owned(),
            listed: Vec::new(),
            listing: None,
            transfer: None,
            busy: Vec::new(),
        }
    }

    /// Files the vehicle is writing now, which an erase leaves.
    pub fn set_busy(&mut self, files: &[PathBuf]) {
        self.busy = files.to_vec();
    }

    /// `LOG_REQUEST_LIST` from `link`: entries `start` to `end` (0xffff: the last) follow from
    /// [`LogService::poll`]; no log at all is one entry saying so.
    pub fn request_list(&mut self, link: u8, start: u16, end: u16, out: &mut FileSends) {
        self.listed = list(&self.dir);
        let n = u16::try_from(self.listed.len()).unwrap_or(u16::MAX);
        if n == 0 {
            self.listing = None;
            out.push((link, entry_message(0, 0, None)));
            return;
        }
        let last = end.min(n - 1);
        self.listing = (start <= last).then_some((link, start, last));
    }

    /// `LOG_REQUEST_DATA`: `count` bytes (0xffffffff: to the end) of log `id` from `ofs`. An
    /// unknown id is ignored, as PX4 does; a start at or past the end is one empty piece.
    pub fn request_data(&mut self, link: u8, id: u16, ofs: u32, count: u32, out: &mut FileSends) {
        let Some(log) = self.listed.get(usize::from(id)) else {
            return;
        };
        let (ofs, size) = (u64::from(ofs), log.size);
        if ofs >= size {
            self.transfer = None;
            out.push((link, data_message(id, size, &[])));
            return;
        }
        match File::open(&log.path) {
            Ok(file) => {
                self.transfer = Some(Transfer {
                    link,
                    id,
                    file,
                    offset: ofs,
                    end: ofs.saturating_add(count.into()).min(size),
                });
            }
            Err(e) => tracing::warn!(log = %log.path.display(), "log download: {e}"),
        }
    }

    /// `LOG_REQUEST_END`: stops sending.
    pub fn request_end(&mut self) {
        self.transfer = None;
        self.listing = None;
    }

    /// `LOG_ERASE`: removes every flight log but those being written, with the telemetry log
    /// and flight CSV of the same run.
    pub fn erase(&mut self) {
        self.request_end();
        for log in list(&self.dir) {
            if self.busy.iter().any(|b| same_file(b, &log.path)) {
                continue;
            }
            for ext in ["ulg", "tlog", "csv"] {
                let path = log.path.with_extension(ext);
                if path.exists()
                    && let Err(e) = std::fs::remove_file(&path)
                {
                    tracing::warn!(file = %path.display(), "log erase: {e}");
                }
            }
        }
        self.listed.clear();
    }

    /// Sends up to `budget` messages of the listing, then of the download, under way.
    pub fn poll(&mut self, budget: usize, out: &mut FileSends) {
        let mut sent = 0;
        while sent < budget {
            let Some((link, id, last)) = self.listing else {
                break;
            };
            let n = u16::try_from(self.listed.len()).unwrap_or(u16::MAX);
            let Some(log) = self.listed.get(usize::from(id)) else {
                self.listing = None;
                break;
            };
            out.push((link, entry_message(id, n, Some(log))));
            sent += 1;
            self.listing = (id < last).then_some((link, id + 1, last));
        }
        while sent < budget {
            let Some(t) = self.transfer.as_mut() else {
                break;
            };
            let n = (t.end - t.offset).min(PIECE as u64) as usize;
            let mut piece = [0u8; PIECE];
            let read = t
                .file
                .seek(SeekFrom::Start(t.offset))
                .and_then(|_| t.file.read_exact(&mut piece[..n]));
            if let Err(e) = read {
                tracing::warn!("log download stopped: {e}");
                self.transfer = None;
                break;
            }
            out.push((t.link, data_message(t.id, t.offset, &piece[..n])));
            sent += 1;
            t.offset += n as u64;
            if t.offset >= t.end {
                self.transfer = None;
            }
        }
    }
}

/// Whether two paths name the same file (both made canonical where they exist).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// `LOG_ENTRY` of log `id` of `num_logs` (none: no log at all).
fn entry_message(id: u16, num_logs: u16, log: Option<&LogFileEntry>) -> MavMessage {
    MavMessage::LOG_ENTRY(LOG_ENTRY_DATA {
        id,
        num_logs,
        last_log_num: num_logs.saturating_sub(1),
        time_utc: log.map_or(0, |l| l.utc_s),
        size: log.map_or(0, |l| u32::try_from(l.size).unwrap_or(u32::MAX)),
    })
}

/// `LOG_DATA` of log `id` at `ofs` with `bytes` (none: the end).
fn data_message(id: u16, ofs: u64, bytes: &[u8]) -> MavMessage {
    let mut data = [0u8; PIECE];
    data[..bytes.len()].copy_from_slice(bytes);
    MavMessage::LOG_DATA(LOG_DATA_DATA {
        ofs: u32::try_from(ofs).unwrap_or(u32::MAX),
        id,
        count: bytes.len() as u8,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logs_list_oldest_first_and_download_in_aligned_pieces() {
        let dir = std::env::temp_dir().join(format!("logs-svc-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let mut s = LogService::new(&dir);
        let mut out = Vec::new();
        s.request_list(1, 0, 0xffff, &mut out);
        let MavMessage::LOG_ENTRY(e) = &out[0].1 else {
            panic!("{out:?}")
        };
        assert_eq!((out.len(), e.num_logs, e.size), (1, 0, 0));
        let names = [
            "2026-11-24_10-00-00-2",
            "2026-11-24_10-00-00",
            "2026-11-23_09-00-00",
        ];
        for (k, n) in names.iter().enumerate() {
            std::fs::write(dir.join(format!("{n}.ulg")), vec![k as u8; 200 + k]).expect("log");
            std::fs::write(dir.join(format!("{n}.csv")), b"t").expect("csv");
        }
        out.clear();
        s.request_list(1, 0, 0xffff, &mut out);
        s.poll(10, &mut out);
        let sizes: Vec<u32> = out
            .iter()
            .map(|(_, m)| match m {
                MavMessage::LOG_ENTRY(e) => e.size,
                _ => 0,
            })
            .collect();
        assert_eq!(sizes, [202, 201, 200], "oldest first");
        out.clear();
        s.request_data(2, 1, 0, u32::MAX, &mut out);
        s.poll(100, &mut out);
        let pieces: Vec<(u32, u8)> = out
            .iter()
            .map(|(link, m)| match m {
                MavMessage::LOG_DATA(d) if *link == 2 => (d.ofs, d.count),
                _ => panic!("{m:?}"),
            })
            .collect();
        assert_eq!(pieces, [(0, 90), (90, 90), (180, 21)]);
        out.clear();
        s.request_data(2, 1, 201, 90, &mut out);
        assert!(matches!(&out[0].1, MavMessage::LOG_DATA(d) if d.count == 0 && d.ofs == 201));
        s.request_data(2, 9, 0, 90, &mut out);
        assert_eq!(out.len(), 1, "an unknown log is ignored");
        s.set_busy(&[dir.join("2026-11-24_10-00-00-2.ulg")]);
        s.erase();
        let left: Vec<_> = list(&dir).into_iter().map(|l| l.size).collect();
        assert_eq!(left, [200], "the log being written stays");
        assert!(!dir.join("2026-11-23_09-00-00.csv").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
