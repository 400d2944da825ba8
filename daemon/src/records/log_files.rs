//! A run's log files: where they go (`logs/2026-11-23_10-15-02.tlog` and `.csv`, named by the
//! UTC time of the start, as PX4 names its logs) and the writer thread behind each, so that
//! neither the control loop nor the ground-station task ever waits on the disk (as PX4's logger
//! and ArduPilot's both write from a thread of their own).
//!
//! The producers fill a buffer (bytes, or rows the writer formats) and hand it over every
//! [`SHIP_INTERVAL_S`]; a daemon killed outright loses at most that much of its logs.

use std::io::{Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, OnceLock};
use std::thread::JoinHandle;

/// How much of a log the producers hold before handing it to the writer (s).
pub const SHIP_INTERVAL_S: f64 = 0.5;

/// Buffers the writer may hold before a new one is dropped: 32 s of log at one per
/// [`SHIP_INTERVAL_S`], so only a disk stalled for that long loses anything.
const QUEUE: usize = 64;

/// One log file written by its own thread: the producers hand it chunks of `T` (bytes, or rows
/// the thread formats, so that formatting costs the producer nothing either).
pub struct LogFile<T: Send + 'static = Vec<u8>> {
    path: PathBuf,
    /// Chunks to write; `None` ends the file (other producers may still hold a sender).
    chunks: Option<SyncSender<Option<T>>>,
    writer: Option<JoinHandle<std::io::Result<()>>>,
    /// What stopped the writer, for the producers as soon as it happens (the error itself comes
    /// from [`LogFile::finish`]).
    fault: Arc<OnceLock<std::io::ErrorKind>>,
    /// Chunks dropped because the writer was behind.
    dropped: u64,
    /// Wait for a writer that is behind instead of dropping (a simulation in lockstep, where
    /// waiting costs only simulated time).
    lossless: bool,
}

impl LogFile<Vec<u8>> {
    /// Creates (truncates) `path` and starts its writer, which writes the bytes it is handed.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        Self::create_with(path, b"", |chunk: Vec<u8>, out| out.write_all(&chunk))
    }
}

