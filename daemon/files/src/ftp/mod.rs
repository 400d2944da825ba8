//! The MAVLink FTP server (`FILE_TRANSFER_PROTOCOL`), as PX4's `MavlinkFTP` answers: every
//! opcode of the microservice, one session at a time closed after 10 s unused (its id the one
//! the opening request carried, as ArduPilot takes it: pymavlink numbers its sessions and
//! writes before the open is answered; MAVSDK always uses 0), a reply's
//! sequence number its request's plus one, a repeated request answered with the same small
//! reply without acting twice, burst reads streamed by [`FtpServer::poll`] at the pace the
//! host allows, the spec's error codes.
//!
//! Files are read and written here, through `std::fs`, under an [`FtpRoot`].

pub mod listing;
pub mod paths;
pub mod payload;
pub mod virtual_dir;

use paths::FtpRoot;
use payload::{EFBIG, EINVAL, EISDIR, ENOTDIR, FtpError, FtpPayload, MAX_DATA, Opcode};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use virtual_dir::{OpenFile, VirtualDir, VirtualPlace};

/// A session unused this long is closed (s), as PX4 closes it.
pub const SESSION_IDLE_S: f64 = 10.0;

/// Bytes a burst sends before it pauses (`burst_complete`) for the client to ask for the
/// next, as PX4 pauses: a client that has asked nothing for a few seconds takes the
/// transfer for stalled (pymavlink's `mavftp` after 3.7 s).
pub const BURST_BYTES: u64 = 35_000;

/// Who asked: the link it came on and the sender's ids, which the reply is addressed to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Requester {
    /// The endpoint it came on.
    pub link: u8,
    /// The sender's system id.
    pub system: u8,
    /// The sender's component id.
    pub component: u8,
}

/// The open file of the session.
#[derive(Debug)]
struct Session {
    /// Its id.
    id: u8,
    file: OpenFile,
    /// Its size when opened (reads end there).
    size: u64,
    writable: bool,
    last_used_s: f64,
}

/// A burst read under way.
#[derive(Debug, Clone, Copy)]
struct Burst {
    to: Requester,
    /// The next packet's sequence number and offset.
    seq: u16,
    offset: u64,
    /// Bytes sent since the request.
    sent: u64,
}

/// A `CalcFileCRC32` being computed: the file is read [`CRC_BYTES_PER_POLL`] at a time.
#[derive(Debug)]
struct PendingCrc {
    to: Requester,
    req: FtpPayload,
    file: File,
    hasher: crc32fast::Hasher,
}

/// The largest file a ground station may make (a write or truncation beyond is refused with
/// `EFBIG`): uploads to a vehicle are plans and settings, not gigabytes.
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// Bytes of a file a poll reads for a CRC (1 MiB: a poll every 10 ms reads 100 MiB/s).
const CRC_BYTES_PER_POLL: usize = 1 << 20;

/// The FTP server.
#[derive(Debug)]
pub struct FtpServer {
    root: FtpRoot,
    /// Files held in memory, read-only, at `/<name>/`.
    virtual_dir: VirtualDir,
    session: Option<Session>,
    burst: Option<Burst>,
    /// A CRC under way.
    crc: Option<PendingCrc>,
    /// The last small reply (≤ 4 bytes of data) and the request it answered: a request
    /// repeated (its reply lost) gets it again rather than acting twice.
    last: Option<(Requester, u16, FtpPayload)>,
}

/// Replies to send, each to its requester.
pub type Replies = Vec<(Requester, FtpPayload)>;

impl FtpServer {
    /// A server of `root`.
    pub fn new(root: FtpRoot, virtual_dir: VirtualDir) -> Self {
        Self {
            root,
            virtual_dir,
            session: None,
            burst: None,
            crc: None,
            last: None,
        }
    }

    /// Answers one request at time `now_s` (any monotonic clock, s).
    pub fn handle(&mut self, from: Requester, req: &FtpPayload, now_s: f64, out: &mut Replies) {
        if let Some((to, seq, reply)) = &self.last
            && *to == from
            && *seq == req.seq
            && reply.req_opcode == req.opcode
        {
            out.push((from, reply.clone()));
            return;
        }
        let reply = match self.act(from, req, now_s) {
            Ok(Some(reply)) => reply,
            Ok(None) => {
                self.last = None; // a burst answers from poll()
                return;
            }
            Err(e) => req.nak(e),
        };
        self.last = (reply.data.len() <= 4).then(|| (from, req.seq, reply.clone()));
        out.push((from, reply));
    }

