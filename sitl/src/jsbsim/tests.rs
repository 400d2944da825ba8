//! The bridge against a fake JSBSim (a TCP command server and a UDP state sender that behave as
//! the pinned JSBSim does, recorded in `sitl_core::jsbsim`), and the start-up against fake
//! programs. The real JSBSim flies in the Python end-to-end tests.

#![allow(clippy::unwrap_used)]
use super::*;
use nalgebra::Vector3;
use sitl_core::jsbsim::{M_PER_FT, N_PER_LBF, STATE_PROPERTIES};
use sitl_core::powertrain::RotorWrench;
use std::collections::HashMap;
use std::thread::JoinHandle;

fn quad() -> Airframe {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params/airframes");
    Airframe::load(&dir.join("quad_x.toml")).unwrap()
}

const HOME: Geodetic = Geodetic {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 400.0,
};

/// How the fake misbehaves.
#[derive(Clone, Copy)]
enum Fault {
    None,
    /// Answers `Unknown property` to this one and, as JSBSim, silently drops the batch's
    /// iterate.
    Refuse(&'static str),
    /// Stops sending state after this frame.
    SilentAfter(u64),
}

/// What the fake received.
#[derive(Default)]
struct Seen {
    batches: usize,
    values: HashMap<String, f64>,
    sets: usize,
}

/// A JSBSim stand-in: climbs 1 cm per frame and reports as its total body force the rotor
/// thrusts it was sent, re-sending the previous frame before each new one as JSBSim does.
fn fake(state_port: u16, fault: Fault) -> (u16, Arc<Mutex<Seen>>, JoinHandle<()>) {
    let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    let port = listener.local_addr().unwrap().port();
    let seen = Arc::new(Mutex::new(Seen::default()));
    let seen_ = seen.clone();
    let handle = std::thread::spawn(move || {
        let (stream, _) = listener.accept().unwrap();
        let udp = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
        udp.connect((Ipv4Addr::LOCALHOST, state_port)).unwrap();
        udp.send(b"<LABELS> ,Time,frame,...\n").unwrap();
        let mut out = stream.try_clone().unwrap();
        out.write_all(b"Connected to JSBSim server\r\nJSBSim> ")
            .unwrap();
        let line_of = |frame: u64, thrust_lbf: f64| {
            let mut v = vec![0.0; STATE_PROPERTIES.len() + 1];
            v[0] = frame as f64 * 0.004;
            v[1] = frame as f64;
            v[4] = 0.01 * frame as f64 / M_PER_FT; // offsets from the origin
            v[7] = -2.5 / M_PER_FT; // climbing
            v[19] = -thrust_lbf;
            v[23] = 2116.22;
            v[24] = 518.67;
            v[25] = 0.0023769;
            let text: Vec<String> = v.iter().map(|x| format!("{x:>12}")).collect();
            text.join(",") + "\n"
        };
        let mut frame = 0;
        let mut cancelled = false;
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            let mut s = seen_.lock().unwrap();
            if let Some(rest) = line.strip_prefix("set ") {
                let (name, value) = rest.split_once(' ').unwrap();
                if matches!(fault, Fault::Refuse(p) if p == name) {
                    out.write_all(b"Unknown property\r\nJSBSim> ").unwrap();
                    cancelled = true;
                } else {
                    s.values.insert(name.to_owned(), value.parse().unwrap());
                    s.sets += 1;
                    out.write_all(b"set successful\r\nJSBSim> ").unwrap();
                }
            } else if line == "iterate 1" {
                s.batches += 1;
                if std::mem::take(&mut cancelled)
                    || matches!(fault, Fault::SilentAfter(n) if frame >= n)
                {
                    continue;
                }
                let thrust: f64 = (1..=4)
                    .map(|i| s.values[&format!("bridge/rotor{i}-thrust-lbs")])
                    .sum();
                if frame > 0 {
                    udp.send(line_of(frame, thrust).as_bytes()).unwrap();
                }
                frame += 1;
                udp.send(line_of(frame, thrust).as_bytes()).unwrap();
                out.write_all(b"Iterations performed\r\nJSBSim> ").unwrap();
            }
        }
    });
    (port, seen, handle)
}

fn bridge(fault: Fault, step_timeout: Duration) -> (Bridge, Arc<Mutex<Seen>>, JoinHandle<()>) {
    let state = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    let (port, seen, handle) = fake(state.local_addr().unwrap().port(), fault);
    let deadline = Instant::now() + Duration::from_secs(5);
    let b = Bridge::connect(port, state, HOME, &quad(), step_timeout, deadline).unwrap();
    (b, seen, handle)
}

/// Every rotor at `thrust_n`.
fn loads(thrust_n: f64) -> StepLoads {
    let mut rotor = RotorWrench {
        force_frd_n: Vector3::new(0.0, 0.0, -4.0 * thrust_n),
        torque_frd_n_m: Vector3::zeros(),
        rotor_momentum_frd: Vector3::zeros(),
        shaft_power_w: 0.0,
        thrust_n: Default::default(),
        yaw_moment_n_m: Default::default(),
    };
    rotor.thrust_n[..4].fill(thrust_n);
    rotor.yaw_moment_n_m[..4].copy_from_slice(&[0.1, -0.1, 0.1, -0.1]);
    StepLoads {
        dt_s: 0.004,
        rotor,
        aero_force_frd_n: Vector3::new(1.0, 0.0, 0.0),
        aero_moment_frd_n_m: Vector3::new(0.0, 0.0, 0.02),
    }
}