impl<T: Send + 'static> LogFile<T> {
    /// Creates (truncates) `path`, writes `header`, and starts the writer, which writes each
    /// chunk it is handed with `encode`, in parts as `SDLOG_MAX_SIZE` and `SDLOG_ROTATE` say
    /// ([`crate::records::log_budget::rotation`]).
    pub fn create_with(
        path: &Path,
        header: &[u8],
        encode: impl FnMut(T, &mut dyn Write) -> std::io::Result<()> + Send + 'static,
    ) -> std::io::Result<Self> {
        Self::create_in_parts(path, header, encode, crate::records::log_budget::rotation())
    }

    /// [`LogFile::create_with`], going on in a new part (its own `header` first) once a part
    /// has `rotation.0` bytes (0: never), keeping the newest `rotation.1` parts (0: all).
    pub fn create_in_parts(
        path: &Path,
        header: &[u8],
        mut encode: impl FnMut(T, &mut dyn Write) -> std::io::Result<()> + Send + 'static,
        rotation: (u64, u32),
    ) -> std::io::Result<Self> {
        let mut file = std::fs::File::create(path)?;
        file.write_all(header)?;
        let (tx, rx) = sync_channel::<Option<T>>(QUEUE);
        let mut whole = header.len() as u64;
        let fault = Arc::new(OnceLock::new());
        let stopped = Arc::clone(&fault);
        let first = path.to_owned();
        let mut at = path.to_owned();
        let header = header.to_vec();
        let (rotate_bytes, keep) = rotation;
        let writer = std::thread::Builder::new()
            .name("log-writer".into())
            .spawn(move || -> std::io::Result<()> {
                let mut out = std::io::BufWriter::with_capacity(256 * 1024, file);
                let mut part = 1;
                // Until the owner's end: another producer's sender may outlive it.
                for chunk in rx.iter().map_while(|c| c) {
                    // Past SDLOG_MAX_SIZE, between two chunks: the next part, its own header
                    // first, readable on its own; the oldest beyond SDLOG_ROTATE removed.
                    if rotate_bytes > 0 && whole >= rotate_bytes {
                        part += 1;
                        let next = part_path(&first, part);
                        let started = std::fs::File::create(&next).and_then(|mut f| {
                            f.write_all(&header)?;
                            Ok(f)
                        });
                        match started {
                            Ok(f) => out = std::io::BufWriter::with_capacity(256 * 1024, f),
                            Err(e) => {
                                let _ = stopped.set(e.kind());
                                return Err(e);
                            }
                        }
                        (at, whole) = (next, header.len() as u64);
                        if keep > 0 && part > keep {
                            let _ = std::fs::remove_file(part_path(&first, part - keep));
                        }
                    }
                    // To the kernel with every chunk: nothing is held here that a kill would lose;
                    // not below the free space kept (SDLOG_MIN_FREE), where it stops as on a
                    // full disk, nor into a file whose directory was removed.
                    let written = room_to_write(&at)
                        .and_then(|()| encode(chunk, &mut out))
                        .and_then(|()| out.flush());
                    if let Err(e) = written {
                        // A full disk, say: the file ends with the last chunk written whole (a
                        // row, a message is never cut), and the writer stops.
                        // What the buffer still holds is dropped unwritten (a drop would flush
                        // it after the cut).
                        let (file, _unwritten) = out.into_parts();
                        let _ = file.set_len(whole);
                        let _ = stopped.set(e.kind());
                        return Err(e);
                    }
                    let mut file: &std::fs::File = out.get_ref();
                    whole = file.stream_position()?;
                }
                Ok(())
            })?;
        Ok(Self {
            path: path.to_owned(),
            chunks: Some(tx),
            writer: Some(writer),
            fault,
            dropped: 0,
            lossless: false,
        })
    }

    /// From now on [`LogFile::write`] waits for a writer that is behind rather than dropping:
    /// for producers whose time is simulated (lockstep), where a wait costs no flight.
    pub fn lossless(mut self) -> Self {
        self.lossless = true;
        self
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Hands `chunk` to the writer without waiting (unless [`LogFile::lossless`]). A writer behind by [`QUEUE`] chunks loses
    /// this one (counted, logged); an `Err` means the writer has stopped (a full disk, say: the
    /// cause comes from [`LogFile::finish`]).
    pub fn write(&mut self, chunk: T) -> std::io::Result<()> {
        let Some(tx) = &self.chunks else {
            return Err(std::io::Error::other("log finished"));
        };
        let stopped = || {
            let kind = self.fault.get().copied();
            std::io::Error::new(
                kind.unwrap_or(std::io::ErrorKind::Other),
                format!(
                    "the log writer stopped ({})",
                    kind.map_or("unknown".into(), |k| k.to_string())
                ),
            )
        };
        if self.lossless {
            return tx.send(Some(chunk)).map_err(|_| stopped());
        }
        match tx.try_send(Some(chunk)) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => {
                self.dropped += 1;
                if self.dropped.is_power_of_two() {
                    tracing::warn!(file = %self.path.display(), dropped = self.dropped, "log writer behind: log data dropped");
                }
                Ok(())
            }
            Err(TrySendError::Disconnected(_)) => Err(stopped()),
        }
    }

    /// Another producer's way into the file (the ground-station task's, say), which never
    /// waits; what it hands over after [`LogFile::finish`] is lost.
    pub fn producer(&self) -> Option<LogProducer<T>> {
        self.chunks.clone().map(|chunks| LogProducer { chunks })
    }

    /// Waits for the writer to write everything handed to it; its error, if it met one.
    pub fn finish(&mut self) -> std::io::Result<()> {
        if let Some(tx) = self.chunks.take() {
            // Waits for room: the end must arrive (a stopped writer has hung up: no wait).
            let _ = tx.send(None);
        }
        match self.writer.take().map(JoinHandle::join) {
            None => Ok(()),
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(std::io::Error::other("the log writer panicked")),
        }
    }
}

/// Part `n` of the log file whose first part is `first`: `first` itself, then `NAME.2.ulg` and
/// so on (`SDLOG_MAX_SIZE`).
pub fn part_path(first: &Path, n: u32) -> PathBuf {
    if n <= 1 {
        return first.to_owned();
    }
    let stem = first.file_stem().unwrap_or_default().to_string_lossy();
    let name = match first.extension() {
        Some(ext) => format!("{stem}.{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}.{n}"),
    };
    first.with_file_name(name)
}

