//! A directory's listing as FTP sends it: from an entry index, as many entries as fit in one
//! payload, `F<name>\t<size>` (and `\t<mtime>` for `ListDirectoryWithTime`) for a file,
//! `D<name>` for a directory, `S` for anything else, each ending in NUL. Entries are sorted
//! by name, so that the indices a client counts stay put between its requests; the root
//! lists its virtual directories (`@MAV_LOG`, the metadata's) first.

use super::payload::{FtpError, MAX_DATA};
use std::path::Path;

/// The entries of `dir` from index `offset` that fit in one payload; [`FtpError::Eof`] when
/// none is left (an empty directory included, which clients take as the end).
pub fn entries(
    dir: &Path,
    offset: u32,
    with_time: bool,
    virtual_dirs: &[&str],
) -> Result<Vec<u8>, FtpError> {
    if !dir.is_dir() {
        return Err(match dir.exists() {
            true => FtpError::FailErrno(ENOTDIR),
            false => FtpError::FileNotFound,
        });
    }
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .map_err(|e| FtpError::of_io(&e))?
        .filter_map(|e| e.ok())
        .collect();
    names.sort_by_key(|e| e.file_name());
    let mut all: Vec<Vec<u8>> = Vec::with_capacity(names.len() + 1);
    for name in virtual_dirs {
        all.push(format!("D{name}").into_bytes());
    }
    for e in names {
        all.push(entry(&e, with_time));
    }
    let mut out = Vec::new();
    for mut e in all.into_iter().skip(offset as usize) {
        if e.len() + 1 > MAX_DATA {
            e = b"S".to_vec(); // a name too long for any payload
        }
        if out.len() + e.len() + 1 > MAX_DATA {
            break;
        }
        out.extend_from_slice(&e);
        out.push(0);
    }
    if out.is_empty() {
        return Err(FtpError::Eof);
    }
    Ok(out)
}

/// `ENOTDIR` (Linux's number).
const ENOTDIR: u8 = 20;

/// One entry's text (without its NUL).
fn entry(e: &std::fs::DirEntry, with_time: bool) -> Vec<u8> {
    let (Some(name), Ok(meta)) = (e.file_name().to_str().map(str::to_owned), e.metadata()) else {
        return b"S".to_vec();
    };
    if name.contains(['\t', '\0']) {
        return b"S".to_vec();
    }
    let mtime = || {
        meta.modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_secs())
    };
    match (meta.is_dir(), meta.is_file(), with_time) {
        (true, _, false) => format!("D{name}"),
        (true, _, true) => format!("D{name}\t0\t{}", mtime()),
        (_, true, false) => format!("F{name}\t{}", meta.len()),
        (_, true, true) => format!("F{name}\t{}\t{}", meta.len(), mtime()),
        _ => "S".to_owned(),
    }
    .into_bytes()
}
