//! End to end: the `autopilot` binary as a user runs it. It flies take-off, hover and landing in
//! lockstep in the embedded simulator, against a `sitl` process over UDP and over a serial line
//! (one seed, one flight), and refuses what it cannot fly.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

mod common;
use common::*;
use std::collections::HashMap;
use std::path::Path;
use std::time::{Duration, Instant};

const FLIGHT: [&str; 6] = ["--takeoff", "5", "--hover", "20", "--params-dir", "params"];

fn embedded(airframe: &str, seed: u64, truth_csv: Option<&Path>) -> HashMap<String, String> {
    let seed = seed.to_string();
    let mut args = vec![
        "--sim",
        "--speed",
        "max",
        "--airframe",
        airframe,
        "--seed",
        &seed,
    ];
    args.extend(FLIGHT);
    let csv;
    if let Some(p) = truth_csv {
        csv = p.to_str().unwrap().to_owned();
        args.extend(["--truth-csv", &csv]);
    }
    summary(&wait(
        spawn_autopilot(&args),
        "autopilot --sim",
        Duration::from_secs(120),
    ))
}

/// Every multirotor in lockstep, take-off to 5 m, 20 s hover, landing, over four seeds with the
/// typical sensors. Each flight must land softly and disarm. The hover figures are RMS over the
/// four flights; the targets are 0.15 m, 0.3 m and 1°. Altitude and attitude are held to
/// them. The horizontal drift from the take-off spot is the GPS's own wander (0.3 m σ per axis,
/// 60 s correlation: ≈ 0.28 m expected over this hover, and four seeds scatter by ±25 %), which
/// no estimator can see; it is held to 0.45 m here, and the autopilot's own part (holding where
/// the GPS says) to 0.2 m per flight in `daemon/core/tests/closed_loop.rs`.
#[test]
fn every_airframe_takes_off_hovers_and_lands_in_lockstep() {
    for airframe in ["quad_x", "hexa_x", "octa_x", "dodeca"] {
        let mut sq = [0.0; 3];
        let seeds = [1, 2, 3, 4];
        for seed in seeds {
            let s = embedded(airframe, seed, None);
            println!("{airframe} seed {seed}: {s:?}");
            let touchdown = figure(&s, "touchdown_m_s");
            assert!(
                touchdown <= 0.5,
                "{airframe} seed {seed}: touchdown {touchdown} m/s"
            );
            assert_eq!(
                (
                    s["landed"].as_str(),
                    s["disarmed"].as_str(),
                    s["malformed"].as_str()
                ),
                ("true", "true", "0"),
                "{airframe} seed {seed}"
            );
            let max_alt = figure(&s, "max_alt_m");
            assert!(
                (4.8..5.4).contains(&max_alt),
                "{airframe} seed {seed}: climbed to {max_alt} m"
            );
            for (i, key) in ["hover_alt_rms_m", "hover_drift_rms_m", "attitude_rms_deg"]
                .iter()
                .enumerate()
            {
                sq[i] += figure(&s, key).powi(2);
            }
        }
        let [alt, drift, att] = sq.map(|x| (x / seeds.len() as f64).sqrt());
        println!(
            "{airframe}: hover altitude RMS {alt:.3} m, drift RMS {drift:.3} m, attitude RMS {att:.2} deg"
        );
        assert!(alt <= 0.15, "{airframe}: hover altitude RMS {alt:.3} m");
        assert!(
            drift <= 0.45,
            "{airframe}: horizontal drift RMS {drift:.3} m"
        );
        assert!(att <= 1.0, "{airframe}: attitude estimate RMS {att:.2} deg");
    }
}

