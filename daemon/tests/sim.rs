//! `autopilot --sim` run as a user runs it.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs the autopilot to its end; a run still going after two minutes is killed and fails the
/// test (a hang must fail here, not stall CI).
fn autopilot(args: &[&str]) -> std::process::Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_autopilot"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            let out = child.wait_with_output().unwrap();
            panic!(
                "autopilot {args:?} still running after 120 s:\n{}",
                String::from_utf8_lossy(&out.stdout)
                    .lines()
                    .rev()
                    .take(5)
                    .collect::<Vec<_>>()
                    .join("\n")
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn summary(out: &std::process::Output) -> HashMap<String, String> {
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
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

/// Take-off, hover, land and disarm in the embedded simulator, through the HIL messages.
#[test]
fn flies_the_sequence_in_the_embedded_simulator() {
    for airframe in ["quad_x", "dodeca"] {
        let s = summary(&autopilot(&[
            "--sim",
            "--speed",
            "max",
            "--airframe",
            airframe,
            "--takeoff",
            "4",
            "--hover",
            "3",
        ]));
        let alt: f64 = s["max_alt_m"].parse().unwrap();
        let touchdown: f64 = s["touchdown_m_s"].parse().unwrap();
        println!("{airframe}: {s:?}");
        assert!((3.5..5.0).contains(&alt), "{airframe}: climbed to {alt} m");
        assert!(touchdown <= 0.5, "{airframe}: touchdown {touchdown} m/s");
        assert_eq!(
            (
                s["landed"].as_str(),
                s["disarmed"].as_str(),
                s["malformed"].as_str()
            ),
            ("true", "true", "0")
        );
    }
}

#[test]
fn refuses_what_it_cannot_fly() {
    let o = autopilot(&[]);
    assert!(!o.status.success(), "no arguments: help, not a flight");
    let o = autopilot(&["--takeoff", "5"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("no sensor source: give --sim"));
    let o = autopilot(&["--sim", "--speed", "0"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--speed must be a positive factor"));
    let o = autopilot(&["--sim", "--airframe", "tricopter"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("tricopter.toml: cannot read"));
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[position]\nmax_tilt_deg = 120.0\n").unwrap();
    let o = autopilot(&["--sim", "--params", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("`position.max_tilt_deg`: must be within [5, 80] deg, got 120"),
        "{err}"
    );
}