/// `Err` when the log at `path` is gone (its directory removed: the writes would go on into a
/// file no one can open, lost without a word), or (as a full disk's) when its disk has less
/// free space than the logs keep ([`crate::records::log_budget::keep_free`]).
fn room_to_write(path: &Path) -> std::io::Result<()> {
    if let Err(e) = std::fs::metadata(path)
        && e.kind() == std::io::ErrorKind::NotFound
    {
        return Err(std::io::Error::new(
            e.kind(),
            format!("{} is gone (its directory removed?)", path.display()),
        ));
    }
    let floor = crate::records::log_budget::kept_free();
    match crate::records::log_budget::free_bytes(path) {
        Some(free) if floor > 0 && free < floor => Err(std::io::Error::new(
            std::io::ErrorKind::StorageFull,
            format!(
                "{} MB free, below the {} MB the logs keep (SDLOG_MIN_FREE)",
                free / 1_000_000,
                floor / 1_000_000
            ),
        )),
        _ => Ok(()),
    }
}

/// A second producer of a [`LogFile`]: it hands chunks over without waiting, and loses one
/// when the writer is behind or finished.
#[derive(Debug)]
pub struct LogProducer<T> {
    chunks: SyncSender<Option<T>>,
}

impl<T> Clone for LogProducer<T> {
    fn clone(&self) -> Self {
        Self {
            chunks: self.chunks.clone(),
        }
    }
}

impl<T> LogProducer<T> {
    /// Hands `chunk` to the writer; false if it was lost.
    pub fn write(&self, chunk: T) -> bool {
        self.chunks.try_send(Some(chunk)).is_ok()
    }
}

impl<T: Send + 'static> Drop for LogFile<T> {
    fn drop(&mut self) {
        if let Err(e) = self.finish() {
            tracing::error!(file = %self.path.display(), "log: {e}");
        }
    }
}

/// The MAVLink telemetry log (`.tlog`, as MAVProxy and QGroundControl write it): every frame
/// the vehicle sent and every message it heard, each after the time it passed (µs since the
/// Unix epoch, 8 bytes big-endian). pymavlink (`mavlogdump.py`, MAVExplorer) and
/// QGroundControl open it.
pub struct Tlog {
    file: LogFile,
    buf: Vec<u8>,
    /// When `buf` was last handed over (µs since the epoch).
    shipped_us: u64,
}

impl Tlog {
    /// Creates the log at `path`.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        Ok(Self {
            file: LogFile::create(path)?,
            buf: Vec::with_capacity(64 * 1024),
            shipped_us: 0,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// Records one frame at `unix_us`.
    pub fn record(&mut self, unix_us: u64, frame: &[u8]) {
        self.buf.extend_from_slice(&unix_us.to_be_bytes());
        self.buf.extend_from_slice(frame);
    }

    /// Hands what is recorded to the writer when [`SHIP_INTERVAL_S`] has passed since it last
    /// did (or the clock stepped back).
    pub fn ship_if_due(&mut self, unix_us: u64) -> std::io::Result<()> {
        let due = self.shipped_us + (SHIP_INTERVAL_S * 1e6) as u64;
        if unix_us >= due || unix_us < self.shipped_us {
            self.shipped_us = unix_us;
            return self.ship();
        }
        Ok(())
    }

    fn ship(&mut self) -> std::io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        let chunk = std::mem::replace(&mut self.buf, Vec::with_capacity(64 * 1024));
        self.file.write(chunk)
    }

    /// Writes the rest and closes the file.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.ship()?;
        self.file.finish()
    }
}

/// Where a run's default logs go: `dir/STEM.tlog`, `.ulg` and `.csv`, STEM the UTC date and time
/// of `unix_s` (`2026-11-23_10-15-02`), `_iN` added for instance N > 0 and `-2`, `-3`, … when
/// a run of the same second already left logs. Creates `dir`.
pub fn run_stem(dir: &Path, unix_s: u64, instance: u16) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let mut stem = utc_stamp(unix_s);
    if instance > 0 {
        stem += &format!("_i{instance}");
    }
    let taken = |s: &str| {
        ["tlog", "csv", "ulg"]
            .iter()
            .any(|ext| dir.join(format!("{s}.{ext}")).exists())
    };
    let mut n = 1;
    let mut name = stem.clone();
    while taken(&name) {
        n += 1;
        name = format!("{stem}-{n}");
    }
    Ok(dir.join(name))
}