#[test]
fn the_bridge_takes_each_frame_once_and_converts_it() {
    let (mut b, seen, handle) = bridge(Fault::None, Duration::from_secs(5));
    let mass = quad().mass_kg;
    for k in 1..=50 {
        let step = b.advance(&loads(2.0)).unwrap();
        // Frame k, not the stale k − 1 sent before it: 1 cm per frame above the origin.
        assert!(
            (step.body.pos_ned_m.z + 0.01 * k as f64).abs() < 1e-6,
            "frame {k}: {step:?}"
        );
        assert!((step.body.vel_ned_m_s.z + 2.5).abs() < 1e-9);
        // What was sent came back: four rotors at 2 N, in pounds and out again.
        assert!((step.specific_force_frd_m_s2.z + 8.0 / mass).abs() < 1e-6);
        assert!(!step.on_ground);
    }
    let s = seen.lock().unwrap();
    assert_eq!(s.batches, 50);
    assert_eq!(s.sets, 50 * (4 * 2 + 6));
    assert!((s.values["bridge/rotor2-thrust-lbs"] * N_PER_LBF - 2.0).abs() < 1e-6);
    assert!((s.values["bridge/rotor2-torque-lbsft"] * N_PER_LBF * M_PER_FT + 0.1).abs() < 1e-6);
    assert!((s.values["bridge/aero-x-lbs"] * N_PER_LBF - 1.0).abs() < 1e-6);
    drop(s);
    assert!(b.replies.errors.is_empty(), "{:?}", b.replies.errors);
    drop(b);
    handle.join().unwrap(); // the fake saw the command port close
}

#[test]
fn a_refused_property_fails_the_step_with_jsbsims_reply() {
    let (mut b, _, _) = bridge(
        Fault::Refuse("bridge/aero-n-lbsft"),
        Duration::from_secs(30),
    );
    let started = Instant::now();
    let e = b.advance(&loads(2.0)).unwrap_err().to_string();
    // Told at once, not at the step's timeout.
    assert!(started.elapsed() < Duration::from_secs(10));
    assert!(
        e.contains("refused a command") && e.contains("Unknown property"),
        "{e}"
    );
}

#[test]
fn a_silent_jsbsim_fails_the_step_in_time_naming_the_frame() {
    let (mut b, _, _) = bridge(Fault::SilentAfter(3), Duration::from_millis(300));
    for _ in 0..3 {
        b.advance(&loads(2.0)).unwrap();
    }
    let started = Instant::now();
    let e = b.advance(&loads(2.0)).unwrap_err().to_string();
    assert!(e.contains("no state for frame 4"), "{e}");
    assert!(started.elapsed() < Duration::from_secs(3));
}

#[test]
fn non_finite_loads_are_refused_before_anything_is_sent() {
    let (mut b, seen, _) = bridge(Fault::None, Duration::from_secs(5));
    let mut bad = loads(2.0);
    bad.rotor.thrust_n[2] = f64::NAN;
    let e = b.advance(&bad).unwrap_err().to_string();
    assert!(
        e.contains("non-finite value for bridge/rotor3-thrust-lbs"),
        "{e}"
    );
    // The next good step is frame 1: nothing of the bad batch reached JSBSim.
    let step = b.advance(&loads(2.0)).unwrap();
    assert!((step.body.pos_ned_m.z + 0.01).abs() < 1e-6);
    assert_eq!(seen.lock().unwrap().batches, 1);
}

/// A shell script standing in for JSBSim's console program.
fn program(dir: &Path, body: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join("jsbsim");
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path
}

fn launch(program: &Path) -> Result<Jsbsim> {
    let a = quad();
    Jsbsim::launch(&Launch {
        program,
        airframe: &a,
        home: HOME,
        initial: BodyState::default(),
        rate_hz: 250.0,
        startup_timeout: Duration::from_secs(5),
        step_timeout: Duration::from_secs(1),
    })
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sitl-jsbsim-test-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_missing_program_says_how_to_get_one() {
    let e = format!(
        "{:#}",
        launch(Path::new("/nonexistent/jsbsim")).err().unwrap()
    );
    assert!(e.contains("jsbsim==1.3.3") && e.contains("--jsbsim"), "{e}");
    assert!(e.contains("/nonexistent/jsbsim"), "{e}");
}

#[test]
fn a_program_that_exits_is_reported_with_its_words() {
    let dir = scratch("exits");
    let p = program(&dir, "echo 'Could not open aircraft file' >&2\nexit 1");
    let e = format!("{:#}", launch(&p).err().unwrap());
    assert!(
        e.contains("exited during start-up") && e.contains("Could not open aircraft file"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_taken_command_port_is_tried_three_times_then_reported() {
    let dir = scratch("taken");
    let count = dir.join("count");
    let p = program(
        &dir,
        &format!(
            "echo x >> {}\necho 'Could not bind to TCP input socket'\nsleep 30",
            count.display()
        ),
    );
    let started = Instant::now();
    let e = format!("{:#}", launch(&p).err().unwrap());
    assert!(e.contains("was taken"), "{e}");
    assert_eq!(std::fs::read_to_string(&count).unwrap().lines().count(), 3);
    // Each attempt's process was stopped, not waited out.
    assert!(started.elapsed() < Duration::from_secs(20));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_program_that_never_gets_ready_is_stopped_at_the_timeout() {
    let dir = scratch("slow");
    let p = program(&dir, "echo 'loading'\nsleep 30");
    let started = Instant::now();
    let e = format!("{:#}", launch(&p).err().unwrap());
    assert!(
        e.contains("not ready within") && e.contains("loading"),
        "{e}"
    );
    assert!(started.elapsed() < Duration::from_secs(20));
    let _ = std::fs::remove_dir_all(dir);
}
