//! Records the git commit the autopilot is built from, `-dirty` after it when tracked files
//! have changes (`AUTOPILOT_GIT_HASH` from the build's environment instead, when there is no
//! git checkout, as in a container build), for the manifests of `autopilot batch`.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

fn main() {
    println!("cargo:rerun-if-env-changed=AUTOPILOT_GIT_HASH");
    let given = std::env::var("AUTOPILOT_GIT_HASH")
        .ok()
        .filter(|s| !s.is_empty());
    let from_git = || {
        let hash = git(&["rev-parse", "HEAD"]).filter(|h| !h.is_empty())?;
        let changed = git(&["status", "--porcelain", "--untracked-files=no"])?;
        Some(if changed.is_empty() {
            hash
        } else {
            format!("{hash}-dirty")
        })
    };
    let hash = given.or_else(from_git).unwrap_or_else(|| "unknown".into());
    // Run again when HEAD moves (HEAD itself, the branch it names) or a source changes (the
    // workspace's crates, from this package's directory).
    let watched = [git(&["rev-parse", "--git-path", "HEAD"]), branch_file()];
    for path in watched
        .into_iter()
        .flatten()
        .chain([".", "../airframe", "../navmath", "../sitl", "../Cargo.lock"].map(String::from))
    {
        if std::path::Path::new(&path).exists() {
            println!("cargo:rerun-if-changed={path}");
        }
    }
    println!("cargo:rustc-env=AUTOPILOT_GIT_HASH={hash}");
}

/// The file of the branch HEAD names (absent once packed; then packed-refs).
fn branch_file() -> Option<String> {
    let branch = git(&["symbolic-ref", "-q", "HEAD"]).filter(|b| !b.is_empty())?;
    let loose = git(&["rev-parse", "--git-path", &branch])?;
    if std::path::Path::new(&loose).exists() {
        Some(loose)
    } else {
        git(&["rev-parse", "--git-path", "packed-refs"])
    }
}