    /// Sends up to `budget` packets of a burst under way, and closes a session unused for
    /// [`SESSION_IDLE_S`].
    pub fn poll(&mut self, now_s: f64, budget: usize, out: &mut Replies) {
        if self
            .session
            .as_ref()
            .is_some_and(|s| now_s - s.last_used_s > SESSION_IDLE_S)
        {
            tracing::debug!("FTP session closed after {SESSION_IDLE_S} s unused");
            self.close();
        }
        self.crc_step(out);
        for _ in 0..budget {
            let (Some(b), Some(s)) = (self.burst.as_mut(), self.session.as_mut()) else {
                break;
            };
            // Offsets are 32 bits: a file is served up to 4 GiB.
            let size = s.size.min(u64::from(u32::MAX));
            s.last_used_s = now_s;
            let mut packet = FtpPayload {
                seq: b.seq,
                session: s.id,
                opcode: Opcode::Ack as u8,
                req_opcode: Opcode::BurstReadFile as u8,
                offset: b.offset as u32,
                ..FtpPayload::default()
            };
            b.seq = b.seq.wrapping_add(1);
            match s.file.read_at(b.offset, size, MAX_DATA) {
                Ok(data) if !data.is_empty() => {
                    b.offset += data.len() as u64;
                    b.sent += data.len() as u64;
                    packet.data = data;
                    packet.burst_complete = b.sent >= BURST_BYTES;
                    out.push((b.to, packet));
                    if b.sent >= BURST_BYTES {
                        self.burst = None;
                    }
                }
                Ok(_) => {
                    packet.opcode = Opcode::Nak as u8;
                    packet.data = FtpError::Eof.data();
                    out.push((b.to, packet));
                    self.burst = None;
                }
                Err(e) => {
                    packet.opcode = Opcode::Nak as u8;
                    packet.data = e.data();
                    out.push((b.to, packet));
                    self.burst = None;
                }
            }
        }
    }

    /// Reads the next slice of a CRC under way; its answer once the file is read.
    fn crc_step(&mut self, out: &mut Replies) {
        let Some(c) = self.crc.as_mut() else {
            return;
        };
        let mut buf = vec![0u8; 64 * 1024];
        let mut read = 0;
        let answer = loop {
            match c.file.read(&mut buf) {
                Ok(0) => break Some(Ok(c.hasher.clone().finalize() ^ u32::MAX)),
                Ok(n) => {
                    c.hasher.update(&buf[..n]);
                    read += n;
                    if read >= CRC_BYTES_PER_POLL {
                        break None;
                    }
                }
                Err(e) => break Some(Err(FtpError::of_io(&e))),
            }
        };
        if let Some(answer) = answer {
            let reply = match answer {
                Ok(crc) => c.req.ack(crc.to_le_bytes().to_vec()),
                Err(e) => c.req.nak(e),
            };
            out.push((c.to, reply));
            self.crc = None;
        }
    }

    fn close(&mut self) {
        self.session = None;
        self.burst = None;
        self.crc = None;
        self.last = None;
    }

    /// The open session a request names, marked used.
    fn session(&mut self, req: &FtpPayload, now_s: f64) -> Result<&mut Session, FtpError> {
        match self.session.as_mut() {
            Some(s) if req.session == s.id => {
                s.last_used_s = now_s;
                Ok(s)
            }
            _ => Err(FtpError::InvalidSession),
        }
    }

    /// Opens a session on `file`; the ACK carries `size_data` (a size, u32).
    fn open(
        &mut self,
        req: &FtpPayload,
        file: OpenFile,
        writable: bool,
        now_s: f64,
    ) -> Result<Option<FtpPayload>, FtpError> {
        if self.session.is_some() {
            return Err(FtpError::NoSessionsAvailable);
        }
        let size = match &file {
            OpenFile::Disk(f) => f.metadata().map_err(|e| FtpError::of_io(&e))?.len(),
            OpenFile::Memory(bytes) => bytes.len() as u64,
        };
        self.session = Some(Session {
            id: req.session,
            file,
            size,
            writable,
            last_used_s: now_s,
        });
        let size = u32::try_from(size).unwrap_or(u32::MAX);
        Ok(Some(req.ack(size.to_le_bytes().to_vec())))
    }

