//! The MAVLink signing key's file and, beside it, what signing remembers across restarts
//! ([`gcs::signing::SigningMemory`], `NAME.timestamps`).
//!
//! A key file must be the owner's alone (mode 0600: no group or other permission bits) and
//! hold a key that is not all zeros (which the spec reserves for "signing off"); otherwise
//! the daemon refuses to start and says why, rather than fly with a key others can read.

use anyhow::{Context, Result, bail};
use gcs::signing::{SecretKey, SigningMemory};
use std::path::{Path, PathBuf};

/// The key in the file at `path`; a missing file is no key (signing off).
pub fn load_key(path: &Path) -> Result<Option<SecretKey>> {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path)
            .with_context(|| format!("reading {}", path.display()))?
            .permissions()
            .mode()
            & 0o777;
        if mode & 0o077 != 0 {
            bail!(
                "{}: a signing key others may read (mode {mode:04o}): `chmod 600 {}`",
                path.display(),
                path.display()
            );
        }
    }
    let key = SecretKey::from_hex(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if key.0 == [0; 32] {
        bail!(
            "{}: an all-zero key means signing off: remove the file to fly unsigned, or write a real key",
            path.display()
        );
    }
    Ok(Some(key))
}

/// Where signing's memory is kept for the key at `key_path`: `NAME.timestamps` beside it.
pub fn memory_path(key_path: &Path) -> PathBuf {
    let mut name = key_path.file_name().unwrap_or_default().to_os_string();
    name.push(".timestamps");
    key_path.with_file_name(name)
}

/// The memory at `path`: none if missing; if unreadable, none and a warning (the one-minute
/// window for new streams still holds; what was captured within it could be replayed once).
pub fn load_memory(path: &Path) -> (SigningMemory, Option<String>) {
    let warn = |what: String| {
        let w = format!(
            "{}: {what}: stream timestamps forgotten (frames captured in the last minute could be replayed)",
            path.display()
        );
        (SigningMemory::default(), Some(w))
    };
    match std::fs::read_to_string(path) {
        Ok(text) => match SigningMemory::parse(&text) {
            Ok(m) => (m, None),
            Err(e) => warn(e.to_string()),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => (SigningMemory::default(), None),
        Err(e) => warn(e.to_string()),
    }
}

/// Writes the memory to `path`, atomically, the owner's alone.
pub fn save_memory(path: &Path, m: &SigningMemory) -> Result<()> {
    crate::records::param_file::write_private(path, &m.to_text())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn write(path: &Path, text: &str, mode: u32) {
        std::fs::write(path, text).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
        }
    }

    #[test]
    fn a_key_file_must_be_private_and_hold_a_real_key() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("key");
        assert_eq!(load_key(&path).unwrap(), None, "no file: signing off");
        let hex = "07".repeat(32);
        write(&path, &hex, 0o600);
        assert_eq!(load_key(&path).unwrap(), Some(SecretKey([7; 32])));
        write(&path, &hex, 0o644);
        let e = load_key(&path).unwrap_err().to_string();
        assert!(
            e.contains("others may read (mode 0644)") && e.contains("chmod 600"),
            "{e}"
        );
        write(&path, &"00".repeat(32), 0o600);
        let e = load_key(&path).unwrap_err().to_string();
        assert!(e.contains("all-zero key"), "{e}");
        write(&path, "0707", 0o600);
        let e = load_key(&path).unwrap_err().to_string();
        assert!(e.contains("64 hexadecimal digits"), "{e}");
    }

    #[test]
    fn the_memory_is_kept_privately_beside_the_key_and_damage_is_a_warning() {
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("signing.key");
        let path = memory_path(&key);
        assert_eq!(path, dir.path().join("signing.key.timestamps"));
        assert_eq!(load_memory(&path), (SigningMemory::default(), None));
        let m = SigningMemory {
            timestamp: 37_100_000_000_000,
            streams: vec![((255, 190, 0), 37_099_999_999_999)],
        };
        save_memory(&path, &m).unwrap();
        assert_eq!(load_memory(&path), (m, None));
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o600);
        }
        std::fs::write(&path, "").unwrap();
        let (m, warning) = load_memory(&path);
        assert_eq!(m, SigningMemory::default());
        assert!(warning.unwrap().contains("no `timestamp` line"));
    }
}
