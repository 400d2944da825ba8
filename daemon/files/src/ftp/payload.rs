//! The payload of `FILE_TRANSFER_PROTOCOL`: a 12-byte header (sequence number, session,
//! opcode, data size, the request's opcode in a reply, burst complete, offset) and up to 239
//! bytes of data, little-endian, as the MAVLink FTP microservice defines it.

/// Bytes of data a payload carries at most.
pub const MAX_DATA: usize = 239;

/// The payload's bytes in `FILE_TRANSFER_PROTOCOL`.
pub const PAYLOAD_LEN: usize = 251;

/// What a request asks, or a reply answers (`MAV_FTP_OPCODE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Opcode {
    /// Nothing: acknowledged.
    None = 0,
    /// Closes the session's file.
    TerminateSession = 1,
    /// Closes every session.
    ResetSessions = 2,
    /// Lists a directory from an entry index.
    ListDirectory = 3,
    /// Opens a file to read.
    OpenFileRO = 4,
    /// Reads from the open file.
    ReadFile = 5,
    /// Creates (truncates) a file and opens it to write.
    CreateFile = 6,
    /// Writes to the open file.
    WriteFile = 7,
    /// Removes a file.
    RemoveFile = 8,
    /// Makes a directory.
    CreateDirectory = 9,
    /// Removes an empty directory.
    RemoveDirectory = 10,
    /// Opens a file to write, not truncated.
    OpenFileWO = 11,
    /// Cuts a file to a length.
    TruncateFile = 12,
    /// Renames a file or directory.
    Rename = 13,
    /// A file's CRC-32.
    CalcFileCRC32 = 14,
    /// Streams the open file from an offset.
    BurstReadFile = 15,
    /// Lists a directory with each file's modification time.
    ListDirectoryWithTime = 16,
    /// A reply: done.
    Ack = 128,
    /// A reply: refused, with an [`FtpError`] in the data.
    Nak = 129,
}

impl Opcode {
    /// The opcode of a byte, if it is one.
    pub fn from_u8(b: u8) -> Option<Self> {
        use Opcode::*;
        Some(match b {
            0 => None,
            1 => TerminateSession,
            2 => ResetSessions,
            3 => ListDirectory,
            4 => OpenFileRO,
            5 => ReadFile,
            6 => CreateFile,
            7 => WriteFile,
            8 => RemoveFile,
            9 => CreateDirectory,
            10 => RemoveDirectory,
            11 => OpenFileWO,
            12 => TruncateFile,
            13 => Rename,
            14 => CalcFileCRC32,
            15 => BurstReadFile,
            16 => ListDirectoryWithTime,
            128 => Ack,
            129 => Nak,
            _ => return Option::None,
        })
    }
}

/// `ENOTDIR`, `EISDIR`, `EINVAL`: Linux's numbers, which clients print.
pub const ENOTDIR: u8 = 20;
/// See [`ENOTDIR`].
pub const EISDIR: u8 = 21;
/// See [`ENOTDIR`].
pub const EINVAL: u8 = 22;
/// `EFBIG`: a write or truncation past [`super::MAX_FILE_BYTES`].
pub const EFBIG: u8 = 27;

/// Why a request was refused (`MAV_FTP_ERR`), the first byte of a NAK's data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FtpError {
    /// Failed, no more said.
    #[error("failed")]
    Fail,
    /// Failed in the file system: the `errno` follows.
    #[error("failed: errno {0}")]
    FailErrno(u8),
    /// The data size is wrong for the request.
    #[error("invalid data size")]
    InvalidDataSize,
    /// No such session, or it has no file open.
    #[error("invalid session")]
    InvalidSession,
    /// Every session is in use.
    #[error("no session available")]
    NoSessionsAvailable,
    /// Read or listed past the end.
    #[error("end of file")]
    Eof,
    /// An opcode this server does not know.
    #[error("unknown command")]
    UnknownCommand,
    /// The file or directory exists already.
    #[error("file exists")]
    FileExists,
    /// Not allowed: outside the root, or writes are off.
    #[error("file protected")]
    FileProtected,
    /// No such file or directory.
    #[error("file not found")]
    FileNotFound,
}

impl FtpError {
    /// The NAK's data: the error code, and the `errno` for [`FtpError::FailErrno`].
    pub fn data(self) -> Vec<u8> {
        match self {
            Self::Fail => vec![1],
            Self::FailErrno(errno) => vec![2, errno],
            Self::InvalidDataSize => vec![3],
            Self::InvalidSession => vec![4],
            Self::NoSessionsAvailable => vec![5],
            Self::Eof => vec![6],
            Self::UnknownCommand => vec![7],
            Self::FileExists => vec![8],
            Self::FileProtected => vec![9],
            Self::FileNotFound => vec![10],
        }
    }

