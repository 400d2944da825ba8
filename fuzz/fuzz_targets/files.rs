//! What a ground station asks of the vehicle's files: any sequence of FTP requests (every
//! opcode and any byte as one, any session, size, offset and path, `..` and all) and of log
//! download requests, against a scratch root with files and flight logs in it. No panic, no
//! escape from the root, a bounded number of replies per request.
#![no_main]

use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;
use mavlink::MavHeader;
use mavlink::dialects::common::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use vehicle_files::{FileServices, FilesConfig};

#[derive(Debug, Arbitrary)]
enum Step {
    Ftp {
        link: u8,
        system: u8,
        seq: u16,
        session: u8,
        opcode: u8,
        size: u8,
        offset: u32,
        path: Vec<u8>,
    },
    List {
        start: u16,
        end: u16,
    },
    Data {
        id: u16,
        ofs: u32,
        count: u32,
    },
    End,
    Erase,
    Poll {
        budget: u8,
        dt_s: u8,
    },
}

/// Opcodes the fuzzer should meet often (any byte stays possible).
const OPCODES: [u8; 18] = [
    0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 129,
];

static RUNS: AtomicU32 = AtomicU32::new(0);

/// The scratch root, made afresh every 256 runs (writes would fill it).
fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fuzz-files-{}", std::process::id()));
    if RUNS.fetch_add(1, Ordering::Relaxed) % 256 == 0 {
        let _ = std::fs::remove_dir_all(&dir);
        let logs = dir.join("logs");
        std::fs::create_dir_all(logs.join("sub")).expect("scratch");
        std::fs::write(dir.join("a.txt"), b"hello").expect("file");
        std::fs::write(logs.join("2026-01-01_00-00-00.ulg"), vec![7u8; 1000]).expect("log");
        std::fs::write(logs.join("2026-01-02_00-00-00.ulg"), vec![9u8; 91]).expect("log");
        // A name not in ASCII, cut by the 19-byte time in the middle of a character.
        std::fs::write(logs.join("ééééééééééé.ulg"), b"x").expect("log");
        #[cfg(unix)]
        {
            // A way out, and one to nowhere.
            let _ = std::os::unix::fs::symlink(std::env::temp_dir(), dir.join("out"));
            let _ = std::os::unix::fs::symlink(dir.join("gone"), dir.join("dangling"));
        }
    }
    dir
}

fuzz_target!(|steps: Vec<Step>| {
    let dir = scratch();
    let config = FilesConfig {
        ftp_root: Some(dir.clone()),
        logs: Some(dir.join("logs")),
        writable: steps.len() % 2 == 0,
        busy: vec![dir.join("logs/2026-01-02_00-00-00.ulg")],
        virtual_dir: vehicle_files::VirtualDir {
            name: "@META".into(),
            files: vec![("general.json".into(), b"{}".as_slice().into())],
        },
    };
    let mut files = FileServices::new(1, 1, &config);
    let mut now = 0.0;
    for step in steps.into_iter().take(64) {
        let mut out = Vec::new();
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        };
        let m = match step {
            Step::Ftp {
                link,
                system,
                seq,
                session,
                opcode,
                size,
                offset,
                path,
            } => {
                let mut payload = [0u8; 251];
                payload[0..2].copy_from_slice(&seq.to_le_bytes());
                payload[2] = session;
                payload[3] = OPCODES.get(usize::from(opcode)).copied().unwrap_or(opcode);
                payload[4] = size;
                payload[8..12].copy_from_slice(&offset.to_le_bytes());
                // A first byte 0xff tries the way out (the rest of the path follows it).
                let path = match path.split_first() {
                    Some((0xff, rest)) => [b"../escaped".as_slice(), rest].concat(),
                    _ => path,
                };
                let n = path.len().min(239);
                payload[12..12 + n].copy_from_slice(&path[..n]);
                let f = FILE_TRANSFER_PROTOCOL_DATA {
                    target_network: 0,
                    target_system: system % 3,
                    target_component: 1,
                    payload,
                };
                files.on_message(
                    link % 4,
                    &header,
                    &MavMessage::FILE_TRANSFER_PROTOCOL(f),
                    now,
                    &mut out,
                );
                assert!(out.len() <= 1, "{out:?}");
                continue;
            }
            Step::List { start, end } => MavMessage::LOG_REQUEST_LIST(LOG_REQUEST_LIST_DATA {
                start,
                end,
                target_system: 1,
                target_component: 1,
            }),
            Step::Data { id, ofs, count } => MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
                ofs,
                count,
                id,
                target_system: 1,
                target_component: 1,
            }),
            Step::End => MavMessage::LOG_REQUEST_END(LOG_REQUEST_END_DATA {
                target_system: 1,
                target_component: 1,
            }),
            Step::Erase => MavMessage::LOG_ERASE(LOG_ERASE_DATA {
                target_system: 1,
                target_component: 1,
            }),
            Step::Poll { budget, dt_s } => {
                now += f64::from(dt_s);
                files.poll(now, usize::from(budget), &mut out);
                // The budget, and a CRC's answer when one is done.
                assert!(
                    out.len() <= usize::from(budget) + 1,
                    "{} > {budget}",
                    out.len()
                );
                continue;
            }
        };
        files.on_message(0, &header, &m, now, &mut out);
        assert!(out.len() <= 1, "{out:?}");
    }
    // Nothing left the root: no `escaped` beside it.
    assert!(!dir.with_file_name("escaped").exists());
});