    /// The answer to a request on the virtual directory, if it names it.
    fn act_virtual(
        &mut self,
        op: Opcode,
        req: &FtpPayload,
        now_s: f64,
    ) -> Option<Result<Option<FtpPayload>, FtpError>> {
        use Opcode::*;
        let names_a_path = !matches!(
            op,
            None | TerminateSession
                | ResetSessions
                | ReadFile
                | WriteFile
                | BurstReadFile
                | Ack
                | Nak
        );
        let reads = matches!(
            op,
            ListDirectory | ListDirectoryWithTime | OpenFileRO | CalcFileCRC32
        );
        if !names_a_path || self.virtual_dir.files.is_empty() {
            return Option::None;
        }
        let place = match self.virtual_dir.find(req.text())? {
            _ if !reads => return Some(Err(FtpError::FileProtected)), // read-only
            Err(e) => return Some(Err(e)),
            Ok(place) => place,
        };
        Some(match (op, place) {
            (ListDirectory | ListDirectoryWithTime, VirtualPlace::Dir) => self
                .virtual_dir
                .entries(req.offset)
                .map(|data| Some(req.ack(data))),
            (OpenFileRO, VirtualPlace::File(bytes)) => {
                self.open(req, OpenFile::Memory(bytes), false, now_s)
            }
            (CalcFileCRC32, VirtualPlace::File(bytes)) => {
                Ok(Some(req.ack(crc32_of(&bytes).to_le_bytes().to_vec())))
            }
            (ListDirectory | ListDirectoryWithTime, VirtualPlace::File(_)) => {
                Err(FtpError::FailErrno(ENOTDIR))
            }
            (_, VirtualPlace::Dir) => Err(FtpError::FailErrno(EISDIR)),
            (_, VirtualPlace::File(_)) => Err(FtpError::FileProtected), // not reached: reads only
        })
    }

    fn act(
        &mut self,
        from: Requester,
        req: &FtpPayload,
        now_s: f64,
    ) -> Result<Option<FtpPayload>, FtpError> {
        if usize::from(req.size) > MAX_DATA {
            return Err(FtpError::InvalidDataSize);
        }
        let op = Opcode::from_u8(req.opcode).ok_or(FtpError::UnknownCommand)?;
        if let Some(answer) = self.act_virtual(op, req, now_s) {
            return answer;
        }
        let done = |data: Vec<u8>| Ok(Some(req.ack(data)));
        let io = |e: std::io::Error| FtpError::of_io(&e);
        match op {
            Opcode::None => done(Vec::new()),
            Opcode::TerminateSession => {
                self.session(req, now_s)?;
                self.close();
                done(Vec::new())
            }
            Opcode::ResetSessions => {
                self.close();
                done(Vec::new())
            }
            Opcode::ListDirectory | Opcode::ListDirectoryWithTime => {
                done(self.list(req, op == Opcode::ListDirectoryWithTime)?)
            }
            Opcode::OpenFileRO => {
                let path = self.root.resolve(req.text())?;
                if path.is_dir() {
                    return Err(FtpError::FailErrno(EISDIR));
                }
                let file = File::open(&path).map_err(io)?;
                self.open(req, OpenFile::Disk(file), false, now_s)
            }
            Opcode::CreateFile | Opcode::OpenFileWO => {
                if self.session.is_some() {
                    return Err(FtpError::NoSessionsAvailable);
                }
                let path = self.root.resolve_for_write(req.text())?;
                let file = std::fs::OpenOptions::new()
                    .write(true)
                    .create(true)
                    .truncate(op == Opcode::CreateFile)
                    .open(&path)
                    .map_err(io)?;
                self.open(req, OpenFile::Disk(file), true, now_s)
            }
            Opcode::ReadFile => {
                let s = self.session(req, now_s)?;
                let data = s.file.read_at(req.offset.into(), s.size, req.size.into())?;
                if data.is_empty() {
                    return Err(FtpError::Eof);
                }
                done(data)
            }
            Opcode::BurstReadFile => {
                let s = self.session(req, now_s)?;
                if u64::from(req.offset) >= s.size {
                    return Err(FtpError::Eof);
                }
                self.burst = Some(Burst {
                    to: from,
                    seq: req.seq.wrapping_add(1),
                    offset: req.offset.into(),
                    sent: 0,
                });
                Ok(None)
            }
            Opcode::WriteFile => done(self.write_file(req, now_s)?),
            Opcode::RemoveFile
            | Opcode::CreateDirectory
            | Opcode::RemoveDirectory
            | Opcode::TruncateFile
            | Opcode::Rename => {
                self.change_tree(op, req)?;
                done(Vec::new())
            }
            Opcode::CalcFileCRC32 => {
                // Computed a slice per poll: a large file never holds up the links.
                let path = self.root.resolve(req.text())?;
                let file = File::open(&path).map_err(io)?;
                self.crc = Some(PendingCrc {
                    to: from,
                    req: req.clone(),
                    file,
                    hasher: crc32fast::Hasher::new_with_initial(u32::MAX),
                });
                Ok(None)
            }
            Opcode::Ack | Opcode::Nak => Err(FtpError::UnknownCommand),
        }
    }

