//! Every opcode against a scratch directory, as PX4's server answers them.

use super::payload::{FtpError, FtpPayload, Opcode};
use super::*;
use std::path::PathBuf;

const ME: Requester = Requester {
    link: 0,
    system: 255,
    component: 190,
};

struct Fixture {
    dir: PathBuf,
    server: FtpServer,
    seq: u16,
}

impl Fixture {
    fn new(name: &str, writable: bool) -> Self {
        let dir = std::env::temp_dir().join(format!("ftp-srv-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("root")).expect("root");
        std::fs::create_dir_all(dir.join("logs")).expect("logs");
        let root = FtpRoot::new(&dir.join("root"), Some(&dir.join("logs")), writable);
        let metadata = VirtualDir {
            name: "@META".into(),
            files: vec![("general.json".into(), b"{\"version\": 1}".as_slice().into())],
        };
        Self {
            server: FtpServer::new(root.expect("root"), metadata),
            dir,
            seq: 0,
        }
    }

    /// One request's replies.
    fn ask(&mut self, op: Opcode, data: &[u8], offset: u32, size: Option<u8>) -> Replies {
        self.seq = self.seq.wrapping_add(2);
        let req = FtpPayload {
            seq: self.seq,
            opcode: op as u8,
            offset,
            size: size.unwrap_or(data.len() as u8),
            data: data.to_vec(),
            ..Default::default()
        };
        let mut out = Vec::new();
        self.server.handle(ME, &req, 0.0, &mut out);
        out
    }

    /// One request's single reply: its data if ACKed, its error if not.
    fn one(&mut self, op: Opcode, data: &[u8], offset: u32) -> Result<Vec<u8>, FtpError> {
        self.one_sized(op, data, offset, None)
    }

    fn one_sized(
        &mut self,
        op: Opcode,
        data: &[u8],
        offset: u32,
        size: Option<u8>,
    ) -> Result<Vec<u8>, FtpError> {
        let out = self.ask(op, data, offset, size);
        assert_eq!(out.len(), 1, "{op:?}: {out:?}");
        let (to, r) = &out[0];
        assert_eq!((*to, r.seq, r.req_opcode), (ME, self.seq + 1, op as u8));
        match Opcode::from_u8(r.opcode) {
            Some(Opcode::Ack) => Ok(r.data.clone()),
            _ => Err(error_of(&r.data)),
        }
    }
}

impl Drop for Fixture {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn error_of(data: &[u8]) -> FtpError {
    match data {
        [1] => FtpError::Fail,
        [2, e] => FtpError::FailErrno(*e),
        [3] => FtpError::InvalidDataSize,
        [4] => FtpError::InvalidSession,
        [5] => FtpError::NoSessionsAvailable,
        [6] => FtpError::Eof,
        [7] => FtpError::UnknownCommand,
        [8] => FtpError::FileExists,
        [9] => FtpError::FileProtected,
        [10] => FtpError::FileNotFound,
        other => panic!("not an error: {other:?}"),
    }
}

#[test]
fn crc32_is_mavlinks_variant() {
    assert_eq!(crc32_of(b"123456789"), 0x2DFD_2D88);
}

#[test]
fn write_then_read_back_list_rename_crc_and_remove() {
    let mut f = Fixture::new("cycle", true);
    use Opcode::*;
    assert_eq!(f.one(CreateDirectory, b"/data", 0), Ok(vec![]));
    assert_eq!(
        f.one(CreateDirectory, b"/data", 0),
        Err(FtpError::FileExists)
    );
    assert_eq!(f.one(CreateFile, b"/data/a.bin\0", 0), Ok(vec![0; 4]));
    // One session: a second open is refused until the first ends.
    assert_eq!(
        f.one(OpenFileRO, b"/data/a.bin", 0),
        Err(FtpError::NoSessionsAvailable)
    );
    let bytes: Vec<u8> = (0..=255u8).cycle().take(1000).collect();
    for (k, chunk) in bytes.chunks(239).enumerate() {
        let written = f.one(WriteFile, chunk, (k * 239) as u32);
        assert_eq!(written, Ok((chunk.len() as u32).to_le_bytes().to_vec()));
    }
    assert_eq!(f.one(TerminateSession, b"", 0), Ok(vec![]));
    assert_eq!(
        f.one(TerminateSession, b"", 0),
        Err(FtpError::InvalidSession)
    );
    assert_eq!(
        f.one(OpenFileRO, b"data/a.bin", 0),
        Ok(1000u32.to_le_bytes().to_vec())
    );
    assert_eq!(
        f.one_sized(ReadFile, b"", 990, Some(80)),
        Ok(bytes[990..].to_vec())
    );
    assert_eq!(
        f.one_sized(ReadFile, b"", 100, Some(7)),
        Ok(bytes[100..107].to_vec())
    );
    assert_eq!(
        f.one_sized(ReadFile, b"", 1000, Some(80)),
        Err(FtpError::Eof)
    );
    // A burst streams the rest from poll(), then says EOF.
    assert!(f.ask(BurstReadFile, b"", 500, Some(239)).is_empty());
    let mut out = Vec::new();
    f.server.poll(0.0, 100, &mut out);
    let data: Vec<u8> = out
        .iter()
        .filter(|(_, p)| p.opcode == Ack as u8)
        .flat_map(|(_, p)| p.data.clone())
        .collect();
    assert_eq!(data, bytes[500..]);
    let last = &out.last().expect("packets").1;
    assert_eq!(
        (last.opcode, last.data.as_slice(), last.offset),
        (Nak as u8, &[6u8][..], 1000)
    );
    let seqs: Vec<u16> = out.iter().map(|(_, p)| p.seq).collect();
    assert_eq!(
        seqs,
        (f.seq + 1..f.seq + 1 + out.len() as u16).collect::<Vec<_>>()
    );
    assert_eq!(f.one(ResetSessions, b"", 0), Ok(vec![]));
    // A CRC is computed in poll()s, then answered.
    assert!(
        f.ask(CalcFileCRC32, b"/data/a.bin", 0, Option::None)
            .is_empty()
    );
    let mut out = Vec::new();
    f.server.poll(0.0, 0, &mut out);
    let want = crc32_of(&bytes).to_le_bytes().to_vec();
    assert_eq!((out[0].1.seq, &out[0].1.data), (f.seq + 1, &want));
    assert_eq!(f.one(Rename, b"/data/a.bin\0/data/b.bin", 0), Ok(vec![]));
    assert_eq!(
        f.one(Rename, b"/data/b.bin", 0),
        Err(FtpError::FailErrno(22))
    );
    let listing = f.one(ListDirectory, b"/data", 0).expect("listing");
    assert_eq!(listing, b"Fb.bin\t1000\0");
    assert_eq!(f.one(ListDirectory, b"/data", 1), Err(FtpError::Eof));
    assert_eq!(f.one(TruncateFile, b"/data/b.bin", 10), Ok(vec![]));
    assert_eq!(
        std::fs::metadata(f.dir.join("root/data/b.bin"))
            .map(|m| m.len())
            .ok(),
        Some(10)
    );
    assert_eq!(
        f.one(RemoveDirectory, b"/data", 0)
            .map_err(|e| matches!(e, FtpError::FailErrno(_))),
        Err(true)
    );
    assert_eq!(f.one(RemoveFile, b"/data/b.bin", 0), Ok(vec![]));
    assert_eq!(
        f.one(RemoveFile, b"/data/b.bin", 0),
        Err(FtpError::FileNotFound)
    );
    assert_eq!(f.one(RemoveDirectory, b"/data", 0), Ok(vec![]));
    // The root lists the virtual directories; an empty listing is the end.
    assert_eq!(
        f.one(ListDirectory, b"/", 0),
        Ok(b"D@MAV_LOG\0D@META\0".to_vec())
    );
    assert_eq!(f.one(ListDirectory, b"@MAV_LOG", 0), Err(FtpError::Eof));
}

#[test]
fn hostile_requests_get_the_specs_errors() {
    let mut f = Fixture::new("hostile", false);
    use Opcode::*;
    std::fs::write(f.dir.join("logs/x.ulg"), b"ulog").expect("log");
    assert_eq!(
        f.one(OpenFileRO, b"../logs/x.ulg", 0),
        Err(FtpError::FileProtected)
    );
    assert_eq!(
        f.one(OpenFileRO, b"/nothing", 0),
        Err(FtpError::FileNotFound)
    );
    assert_eq!(f.one(ReadFile, b"", 0), Err(FtpError::InvalidSession));
    assert_eq!(f.one(BurstReadFile, b"", 0), Err(FtpError::InvalidSession));
    assert_eq!(f.one(CreateFile, b"a", 0), Err(FtpError::FileProtected));
    assert_eq!(
        f.one(RemoveFile, b"@MAV_LOG/x.ulg", 0),
        Err(FtpError::FileProtected)
    );
    assert_eq!(
        f.one_sized(OpenFileRO, b"x", 0, Some(250)),
        Err(FtpError::InvalidDataSize)
    );
    assert_eq!(
        f.one(ListDirectoryWithTime, b"/@MAV_LOG", 0)
            .map(|d| d.starts_with(b"Fx.ulg\t4\t")),
        Ok(true)
    );
    // A name without its terminator reads to the end of the data.
    assert_eq!(
        f.one(OpenFileRO, b"@MAV_LOG/x.ulg", 0),
        Ok(4u32.to_le_bytes().to_vec())
    );
    // Another session id, an offset past the end.
    let out = f.ask(ReadFile, b"", 0, Some(4));
    assert_eq!(out[0].1.data, b"ulog");
    f.seq = f.seq.wrapping_add(2);
    let mut out = Vec::new();
    let bad = FtpPayload {
        seq: f.seq,
        session: 7,
        opcode: ReadFile as u8,
        size: 4,
        ..Default::default()
    };
    f.server.handle(ME, &bad, 0.0, &mut out);
    assert_eq!(error_of(&out[0].1.data), FtpError::InvalidSession);
    assert_eq!(
        f.one_sized(ReadFile, b"", u32::MAX, Some(239)),
        Err(FtpError::Eof)
    );
    assert_eq!(f.one(Opcode::Ack, b"", 0), Err(FtpError::UnknownCommand));
    // An unknown opcode byte.
    f.seq = f.seq.wrapping_add(2);
    let mut out = Vec::new();
    let odd = FtpPayload {
        seq: f.seq,
        opcode: 77,
        ..Default::default()
    };
    f.server.handle(ME, &odd, 0.0, &mut out);
    assert_eq!(error_of(&out[0].1.data), FtpError::UnknownCommand);
    // The session closes after 10 s unused.
    f.server.poll(11.0, 10, &mut out);
    assert_eq!(f.one(ReadFile, b"", 0), Err(FtpError::InvalidSession));
}

#[test]
fn a_repeated_request_gets_the_same_reply_without_acting_twice() {
    let mut f = Fixture::new("repeat", true);
    let open = FtpPayload {
        seq: 40,
        opcode: Opcode::CreateFile as u8,
        size: 1,
        data: b"n".to_vec(),
        ..Default::default()
    };
    let (mut first, mut again) = (Vec::new(), Vec::new());
    f.server.handle(ME, &open, 0.0, &mut first);
    f.server.handle(ME, &open, 0.0, &mut again);
    assert_eq!(first, again);
    assert_eq!(
        first[0].1.opcode,
        Opcode::Ack as u8,
        "not refused as a second session"
    );
}

#[test]
fn the_virtual_directory_reads_and_refuses_changes() {
    let mut f = Fixture::new("virtual", true);
    use Opcode::*;
    assert_eq!(
        f.one(ListDirectory, b"/@META", 0),
        Ok(b"Fgeneral.json\t14\0".to_vec())
    );
    assert_eq!(f.one(ListDirectory, b"/@META", 1), Err(FtpError::Eof));
    assert_eq!(
        f.one(OpenFileRO, b"@META/nothing.json", 0),
        Err(FtpError::FileNotFound)
    );
    assert_eq!(
        f.one(RemoveFile, b"@META/general.json", 0),
        Err(FtpError::FileProtected)
    );
    assert_eq!(
        f.one(CreateFile, b"@META/x", 0),
        Err(FtpError::FileProtected)
    );
    assert_eq!(
        f.one(CalcFileCRC32, b"@META/general.json", 0),
        Ok(crc32_of(b"{\"version\": 1}").to_le_bytes().to_vec())
    );
    assert_eq!(
        f.one(OpenFileRO, b"/@META/general.json", 0),
        Ok(14u32.to_le_bytes().to_vec())
    );
    assert_eq!(
        f.one_sized(ReadFile, b"", 10, Some(239)),
        Ok(b": 1}".to_vec())
    );
    assert_eq!(f.one(WriteFile, b"x", 0), Err(FtpError::FileProtected));
    // A name that only starts alike is the root's.
    assert_eq!(
        f.one(OpenFileRO, b"@METADATA", 0),
        Err(FtpError::FileNotFound)
    );
}
