//! A directory's listing as FTP sends it: from an entry index, as many entries as fit in one
//! payload, `F<name>\t<size>` (and `\t<mtime>` for `ListDirectoryWithTime`) for a file,
//! `D<name>` for a directory, `S` for anything else, each ending in NUL. Entries are sorted
//! by name, so that the indices a client counts stay put between its requests; the root
//! lists its virtual directories (`@MAV_LOG`, the metadata's) first.

use super::payload::{ENOTDIR, FtpError, MAX_DATA};
use std::path::Path;

/// The entries of `dir` from index `offset` that fit in one payload; [`FtpError::Eof`] when
/// none is left (an empty directory included, which clients take as the end). Only the
/// entries sent are looked at beyond their names.
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
    let mut found: Vec<_> = std::fs::read_dir(dir)
        .map_err(|e| FtpError::of_io(&e))?
        .filter_map(|e| e.ok())
        .collect();
    found.sort_by_key(|e| e.file_name());
    // Skipped before anything but the name is read.
    let names = virtual_dirs
        .iter()
        .map(|name| Err(*name))
        .chain(found.iter().map(Ok));
    let texts = names.skip(offset as usize).map(|n| match n {
        Err(name) => format!("D{name}").into_bytes(),
        Ok(e) => entry(e, with_time),
    });
    pack(texts)
}

/// As many `entries` as fit in one payload, each ending in NUL (one too long for any payload
/// becomes `S`); [`FtpError::Eof`] when there is none.
pub fn pack(entries: impl Iterator<Item = Vec<u8>>) -> Result<Vec<u8>, FtpError> {
    let mut out = Vec::new();
    for mut e in entries {
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