    /// `ListDirectory`: the entries of the requested folder from `req.offset`, with their
    /// times if asked; the root lists the log folder and the virtual folder too.
    fn list(&self, req: &FtpPayload, with_time: bool) -> Result<Vec<u8>, FtpError> {
        let path = self.root.resolve(req.text())?;
        let mut extra = Vec::new();
        if self.root.is_root(&path) {
            if self.root.has_logs() {
                extra.push(paths::MAV_LOG);
            }
            if !self.virtual_dir.files.is_empty() {
                extra.push(self.virtual_dir.name.as_str());
            }
        }
        listing::entries(&path, req.offset, with_time, &extra)
    }

    /// `WriteFile` into the session's file: returns the bytes written, as a little-endian
    /// count.
    fn write_file(&mut self, req: &FtpPayload, now_s: f64) -> Result<Vec<u8>, FtpError> {
        let s = self.session(req, now_s)?;
        if !s.writable {
            return Err(FtpError::FileProtected);
        }
        if u64::from(req.offset) + req.data.len() as u64 > MAX_FILE_BYTES {
            return Err(FtpError::FailErrno(EFBIG));
        }
        let OpenFile::Disk(file) = &mut s.file else {
            return Err(FtpError::FileProtected);
        };
        file.seek(SeekFrom::Start(req.offset.into()))
            .and_then(|_| file.write_all(&req.data))
            .map_err(|e| FtpError::of_io(&e))?;
        Ok((req.data.len() as u32).to_le_bytes().to_vec())
    }

    /// What changes the tree: removing a file or folder, making a folder, truncating a file,
    /// renaming.
    fn change_tree(&self, op: Opcode, req: &FtpPayload) -> Result<(), FtpError> {
        let io = |e: std::io::Error| FtpError::of_io(&e);
        match op {
            Opcode::RemoveFile => {
                let path = self.root.resolve_for_write(req.text())?;
                if path.is_dir() {
                    return Err(FtpError::FailErrno(EISDIR));
                }
                std::fs::remove_file(&path).map_err(io)?;
                Ok(())
            }
            Opcode::CreateDirectory => {
                let path = self.root.resolve_for_write(req.text())?;
                std::fs::create_dir(&path).map_err(io)?;
                Ok(())
            }
            Opcode::RemoveDirectory => {
                let path = self.root.resolve_for_write(req.text())?;
                std::fs::remove_dir(&path).map_err(io)?;
                Ok(())
            }
            Opcode::TruncateFile => {
                if u64::from(req.offset) > MAX_FILE_BYTES {
                    return Err(FtpError::FailErrno(EFBIG));
                }
                let path = self.root.resolve_for_write(req.text())?;
                let file = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&path)
                    .map_err(io)?;
                file.set_len(req.offset.into()).map_err(io)?;
                Ok(())
            }
            Opcode::Rename => {
                let (old, new) = rename_paths(&req.data).ok_or(FtpError::FailErrno(EINVAL))?;
                let old = self.root.resolve_for_write(old)?;
                let new = self.root.resolve_for_write(new)?;
                std::fs::rename(&old, &new).map_err(io)?;
                Ok(())
            }
            _ => Err(FtpError::UnknownCommand),
        }
    }
}

/// Rename's two paths: `old\0new` (a trailing NUL or not).
fn rename_paths(data: &[u8]) -> Option<(&[u8], &[u8])> {
    let nul = data.iter().position(|&b| b == 0)?;
    let (old, rest) = (&data[..nul], &data[nul + 1..]);
    let new = &rest[..rest.iter().position(|&b| b == 0).unwrap_or(rest.len())];
    (!old.is_empty() && !new.is_empty()).then_some((old, new))
}

/// A CRC-32 as MAVLink FTP computes it: reflected, polynomial 0xEDB88320, starting from 0
/// and without the final inversion (zlib's CRC-32 seeded with !0, inverted).
pub fn crc32_of(bytes: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new_with_initial(u32::MAX);
    hasher.update(bytes);
    hasher.finalize() ^ u32::MAX
}

#[cfg(test)]
mod tests;
