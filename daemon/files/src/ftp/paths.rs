//! Where an FTP path lands: inside the served root (or the `@MAV_LOG` virtual directory, the
//! flight logs, as PX4 maps it), never outside. `..`, a symbolic link leading out and a name
//! that is not UTF-8 are refused; writes are refused when switched off and on the logs being
//! written now.

use super::payload::FtpError;
use std::path::{Component, Path, PathBuf};

/// PX4's virtual directory of the flight logs.
pub const MAV_LOG: &str = "@MAV_LOG";

/// The file system an FTP server serves.
#[derive(Debug, Clone)]
pub struct FtpRoot {
    /// The root directory, canonical.
    root: PathBuf,
    /// The flight logs' directory (`@MAV_LOG`), canonical.
    logs: Option<PathBuf>,
    /// Writes (create, write, remove, rename, truncate, make directories) allowed.
    writable: bool,
    /// Files being written by the vehicle now (its logs): never removed, renamed or written.
    busy: Vec<PathBuf>,
}

impl FtpRoot {
    /// Serves `root` (made if missing) and the logs in `logs` as `@MAV_LOG`; `writable`
    /// switches writes on.
    pub fn new(root: &Path, logs: Option<&Path>, writable: bool) -> std::io::Result<Self> {
        std::fs::create_dir_all(root)?;
        Ok(Self {
            root: root.canonicalize()?,
            logs: logs.and_then(|l| l.canonicalize().ok()),
            writable,
            busy: Vec::new(),
        })
    }

    /// Files the vehicle is writing (its logs), protected from the ground station's writes.
    pub fn set_busy(&mut self, files: &[PathBuf]) {
        self.busy = files.iter().filter_map(|f| f.canonicalize().ok()).collect();
    }

    /// Whether the root's listing shows `@MAV_LOG`.
    pub(super) fn has_logs(&self) -> bool {
        self.logs.is_some()
    }

    /// The place of `requested` (an FTP path: `/` or nothing is the root), which may not
    /// exist yet.
    pub fn resolve(&self, requested: &[u8]) -> Result<PathBuf, FtpError> {
        let text = std::str::from_utf8(requested).map_err(|_| FtpError::FileNotFound)?;
        let text = text.trim_start_matches('/');
        let (base, rest) = match text.strip_prefix(MAV_LOG) {
            Some(rest) if rest.is_empty() || rest.starts_with('/') => {
                (self.logs.as_ref().ok_or(FtpError::FileNotFound)?, rest)
            }
            _ if text.starts_with('@') => return Err(FtpError::FileNotFound),
            _ => (&self.root, text),
        };
        let mut path = base.clone();
        for c in Path::new(rest).components() {
            match c {
                Component::Normal(name) => path.push(name),
                Component::CurDir | Component::RootDir => {}
                Component::ParentDir | Component::Prefix(_) => {
                    return Err(FtpError::FileProtected);
                }
            }
        }
        // A symbolic link may lead out: what exists of the path must stay under its base.
        // (A dangling link counts as existing: it cannot be made canonical, so it is refused.)
        let mut existing = path.as_path();
        while existing.symlink_metadata().is_err() {
            existing = existing.parent().ok_or(FtpError::FileNotFound)?;
        }
        let real = existing.canonicalize().map_err(|e| FtpError::of_io(&e))?;
        if !real.starts_with(base) {
            return Err(FtpError::FileProtected);
        }
        Ok(path)
    }

    /// The place of a path to change (write, create, remove, rename): refused when writes are
    /// off, for the root, and for the logs' directory, the logs being written and every
    /// directory holding them (a rename of a parent would move them).
    pub fn resolve_for_write(&self, requested: &[u8]) -> Result<PathBuf, FtpError> {
        if !self.writable {
            return Err(FtpError::FileProtected);
        }
        let path = self.resolve(requested)?;
        let real = path.canonicalize().unwrap_or_else(|_| path.clone());
        let holds = |p: &PathBuf| p.starts_with(&real);
        if real == self.root || self.logs.iter().chain(&self.busy).any(holds) {
            return Err(FtpError::FileProtected);
        }
        Ok(path)
    }

    /// Whether `path` is the root (whose listing adds `@MAV_LOG`).
    pub(super) fn is_root(&self, path: &Path) -> bool {
        path == self.root
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory under the system's temporary one.
    pub(crate) fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ftp-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch directory");
        dir
    }

    #[test]
    fn paths_stay_inside_the_root_and_logs_are_at_mav_log() {
        let dir = scratch("paths");
        let (root, logs) = (dir.join("root"), dir.join("logs"));
        std::fs::create_dir_all(&logs).expect("logs");
        let r = FtpRoot::new(&root, Some(&logs), true).expect("root");
        let root = root.canonicalize().expect("canonical");
        let logs = logs.canonicalize().expect("canonical");
        assert_eq!(r.resolve(b"/a/b.txt"), Ok(root.join("a/b.txt")));
        assert_eq!(r.resolve(b"//./a"), Ok(root.join("a")));
        assert_eq!(r.resolve(b""), Ok(root.clone()));
        assert_eq!(r.resolve(b"@MAV_LOG/x.ulg"), Ok(logs.join("x.ulg")));
        assert_eq!(r.resolve(b"/@MAV_LOG"), Ok(logs.clone()));
        assert_eq!(r.resolve(b"@MAV_LOGS"), Err(FtpError::FileNotFound));
        assert_eq!(r.resolve(b"@ROMFS/x"), Err(FtpError::FileNotFound));
        assert_eq!(r.resolve(b"../etc/passwd"), Err(FtpError::FileProtected));
        assert_eq!(r.resolve(b"a/../../x"), Err(FtpError::FileProtected));
        assert_eq!(r.resolve(b"@MAV_LOG/../root"), Err(FtpError::FileProtected));
        assert_eq!(r.resolve(&[0xff, 0xfe]), Err(FtpError::FileNotFound));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink("/etc", root.join("out")).expect("symlink");
            assert_eq!(r.resolve(b"out/passwd"), Err(FtpError::FileProtected));
            assert_eq!(r.resolve(b"out"), Err(FtpError::FileProtected));
            std::os::unix::fs::symlink(dir.join("nowhere"), root.join("dangling")).expect("link");
            assert!(r.resolve_for_write(b"dangling").is_err());
        }
        assert_eq!(r.resolve_for_write(b"/"), Err(FtpError::FileProtected));
        assert_eq!(
            r.resolve_for_write(b"@MAV_LOG"),
            Err(FtpError::FileProtected)
        );
        std::fs::write(logs.join("now.ulg"), b"x").expect("log");
        let mut r = r;
        r.set_busy(&[logs.join("now.ulg")]);
        assert_eq!(
            r.resolve_for_write(b"@MAV_LOG/now.ulg"),
            Err(FtpError::FileProtected)
        );
        assert!(r.resolve_for_write(b"@MAV_LOG/old.ulg").is_ok());
        let ro = FtpRoot::new(&root, Some(&logs), false).expect("root");
        assert_eq!(ro.resolve_for_write(b"a"), Err(FtpError::FileProtected));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
