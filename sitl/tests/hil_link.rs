//! The `sitl` process driven over UDP as an autopilot drives it.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use mavlink::MavHeader;
use mavlink::dialects::common::{
    HIL_ACTUATOR_CONTROLS_DATA, HilActuatorControlsFlags, MavMessage, MavModeFlag,
};
use std::net::UdpSocket;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const HOVER_SCENARIO: &str = r#"
airframe = "quad_x"
duration_s = 0.4
sensors = "ideal"
[initial]
position_ned_m = [0.0, 0.0, -10.0]
rotors_at_hover = true
"#;

struct Autopilot {
    socket: UdpSocket,
    sim: Option<std::net::SocketAddr>,
    seq: u8,
}

impl Autopilot {
    fn new() -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        Self {
            socket,
            sim: None,
            seq: 0,
        }
    }

    fn port(&self) -> u16 {
        self.socket.local_addr().unwrap().port()
    }

    /// Next datagram's messages; None when the simulator has gone quiet for the timeout.
    fn recv(&mut self) -> Option<Vec<MavMessage>> {
        let mut buf = [0u8; 4096];
        let (n, from) = self.socket.recv_from(&mut buf).ok()?;
        self.sim = Some(from);
        let mut reader = mavlink::MavlinkReader::new(&buf[..n]);
        let mut out = Vec::new();
        while let Ok((_, m)) = reader.read_any_message::<MavMessage>() {
            out.push(m);
        }
        Some(out)
    }

    fn send_raw(&self, bytes: &[u8]) {
        self.socket.send_to(bytes, self.sim.unwrap()).unwrap();
    }

    fn actuators(&mut self, time_usec: u64, value: f32, armed: bool) -> Vec<u8> {
        let msg = MavMessage::HIL_ACTUATOR_CONTROLS(HIL_ACTUATOR_CONTROLS_DATA {
            time_usec,
            flags: HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP,
            controls: [value; 16],
            mode: if armed {
                MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
            } else {
                MavModeFlag::empty()
            },
        });
        let mut out = Vec::new();
        mavlink::write_v2_msg(
            &mut out,
            MavHeader {
                system_id: 1,
                component_id: 1,
                sequence: self.seq,
            },
            &msg,
        )
        .unwrap();
        self.seq = self.seq.wrapping_add(1);
        out
    }

    fn reply(&mut self, time_usec: u64, value: f32, armed: bool) {
        let bytes = self.actuators(time_usec, value, armed);
        self.send_raw(&bytes);
    }
}

fn sensor_time(msgs: &[MavMessage]) -> (u64, f32, f32) {
    msgs.iter()
        .find_map(|m| match m {
            MavMessage::HIL_SENSOR(s) => Some((s.time_usec, s.zacc, s.pressure_alt)),
            _ => None,
        })
        .expect("every datagram carries HIL_SENSOR")
}

fn spawn(scenario: &str, port: u16, extra: &[&str]) -> (Child, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(&path, scenario).unwrap();
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/../params");
    let child = Command::new(env!("CARGO_BIN_EXE_sitl"))
        .args([
            "--scenario",
            path.to_str().unwrap(),
            "--params-dir",
            params,
            "--status-interval",
            "0",
            "--connect-timeout",
            "20",
        ])
        .args(["--autopilot", &format!("127.0.0.1:{port}")])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (child, dir)
}

fn summary(child: Child) -> std::collections::HashMap<String, String> {
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "sitl failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("sitl summary:"))
        .expect("summary line");
    line.split_whitespace()
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .collect()
}

