//! A flight board in real time: the deadline-paced control loop against `sitl` streaming its
//! frames on a serial line. Its own test binary, so that it does not share the machine with
//! the lockstep flights, which run side by side as fast as the cores go.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

mod common;
use common::*;
use std::path::Path;
use std::time::Duration;

/// A flight board in the real world: `sitl` in real time on a serial line streams its frames
/// without waiting for answers, and the autopilot's loop runs on absolute deadlines at 1 kHz,
/// stepping on each frame as it arrives. How well it keeps its rate is the benchmark's
/// (tools/bench.sh), which a machine busy with other work must not fail: this asserts that the
/// deadline loop flew the sequence to the ground in real time, and prints its rate.
#[test]
fn a_board_in_real_time_flies_the_deadline_paced_loop() {
    let dir = tempfile::tempdir().unwrap();
    let truth = dir.path().join("truth.csv");
    let Some((sitl, device)) = sitl_on_a_pty(&["--serial", "pty", "--mode", "realtime"], 3, &truth)
    else {
        return;
    };
    let source = format!("serial://{device}");
    // A board's magnetometer is calibrated once by its owner (a simulator's is preset).
    let params = dir.path().join("flight.toml");
    let text = std::fs::read_to_string(Path::new(ROOT).join("params/flight.toml")).unwrap();
    let calibrated = text.replace("mag_calibration_id = 0 ", "mag_calibration_id = 1 ");
    assert_ne!(text, calibrated);
    std::fs::write(&params, calibrated).unwrap();
    let args = [
        "--source",
        &source,
        "--params",
        params.to_str().unwrap(),
        "--loop-hz",
        "1000",
        "--takeoff",
        "2",
        "--hover",
        "2",
        "--params-dir",
        "params",
    ];
    let s = summary(&wait(
        spawn_autopilot(&args),
        "autopilot --source serial (real time)",
        Duration::from_secs(90),
    ));
    interrupt(sitl);
    assert_eq!(s["pacing"], "deadlines");
    let wall = figure(&s, "wall_time_s");
    println!(
        "deadline loop at {} Hz ({} ticks in {wall} s), {} frames in {} s of sensor time",
        s["loop_hz"], s["ticks"], s["frames"], s["sim_time_s"]
    );
    // Real time: the flight's sensor time is its wall time, less the start-up before the first
    // frame; never more.
    assert!(
        figure(&s, "sim_time_s") <= wall + 0.1,
        "real time, not faster"
    );
    assert_eq!(s["malformed"], "0");
    assert!(figure(&s, "max_alt_m") > 1.5, "took off");
    assert_eq!(s["landed"], "true");
    assert_eq!(s["disarmed"], "true");
}
