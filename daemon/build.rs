//! Records the git commit the autopilot is built from (`AUTOPILOT_GIT_HASH`, given by the
//! environment of the build when there is no git checkout, as in a container build), for the
//! manifests of `autopilot batch`.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
        .filter(|s| !s.is_empty())
}

fn main() {
    println!("cargo:rerun-if-env-changed=AUTOPILOT_GIT_HASH");
    let given = std::env::var("AUTOPILOT_GIT_HASH")
        .ok()
        .filter(|s| !s.is_empty());
    let hash = given
        .or_else(|| git(&["rev-parse", "HEAD"]))
        .unwrap_or_else(|| "unknown".into());
    // Built again when HEAD moves: HEAD itself, and the branch it names.
    for path in [git(&["rev-parse", "--git-path", "HEAD"]), branch_file()]
        .into_iter()
        .flatten()
    {
        if std::path::Path::new(&path).exists() {
            println!("cargo:rerun-if-changed={path}");
        }
    }
    println!("cargo:rustc-env=AUTOPILOT_GIT_HASH={hash}");
}

/// The file of the branch HEAD names (absent once packed; then packed-refs).
fn branch_file() -> Option<String> {
    let branch = git(&["symbolic-ref", "-q", "HEAD"])?;
    let loose = git(&["rev-parse", "--git-path", &branch])?;
    if std::path::Path::new(&loose).exists() {
        Some(loose)
    } else {
        git(&["rev-parse", "--git-path", "packed-refs"])
    }
}
