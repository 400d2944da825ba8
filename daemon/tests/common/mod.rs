//! The `autopilot` and `sitl` binaries as a user runs them: spawned with a time limit, their
//! summaries read, `sitl` interrupted as a person would, a free port, a pseudo-terminal line.
#![allow(dead_code)] // each test crate uses its share

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

pub const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// Waits for `child` to end; one still running after `limit` is killed and fails the test (a
/// hang must fail here, not stall CI).
pub fn wait(mut child: Child, what: &str, limit: Duration) -> Output {
    let deadline = Instant::now() + limit;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            let out = child.wait_with_output().unwrap();
            panic!(
                "{what} still running after {limit:?}; last output:\n{}\n{}",
                tail(&out.stdout),
                tail(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

pub fn tail(bytes: &[u8]) -> String {
    let s = String::from_utf8_lossy(bytes);
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(8)..].join("\n")
}

pub fn spawn(exe: &Path, args: &[&str]) -> Child {
    Command::new(exe)
        .current_dir(ROOT)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// The autopilot with `args`, keeping no logs but those the arguments name (these flights run
/// as fast as lockstep goes, and the default logs would slow them threefold), and no
/// ground-station links unless they name one (flights run side by side would take each
/// other's ports).
pub fn spawn_autopilot(args: &[&str]) -> Child {
    let mut args = args.to_vec();
    args.extend(["--log-dir", "none"]);
    if !args.contains(&"--mavlink") {
        args.extend(["--mavlink", "none"]);
    }
    spawn(&autopilot_exe(), &args)
}

pub fn autopilot_exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_autopilot"))
}

/// The `sitl` binary beside `autopilot` in the workspace's target directory (`cargo test
/// --workspace` builds both).
pub fn sitl_exe() -> PathBuf {
    let p = autopilot_exe().with_file_name(format!("sitl{}", std::env::consts::EXE_SUFFIX));
    assert!(
        p.exists(),
        "{} is missing: build it first (cargo build -p sitl, or cargo test --workspace)",
        p.display()
    );
    p
}

/// The `autopilot summary:` line as key → value.
pub fn summary(out: &Output) -> HashMap<String, String> {
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}\n{}",
        tail(&out.stdout),
        tail(&out.stderr)
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("autopilot summary:"))
        .expect("summary");
    line.split_whitespace()
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .collect()
}

/// `sitl` on `link` (its link flags), simulating `airframe` with `seed`, writing its truth to
/// `truth_csv`; it waits up to 30 s for the autopilot and runs until interrupted.
pub fn spawn_sitl(link: &[&str], airframe: &str, seed: u64, truth_csv: &Path) -> Child {
    let seed = seed.to_string();
    let mut args = link.to_vec();
    args.extend([
        "--airframe",
        airframe,
        "--seed",
        &seed,
        "--duration",
        "300",
        "--connect-timeout",
        "30",
        "--status-interval",
        "0",
        "--truth-csv",
        truth_csv.to_str().unwrap(),
    ]);
    spawn(&sitl_exe(), &args)
}

/// The flight is over: Ctrl-C the simulator as a person would, so that it writes its truth and
/// summary and exits cleanly.
pub fn interrupt(sitl: Child) -> Output {
    let status = Command::new("kill")
        .args(["-INT", &sitl.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = wait(sitl, "sitl", Duration::from_secs(30));
    assert!(out.status.success(), "sitl: {}", tail(&out.stderr));
    out
}

pub fn figure(s: &HashMap<String, String>, key: &str) -> f64 {
    s[key].parse().unwrap()
}

/// `sitl` with `link` (which opens a pseudo-terminal) flying quad_x with `seed`: the child and
/// the autopilot's end of the line, which sitl prints first. `None` (said loudly) on a machine
/// without pseudo-terminals.
pub fn sitl_on_a_pty(link: &[&str], seed: u64, truth_csv: &Path) -> Option<(Child, String)> {
    let mut sitl = spawn_sitl(link, "quad_x", seed, truth_csv);
    // Read on a thread, so that a simulator that never prints cannot hang the test.
    let stdout = sitl.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        let mut reader = std::io::BufReader::new(stdout);
        let mut line = String::new();
        let _ = reader.read_line(&mut line);
        let _ = tx.send(line);
        // Keep reading to the end: a closed pipe would fail sitl's summary.
        let _ = std::io::copy(&mut reader, &mut std::io::sink());
    });
    let line = rx.recv_timeout(Duration::from_secs(30)).unwrap_or_default();
    let Some(device) = line.trim().strip_prefix("sitl serial: ") else {
        let _ = sitl.kill();
        let out = sitl.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        if err.contains("opening a pseudo-terminal pair") {
            eprintln!("SKIPPED a serial flight: this machine has no pseudo-terminals: {err}");
            return None;
        }
        panic!("sitl did not name its pseudo-terminal: {line:?}\n{err}");
    };
    Some((sitl, device.to_owned()))
}

/// A free UDP port on the loopback: bind, note, release.
pub fn free_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}