    /// The error of a file-system failure: PX4's mapping (not found, exists), else its errno.
    pub fn of_io(e: &std::io::Error) -> Self {
        match e.kind() {
            std::io::ErrorKind::NotFound => Self::FileNotFound,
            std::io::ErrorKind::AlreadyExists => Self::FileExists,
            std::io::ErrorKind::PermissionDenied => Self::FileProtected,
            _ => match e.raw_os_error() {
                Some(errno) => Self::FailErrno(u8::try_from(errno).unwrap_or(u8::MAX)),
                None => Self::Fail,
            },
        }
    }
}

/// One FTP payload.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FtpPayload {
    /// Sequence number: a reply carries its request's plus one.
    pub seq: u16,
    /// Session id.
    pub session: u8,
    /// The opcode (a request's, or ACK / NAK).
    pub opcode: u8,
    /// In a reply, the opcode of the request answered.
    pub req_opcode: u8,
    /// In a burst, the last packet of this burst.
    pub burst_complete: bool,
    /// Offset in the file, or entry index in a listing.
    pub offset: u32,
    /// The data (at most [`MAX_DATA`] bytes). In a read request, `size` is how much is asked
    /// and no data comes: see [`FtpPayload::size`].
    pub data: Vec<u8>,
    /// The header's size field as it came (for a read: the bytes wanted).
    pub size: u8,
}

impl FtpPayload {
    /// Decodes the 251 bytes of a `FILE_TRANSFER_PROTOCOL`.
    pub fn decode(p: &[u8; PAYLOAD_LEN]) -> Self {
        let size = p[4];
        let n = usize::from(size).min(MAX_DATA);
        Self {
            seq: u16::from_le_bytes([p[0], p[1]]),
            session: p[2],
            opcode: p[3],
            size,
            req_opcode: p[5],
            burst_complete: p[6] != 0,
            offset: u32::from_le_bytes([p[8], p[9], p[10], p[11]]),
            data: p[12..12 + n].to_vec(),
        }
    }

    /// Encodes it (its data cut to [`MAX_DATA`]; the size field is the data's length).
    pub fn encode(&self) -> [u8; PAYLOAD_LEN] {
        let mut p = [0u8; PAYLOAD_LEN];
        let n = self.data.len().min(MAX_DATA);
        p[0..2].copy_from_slice(&self.seq.to_le_bytes());
        p[2] = self.session;
        p[3] = self.opcode;
        p[4] = n as u8;
        p[5] = self.req_opcode;
        p[6] = self.burst_complete as u8;
        p[8..12].copy_from_slice(&self.offset.to_le_bytes());
        p[12..12 + n].copy_from_slice(&self.data[..n]);
        p
    }

    /// The data as a path or name: up to the first NUL (a name without one ends with the data).
    pub fn text(&self) -> &[u8] {
        let end = self
            .data
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(self.data.len());
        &self.data[..end]
    }

    /// The reply to this request: its sequence number plus one, its session and offset, ACK
    /// with `data`.
    pub fn ack(&self, data: Vec<u8>) -> Self {
        Self {
            seq: self.seq.wrapping_add(1),
            session: self.session,
            opcode: Opcode::Ack as u8,
            req_opcode: self.opcode,
            burst_complete: false,
            offset: self.offset,
            size: data.len().min(MAX_DATA) as u8,
            data,
        }
    }

    /// The refusal of this request with `error`.
    pub fn nak(&self, error: FtpError) -> Self {
        Self {
            opcode: Opcode::Nak as u8,
            ..self.ack(error.data())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_payload_round_trips_and_a_reply_follows_its_request() {
        let req = FtpPayload {
            seq: 65535,
            session: 3,
            opcode: Opcode::ReadFile as u8,
            offset: 1000,
            size: 80,
            ..Default::default()
        };
        let bytes = req.encode();
        assert_eq!(bytes[0..4], [0xff, 0xff, 3, 5]);
        assert_eq!(FtpPayload::decode(&bytes).offset, 1000);
        let nak = req.nak(FtpError::FailErrno(28));
        assert_eq!(
            (nak.seq, nak.session, nak.opcode, nak.req_opcode),
            (0, 3, 129, 5)
        );
        assert_eq!((nak.size, nak.data.as_slice()), (2, &[2u8, 28][..]));
        // A size beyond the data field is cut to it.
        let mut raw = [0u8; PAYLOAD_LEN];
        raw[4] = 255;
        assert_eq!(FtpPayload::decode(&raw).data.len(), MAX_DATA);
    }
}