/// The same seed flies the same flight: the embedded simulator twice, and `sitl` and `autopilot`
/// as two processes over UDP on loopback, give a byte-identical truth trace.
#[test]
fn one_seed_one_flight_in_process_and_over_udp() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, udp) = (
        dir.path().join("a.csv"),
        dir.path().join("b.csv"),
        dir.path().join("udp.csv"),
    );
    let first = embedded("hexa_x", 7, Some(&a));
    embedded("hexa_x", 7, Some(&b));
    let (a, b) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert!(a.len() > 100_000, "a whole flight of truth rows");
    assert!(a == b, "two in-process runs of one seed differ");

    // A free port for the autopilot: bind, note, release.
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
        .to_string();
    let source = format!("udp://127.0.0.1:{port}");
    let mut args = vec!["--source", &source, "--airframe", "hexa_x"];
    args.extend(FLIGHT);
    let autopilot = spawn_autopilot(&args);
    let target = format!("127.0.0.1:{port}");
    let sitl = spawn_sitl(&["--autopilot", &target], "hexa_x", 7, &udp);
    let over_udp = summary(&wait(
        autopilot,
        "autopilot --source udp",
        Duration::from_secs(120),
    ));
    let sitl_out = interrupt(sitl);
    let sitl_summary = String::from_utf8_lossy(&sitl_out.stdout);
    assert!(sitl_summary.contains("malformed=0"), "{sitl_summary}");

    for key in ["frames", "max_alt_m", "hover_alt_rms_m", "touchdown_m_s"] {
        assert_eq!(first[key], over_udp[key], "{key} in-process vs over UDP");
    }
    assert_eq!(over_udp["disarmed"], "true");
    // sitl keeps stepping a little after the autopilot stops: compare what both wrote.
    let udp = std::fs::read(&udp).unwrap();
    let common = a.len().min(udp.len());
    assert!(common == a.len(), "the UDP trace covers the whole flight");
    assert!(
        a[..common] == udp[..common],
        "truth over UDP differs from in-process at byte {}",
        a.iter()
            .zip(&udp)
            .position(|(x, y)| x != y)
            .unwrap_or(common)
    );
}

/// The same flight over a serial line: `sitl --serial pty` opens a pseudo-terminal pair and plays
/// the flight board on one end, the autopilot opens the other as `serial:///dev/pts/N`. Frames
/// that queued in the line before the autopilot opened it are answered, not flown twice, so the
/// flight is the in-process one, byte for byte.
#[test]
fn the_same_flight_over_a_serial_line() {
    let dir = tempfile::tempdir().unwrap();
    let (local, serial) = (dir.path().join("local.csv"), dir.path().join("serial.csv"));
    let reference = embedded("quad_x", 5, Some(&local));
    let Some((sitl, device)) = sitl_on_a_pty(&["--serial", "pty"], 5, &serial) else {
        return;
    };
    // sitl over a pty is a simulator in lockstep, not a board in the real world: its pauses
    // (a loaded machine) are no sensor failure.
    let source = format!("serial://{device}?lockstep=true");
    let mut args = vec!["--source", &source, "--airframe", "quad_x"];
    args.extend(FLIGHT);
    let over_serial = summary(&wait(
        spawn_autopilot(&args),
        "autopilot --source serial",
        Duration::from_secs(120),
    ));
    interrupt(sitl);

    assert_eq!(over_serial["malformed"], "0");
    assert_eq!(over_serial["disarmed"], "true");
    for key in [
        "max_alt_m",
        "hover_alt_rms_m",
        "attitude_rms_deg",
        "touchdown_m_s",
    ] {
        assert_eq!(
            reference[key], over_serial[key],
            "{key} in-process vs serial"
        );
    }
    let (a, b) = (
        std::fs::read(&local).unwrap(),
        std::fs::read(&serial).unwrap(),
    );
    let common = a.len().min(b.len());
    assert!(common > 100_000, "a whole flight of truth rows");
    assert!(
        a[..common] == b[..common],
        "truth over serial differs from in-process at byte {}",
        a.iter().zip(&b).position(|(x, y)| x != y).unwrap_or(common)
    );
}

