//! A read-only directory of files held in memory (the component metadata a ground station
//! downloads), at `/<name>/` beside what the root holds.

use super::payload::{FtpError, MAX_DATA};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::sync::Arc;

/// The directory's name and files.
#[derive(Debug, Clone, Default)]
pub struct VirtualDir {
    /// Its name (`@META`).
    pub name: String,
    /// Each file's name and bytes.
    pub files: Vec<(String, Arc<[u8]>)>,
}

/// What a path names in the virtual directory.
#[derive(Debug, Clone, PartialEq)]
pub enum VirtualPlace {
    /// The directory itself.
    Dir,
    /// One of its files.
    File(Arc<[u8]>),
}

impl VirtualDir {
    /// What `requested` names here, if it is under this directory: `Err(FileNotFound)` for a
    /// name it does not hold.
    pub fn find(&self, requested: &[u8]) -> Option<Result<VirtualPlace, FtpError>> {
        let text = std::str::from_utf8(requested).ok()?.trim_start_matches('/');
        let rest = text.strip_prefix(self.name.as_str())?;
        let name = match rest.strip_prefix('/') {
            None if rest.is_empty() => return Some(Ok(VirtualPlace::Dir)),
            None => return None, // another name that starts alike
            Some(name) => name.trim_end_matches('/'),
        };
        if name.is_empty() {
            return Some(Ok(VirtualPlace::Dir));
        }
        Some(
            self.files
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, bytes)| VirtualPlace::File(bytes.clone()))
                .ok_or(FtpError::FileNotFound),
        )
    }

    /// Its listing from entry `offset`, as [`super::listing::entries`] gives a directory's.
    pub fn entries(&self, offset: u32) -> Result<Vec<u8>, FtpError> {
        let files = self.files.iter().skip(offset as usize);
        super::listing::pack(
            files.map(|(name, bytes)| format!("F{name}\t{}", bytes.len()).into_bytes()),
        )
    }
}

/// What a session reads or writes: a file, or bytes held in memory.
#[derive(Debug)]
pub enum OpenFile {
    /// A file on disk.
    Disk(File),
    /// A virtual file.
    Memory(Arc<[u8]>),
}

impl OpenFile {
    /// Up to `want` bytes (at most [`MAX_DATA`]) from `offset`, not past `size`; empty at the
    /// end.
    pub fn read_at(&mut self, offset: u64, size: u64, want: usize) -> Result<Vec<u8>, FtpError> {
        let n = size.saturating_sub(offset).min(want.min(MAX_DATA) as u64) as usize;
        match self {
            Self::Memory(bytes) => {
                let from = usize::try_from(offset)
                    .unwrap_or(usize::MAX)
                    .min(bytes.len());
                Ok(bytes[from..(from + n).min(bytes.len())].to_vec())
            }
            Self::Disk(file) => {
                let mut data = vec![0u8; n];
                if n > 0 {
                    file.seek(SeekFrom::Start(offset))
                        .and_then(|_| file.read_exact(&mut data))
                        .map_err(|e| FtpError::of_io(&e))?;
                }
                Ok(data)
            }
        }
    }
}