/// Physics advances exactly one exchange interval per answered frame, and not before.
#[test]
fn lockstep_waits_for_each_answer_and_advances_by_one_interval() {
    let mut ap = Autopilot::new();
    let (child, _dir) = spawn(HOVER_SCENARIO, ap.port(), &[]);
    // Do not answer the first frame: the simulator must send the same time again.
    let (t0, _, _) = sensor_time(&ap.recv().unwrap());
    let (t0_again, _, _) = sensor_time(&ap.recv().unwrap());
    assert_eq!(t0, t0_again, "physics advanced without an answer");
    ap.reply(t0, 0.0, false);
    let mut last = t0;
    let mut frames = 0;
    while let Some(msgs) = ap.recv() {
        let (t, _, _) = sensor_time(&msgs);
        assert_eq!(t, last + 4000, "one 250 Hz interval per answer");
        last = t;
        frames += 1;
        ap.reply(t, 0.0, false);
        if t >= 396_000 {
            break;
        }
    }
    assert!(frames >= 99, "{frames}");
    let s = summary(child);
    assert_eq!(s["lockstep_timeouts"], "0");
    assert_eq!(s["stale"], "0");
    assert_eq!(s["malformed"], "0");
}

/// Unanswered frames after the link is up are counted as timeouts, never silently.
#[test]
fn lockstep_timeouts_are_counted() {
    let mut ap = Autopilot::new();
    let (child, _dir) = spawn(HOVER_SCENARIO, ap.port(), &["--timeout-ms", "50"]);
    let mut unanswered = 0;
    let mut n = 0;
    while let Some(msgs) = ap.recv() {
        let (t, _, _) = sensor_time(&msgs);
        n += 1;
        if (10..15).contains(&n) {
            unanswered += 1; // stay silent for five frames
            continue;
        }
        ap.reply(t, 0.0, false);
        if t >= 396_000 {
            break;
        }
    }
    assert_eq!(unanswered, 5);
    assert_eq!(summary(child)["lockstep_timeouts"], "5");
}

/// Garbage, a corrupted frame and a reply to an old frame are dropped and counted.
#[test]
fn malformed_and_stale_replies_are_counted() {
    let mut ap = Autopilot::new();
    let (child, _dir) = spawn(HOVER_SCENARIO, ap.port(), &[]);
    let mut n = 0;
    while let Some(msgs) = ap.recv() {
        let (t, _, _) = sensor_time(&msgs);
        n += 1;
        if n == 3 {
            ap.send_raw(b"\x00\x01garbage that is not mavlink");
            let mut bad = ap.actuators(t, 0.0, false);
            let k = bad.len() - 1;
            bad[k] ^= 0x55;
            ap.send_raw(&bad);
            ap.reply(t.saturating_sub(4000), 0.0, false); // stale
        }
        ap.reply(t, 0.0, false);
        if t >= 396_000 {
            break;
        }
    }
    let s = summary(child);
    assert_eq!(s["malformed"], "2");
    assert_eq!(s["stale"], "1");
    assert_eq!(s["lockstep_timeouts"], "0");
}

/// Commands without the armed flag leave the motors off; armed full throttle climbs.
#[test]
fn motors_run_only_when_armed() {
    let landed = "airframe = \"quad_x\"\nduration_s = 1.0\nsensors = \"ideal\"\n";
    let mut ap = Autopilot::new();
    let (child, _dir) = spawn(landed, ap.port(), &[]);
    let mut alt0 = None;
    let mut alt_end = 0.0;
    while let Some(msgs) = ap.recv() {
        let (t, zacc, alt) = sensor_time(&msgs);
        alt0.get_or_insert(alt);
        if t < 400_000 {
            assert!(
                (zacc + 9.80665).abs() < 1e-3,
                "unarmed: resting on the ground, got {zacc}"
            );
            ap.reply(t, 1.0, false);
        } else {
            ap.reply(t, 0.9, true);
        }
        alt_end = alt;
        if t >= 996_000 {
            break;
        }
    }
    assert!(
        alt_end - alt0.unwrap() > 0.5,
        "armed full throttle must climb: {alt0:?} → {alt_end}"
    );
    summary(child);
}