/// Bad command lines and parameter files stop the daemon with a message that names the problem.
#[test]
fn refuses_what_it_cannot_fly() {
    let autopilot =
        |args: &[&str]| wait(spawn_autopilot(args), "autopilot", Duration::from_secs(60));
    let o = autopilot(&[]);
    assert!(!o.status.success(), "no arguments: help, not a flight");
    let o = autopilot(&["--takeoff", "5"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("no sensor source: give --sim"));
    let o = autopilot(&["--sim", "--speed", "0"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--speed: 0 is out of range"));
    let o = autopilot(&["--sim", "--takeoff", "500"]);
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--takeoff: 500 is out of range [1, 100] m")
    );
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
    // The settings file: missing, an unknown key, a value out of range.
    let missing = dir.path().join("missing.toml");
    let o = autopilot(&["--config", missing.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("missing.toml: cannot read"), "{err}");
    let config = dir.path().join("autopilot.toml");
    for (text, says) in [
        (
            "source = \"sim\"\ntakeof_m = 5\n",
            "unknown field `takeof_m`",
        ),
        (
            "source = \"sim\"\nhover_s = 700000\n",
            "`hover_s`: 700000 is out of range [0, 604800] s",
        ),
    ] {
        std::fs::write(&config, text).unwrap();
        let o = autopilot(&["--config", config.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains("autopilot.toml") && err.contains(says),
            "{err}"
        );
    }
}

/// ArduPilot's JSON interface: `sitl --json` is the physics, the autopilot plays ArduPilot's
/// side (servo packets out, JSON states in, the sensors JSON lacks made on its side). The
/// take-off, hover and landing fly as over the HIL link.
#[test]
fn the_flight_through_ardupilots_json_interface() {
    let dir = tempfile::tempdir().unwrap();
    let addr = format!("127.0.0.1:{}", free_port());
    let sitl = spawn_sitl(&["--json", &addr], "quad_x", 3, &dir.path().join("t.csv"));
    let source = format!("json://{addr}");
    let mut args = vec!["--source", &source, "--seed", "3"];
    args.extend(FLIGHT);
    let s = summary(&wait(
        spawn_autopilot(&args),
        "autopilot --source json",
        Duration::from_secs(120),
    ));
    let sitl_out = interrupt(sitl);
    let sitl_summary = String::from_utf8_lossy(&sitl_out.stdout);
    eprintln!("{s:?}\n{sitl_summary}");
    assert_eq!(
        (s["landed"].as_str(), s["disarmed"].as_str()),
        ("true", "true")
    );
    assert!((figure(&s, "max_alt_m") - 5.0).abs() < 0.3, "{s:?}");
    assert!(figure(&s, "hover_alt_rms_m") < 0.2, "{s:?}");
    assert!(figure(&s, "hover_drift_rms_m") < 0.5, "{s:?}");
    assert!(figure(&s, "attitude_rms_deg") < 1.5, "{s:?}");
    assert!(figure(&s, "touchdown_m_s") < 0.6, "{s:?}");
    assert_eq!(s["malformed"], "0");
    // Every packet was new (no resend needed in lockstep) and every one was answered.
    for kv in ["malformed=0", "stale=0"] {
        assert!(sitl_summary.contains(kv), "{sitl_summary}");
    }
}

/// `sitl --json` as ArduPilot's SITL sees it: each new servo packet moves the world one exchange
/// and is answered with one line of JSON; a resent packet (the same frame count) gets the same
/// answer without a step; garbage gets none and is counted.
#[test]
fn sitl_json_answers_servo_packets_as_ardupilot_expects() {
    let addr = format!("127.0.0.1:{}", free_port());
    let sitl = spawn(
        &sitl_exe(),
        &[
            "--json",
            &addr,
            "--status-interval",
            "0",
            "--duration",
            "300",
        ],
    );
    let ap = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    ap.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let packet = |count: u32, pwm: u16| {
        // struct { uint16_t magic = 18458; uint16_t frame_rate; uint32_t frame_count;
        // uint16_t pwm[16]; }
        let mut p = Vec::new();
        p.extend_from_slice(&18458u16.to_le_bytes());
        p.extend_from_slice(&400u16.to_le_bytes());
        p.extend_from_slice(&count.to_le_bytes());
        for _ in 0..16 {
            p.extend_from_slice(&pwm.to_le_bytes());
        }
        p
    };
    let mut buf = [0u8; 4096];
    // sitl may still be starting: send until it answers.
    let deadline = Instant::now() + Duration::from_secs(30);
    let first = loop {
        ap.send_to(&packet(1, 1000), &addr).unwrap();
        if let Ok(n) = ap.recv(&mut buf) {
            break String::from_utf8(buf[..n].to_vec()).unwrap();
        }
        assert!(Instant::now() < deadline, "no answer from sitl --json");
    };
    assert!(
        first.starts_with('\n') && first.ends_with('\n'),
        "{first:?}"
    );
    // Compact, as ArduPilot's reader needs: a space after a colon makes its vectors unreadable.
    assert!(!first.contains(": "), "{first:?}");
    let timestamp = |text: &str| -> f64 {
        let rest = &text[text.find("\"timestamp\":").unwrap() + 12..];
        rest[..rest.find(',').unwrap()].parse().unwrap()
    };
    let t1 = timestamp(&first);
    assert!((t1 - 0.004).abs() < 1e-9, "one exchange at 250 Hz: {first}");
    for key in [
        "\"gyro\"",
        "\"accel_body\"",
        "\"position\"",
        "\"velocity\"",
        "\"quaternion\"",
    ] {
        assert!(first.contains(key), "{key} in {first}");
    }
    // Resent packets may cross the first answer; drain, then resend once more.
    while ap.recv(&mut buf).is_ok() {}
    ap.send_to(&packet(1, 1000), &addr).unwrap();
    let n = ap.recv(&mut buf).unwrap();
    assert_eq!(
        timestamp(std::str::from_utf8(&buf[..n]).unwrap()),
        t1,
        "a resend: no step"
    );
    ap.send_to(&packet(2, 1500), &addr).unwrap();
    let n = ap.recv(&mut buf).unwrap();
    let t2 = timestamp(std::str::from_utf8(&buf[..n]).unwrap());
    assert!(
        (t2 - t1 - 0.004).abs() < 1e-9,
        "a new packet: one step ({t1} → {t2})"
    );
    ap.send_to(b"not a servo packet", &addr).unwrap();
    assert!(ap.recv(&mut buf).is_err(), "garbage gets no answer");
    let out = interrupt(sitl);
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(s.contains("malformed=1"), "{s}");
    assert!(!s.contains("stale=0"), "resends counted: {s}");
}

/// Noise-free sensors (`sitl --sensors ideal`) over UDP: the autopilot is not told they are
/// exact, and readings that repeat on a still vehicle are not frozen ones, so it arms, flies
/// and lands as the embedded simulator with the same preset does, to the byte.
#[test]
fn ideal_sensors_fly_over_udp_as_in_process() {
    let dir = tempfile::tempdir().unwrap();
    let (embedded_csv, udp_csv) = (dir.path().join("a.csv"), dir.path().join("udp.csv"));
    let mut args = vec![
        "--sim",
        "--speed",
        "max",
        "--sensors",
        "ideal",
        "--truth-csv",
        embedded_csv.to_str().unwrap(),
    ];
    args.extend(FLIGHT);
    let in_process = summary(&wait(
        spawn_autopilot(&args),
        "autopilot --sim --sensors ideal",
        Duration::from_secs(120),
    ));
    let port = free_port().to_string();
    let source = format!("udp://127.0.0.1:{port}");
    let mut args = vec!["--source", &source];
    args.extend(FLIGHT);
    let autopilot = spawn_autopilot(&args);
    let target = format!("127.0.0.1:{port}");
    let sitl = spawn_sitl(
        &["--autopilot", &target, "--sensors", "ideal"],
        "quad_x",
        1,
        &udp_csv,
    );
    let over_udp = summary(&wait(
        autopilot,
        "autopilot --source udp (sitl --sensors ideal)",
        Duration::from_secs(120),
    ));
    interrupt(sitl);
    println!("in process: {in_process:?}\nover UDP: {over_udp:?}");
    assert!(figure(&over_udp, "max_alt_m") > 4.8, "took off");
    assert_eq!(
        (over_udp["landed"].as_str(), over_udp["disarmed"].as_str()),
        ("true", "true")
    );
    for key in ["frames", "max_alt_m", "hover_alt_rms_m", "touchdown_m_s"] {
        assert_eq!(
            in_process[key], over_udp[key],
            "{key} in-process vs over UDP"
        );
    }
    let (a, udp) = (
        std::fs::read(&embedded_csv).unwrap(),
        std::fs::read(&udp_csv).unwrap(),
    );
    assert!(
        udp.len() >= a.len() && a[..] == udp[..a.len()],
        "truth over UDP differs from in-process"
    );
}