/// `YYYY-MM-DD_HH-MM-SS` of a Unix time, UTC (civil-from-days: the proleptic Gregorian
/// calendar in 400-year eras).
fn utc_stamp(unix_s: u64) -> String {
    let days = (unix_s / 86_400) as i64;
    let secs = unix_s % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}_{:02}-{:02}-{:02}",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn stamps_are_utc_calendar_dates() {
        assert_eq!(utc_stamp(0), "1970-01-01_00-00-00");
        // Leap days and century rules: 2000-02-29 exists, 2100-02-29 does not.
        assert_eq!(utc_stamp(951_782_400), "2000-02-29_00-00-00");
        assert_eq!(utc_stamp(4_107_542_399), "2100-02-28_23-59-59");
        assert_eq!(utc_stamp(4_107_542_400), "2100-03-01_00-00-00");
        assert_eq!(utc_stamp(1_795_432_502), "2026-11-23_11-15-02");
    }

    #[test]
    fn a_log_whose_directory_is_removed_stops_and_says_why() {
        let dir = tempfile::tempdir().unwrap();
        let logs = dir.path().join("logs");
        std::fs::create_dir(&logs).unwrap();
        let mut log = LogFile::create(&logs.join("run.tlog")).unwrap().lossless();
        log.write(b"first".to_vec()).unwrap();
        std::fs::remove_dir_all(&logs).unwrap();
        // The writer meets the removal at its next chunk at the latest; until it has, a write
        // is handed over.
        let _ = log.write(b"second".to_vec());
        let e = log.finish().unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::NotFound, "{e}");
        assert!(e.to_string().contains("is gone"), "{e}");
    }

    /// Past the size, a log goes on in a new part with its own header, between two chunks (a
    /// row, a message never split); beyond the parts kept the oldest is removed. Every byte
    /// handed over is in the parts kept, in order.
    #[test]
    fn a_long_log_goes_on_in_parts_and_keeps_the_newest() {
        let dir = tempfile::tempdir().unwrap();
        let first = dir.path().join("2026-11-23_11-15-02.csv");
        let mut log = LogFile::create_in_parts(
            &first,
            b"HEADER\n",
            |chunk: Vec<u8>, out| out.write_all(&chunk),
            (100, 3),
        )
        .unwrap()
        .lossless();
        for i in 0..60 {
            log.write(format!("row {i:03}\n").into_bytes()).unwrap();
        }
        log.finish().unwrap();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        // 7 + 8 × 12 = 103 bytes ≥ 100: parts of 12 rows, the last of the 60 rows in part 5.
        assert_eq!(
            names,
            [
                "2026-11-23_11-15-02.3.csv",
                "2026-11-23_11-15-02.4.csv",
                "2026-11-23_11-15-02.5.csv"
            ]
        );
        let rows: Vec<String> = (3..=5)
            .flat_map(|n| {
                let text = std::fs::read_to_string(part_path(&first, n)).unwrap();
                assert!(text.starts_with("HEADER\n"), "part {n}: {text}");
                text.lines().skip(1).map(str::to_owned).collect::<Vec<_>>()
            })
            .collect();
        let expected: Vec<String> = (24..60).map(|i| format!("row {i:03}")).collect();
        assert_eq!(rows, expected);
    }

    #[test]
    fn a_second_run_in_the_same_second_gets_its_own_names() {
        let dir = std::env::temp_dir().join(format!("autopilot-logs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let first = run_stem(&dir, 1_795_432_502, 0).unwrap();
        assert_eq!(first, dir.join("2026-11-23_11-15-02"));
        std::fs::write(first.with_extension("tlog"), b"").unwrap();
        let second = run_stem(&dir, 1_795_432_502, 0).unwrap();
        assert_eq!(second, dir.join("2026-11-23_11-15-02-2"));
        assert_eq!(
            run_stem(&dir, 1_795_432_502, 3).unwrap(),
            dir.join("2026-11-23_11-15-02_i3")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_tlog_holds_every_frame_after_its_timestamp_in_order() {
        let path = std::env::temp_dir().join(format!("autopilot-{}.tlog", std::process::id()));
        let mut tlog = Tlog::create(&path).unwrap();
        let mut enc = hil::Encoder::with_ids(1, 1);
        let mut frames = Vec::new();
        for i in 0..2000u64 {
            let mut f = Vec::new();
            enc.push(
                &mut f,
                &mavlink::dialects::common::MavMessage::SYSTEM_TIME(
                    mavlink::dialects::common::SYSTEM_TIME_DATA {
                        time_unix_usec: i,
                        time_boot_ms: i as u32,
                    },
                ),
            );
            let t = 1_795_432_502_000_000 + i * 1000;
            tlog.record(t, &f);
            tlog.ship_if_due(t).unwrap();
            frames.push((t, f));
        }
        tlog.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let mut at = 0;
        for (t, f) in &frames {
            assert_eq!(bytes[at..at + 8], t.to_be_bytes());
            assert_eq!(&bytes[at + 8..at + 8 + f.len()], f.as_slice());
            at += 8 + f.len();
        }
        assert_eq!(at, bytes.len());
    }
}