#[test]
fn bad_scenario_is_refused_naming_file_and_key() {
    let (child, dir) = spawn("airframe = \"quad_x\"\nduration_s = -1.0\n", 9, &[]);
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(dir.path().join("s.toml").to_str().unwrap()),
        "{err}"
    );
    assert!(
        err.contains("`duration_s`: must be a finite number > 0, got -1"),
        "{err}"
    );

    let (child, _dir) = spawn(
        "airframe = \"quad_x\"\nduration_s = 1.0\nwind_speed = 3\n",
        9,
        &[],
    );
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("wind_speed"));

    let (child, _dir) = spawn("airframe = \"hexacopter\"\nduration_s = 1.0\n", 9, &[]);
    let out = child.wait_with_output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("hexacopter.toml: cannot read"));
}

#[test]
fn open_loop_demo_flies_lands_and_writes_truth() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("truth.csv");
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let out = Command::new(env!("CARGO_BIN_EXE_sitl"))
        .current_dir(root)
        .args([
            "--scenario",
            "params/scenarios/demo_open_loop.toml",
            "--open-loop",
            "--truth-csv",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("touchdowns=1"), "{stdout}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("t_s,n_m,e_m,d_m,"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 2200, "100 Hz for 22 s");
    let max_alt = rows.iter().map(|r| -r[3]).fold(0.0, f64::max);
    assert!(
        (5.0..8.0).contains(&max_alt),
        "climbs to about 6 m, got {max_alt}"
    );
    assert_eq!(rows.last().unwrap()[14], 1.0, "landed at the end");
}

/// Real time: physics never waits for the autopilot, and simulated time never runs ahead of
/// wall time × speed (pacing by absolute deadlines gives that lower bound on wall time).
#[test]
fn realtime_mode_does_not_wait_and_is_paced() {
    let ap = Autopilot::new();
    let (child, _dir) = spawn(
        HOVER_SCENARIO,
        ap.port(),
        &["--mode", "realtime", "--speed", "4"],
    );
    let s = summary(child); // nobody answers: it must still finish
    let sim: f64 = s["sim_time_s"].parse().unwrap();
    let wall: f64 = s["wall_time_s"].parse().unwrap();
    assert!((sim - 0.4).abs() < 1e-9);
    assert!(
        wall >= sim / 4.0 * 0.99,
        "ran ahead of 4x real time: {wall} s for {sim} s"
    );
    assert_eq!(s["lockstep_timeouts"], "0");
    assert_eq!(s["actuator_messages"], "0");
}

/// Lockstep with `--speed`: still one interval per answer, and no faster than the cap, counted
/// from the first answer (the wait for an autopilot is not caught up in a burst).
#[test]
fn lockstep_with_a_speed_is_capped_and_still_waits_for_each_answer() {
    let mut ap = Autopilot::new();
    let (child, _dir) = spawn(HOVER_SCENARIO, ap.port(), &["--speed", "2"]);
    let (t0, _, _) = sensor_time(&ap.recv().unwrap());
    std::thread::sleep(Duration::from_millis(300)); // an autopilot that starts late
    let answered = Instant::now();
    ap.reply(t0, 0.0, false);
    let mut last = t0;
    while let Some(msgs) = ap.recv() {
        let (t, _, _) = sensor_time(&msgs);
        if t == last {
            continue; // a frame re-sent before the first answer arrived
        }
        assert_eq!(t, last + 4000, "one 250 Hz interval per answer");
        last = t;
        ap.reply(t, 0.0, false);
        if t >= 396_000 {
            break;
        }
    }
    let wall = answered.elapsed().as_secs_f64();
    let sim = (last - t0) as f64 * 1e-6;
    assert!(
        wall >= sim / 2.0 * 0.99,
        "ran ahead of 2x: {wall} s for {sim} s"
    );
    assert_eq!(summary(child)["lockstep_timeouts"], "0");
}

#[test]
fn lockstep_gives_up_when_no_autopilot_answers_within_the_connect_timeout() {
    let ap = Autopilot::new();
    let (child, _dir) = spawn(HOVER_SCENARIO, ap.port(), &["--connect-timeout", "0.3"]);
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no autopilot answered"));
}
