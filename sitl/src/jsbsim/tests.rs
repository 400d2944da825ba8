//! The link against a fake bridge (a UDP responder speaking the bridge's wire format), and the
//! start-up and shutdown against fake Pythons (shell scripts). The real bridge, with the pinned
//! JSBSim, flies in the Python end-to-end tests.

#![allow(clippy::unwrap_used)]
use super::*;
use nalgebra::Vector3;
use sitl_core::jsbsim::{M_PER_FT, N_PER_LBF};
use sitl_core::powertrain::RotorWrench;
use std::thread::JoinHandle;

fn quad() -> Airframe {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params/airframes");
    Airframe::load(&dir.join("quad_x.toml")).unwrap()
}

const HOME: LatLonAlt = LatLonAlt {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 400.0,
};

/// The fake's thread: when it ends, every request it received (number, values).
type Fake = JoinHandle<Vec<(u64, Vec<f64>)>>;

/// How the fake misbehaves.
#[derive(Clone, Copy, PartialEq)]
enum Fault {
    None,
    /// Stops answering after this many requests.
    SilentAfter(u64),
    /// Answers with the wrong sequence number.
    OutOfStep,
}

/// A bridge stand-in: climbs 1 cm per request, from the origin, and reports as its total body
/// force the rotor thrusts it was sent. Returns its address and, when it ends (on a request of
/// the wrong size, e.g. an empty one), every request it received.
fn fake(fault: Fault) -> (SocketAddr, Fake) {
    let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    let addr = socket.local_addr().unwrap();
    let inputs = input_properties(4).len();
    let handle = std::thread::spawn(move || {
        let mut seen = Vec::new();
        let mut buf = [0u8; 1024];
        loop {
            let (len, peer) = socket.recv_from(&mut buf).unwrap();
            if len != 8 * (1 + inputs) {
                return seen;
            }
            let word = |i: usize| <[u8; 8]>::try_from(&buf[8 * i..8 * i + 8]).unwrap();
            let sequence = u64::from_le_bytes(word(0));
            let values: Vec<f64> = (1..=inputs).map(|i| f64::from_le_bytes(word(i))).collect();
            let thrust_lbf: f64 = (0..4).map(|r| values[2 * r]).sum();
            seen.push((sequence, values));
            let k = seen.len() as u64;
            if matches!(fault, Fault::SilentAfter(n) if k > n) {
                continue;
            }
            let mut state = [0.0; STATE_PROPERTIES.len()];
            state[0] = k as f64 * 0.004;
            state[1] = HOME.lat_deg;
            state[2] = HOME.lon_deg;
            state[3] = (HOME.alt_m + 0.01 * k as f64) / M_PER_FT;
            state[6] = -2.5 / M_PER_FT; // climbing
            state[18] = -thrust_lbf;
            state[22] = 2116.22;
            state[23] = 518.67;
            state[24] = 0.0023769;
            let answer = if fault == Fault::OutOfStep {
                sequence + 1
            } else {
                sequence
            };
            let mut out = answer.to_le_bytes().to_vec();
            for v in state {
                out.extend_from_slice(&v.to_le_bytes());
            }
            socket.send_to(&out, peer).unwrap();
        }
    });
    (addr, handle)
}

fn bridge(fault: Fault, step_timeout: Duration) -> (Bridge, Fake) {
    let (addr, handle) = fake(fault);
    (
        Bridge::connect(addr, HOME, &quad(), step_timeout).unwrap(),
        handle,
    )
}

/// Ends the fake and returns what it received.
fn requests(b: &Bridge, fake: Fake) -> Vec<(u64, Vec<f64>)> {
    b.socket.send(&[]).unwrap();
    fake.join().unwrap()
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
fn each_step_is_one_numbered_request_and_its_reply_in_si() {
    let (mut b, fake) = bridge(Fault::None, Duration::from_secs(5));
    let mass = quad().mass_kg;
    for k in 1..=50 {
        let step = b.advance(&loads(2.0)).unwrap();
        // Reply k: 1 cm per request above the origin.
        assert!(
            (step.body.pos_ned_m.z + 0.01 * k as f64).abs() < 1e-6,
            "request {k}: {step:?}"
        );
        assert!((step.body.vel_ned_m_s.z + 2.5).abs() < 1e-9);
        // What was sent came back: four rotors at 2 N, in pounds and out again.
        assert!((step.specific_force_frd_m_s2.z + 8.0 / mass).abs() < 1e-6);
        assert!(!step.on_ground);
    }
    let seen = requests(&b, fake);
    assert_eq!(seen.len(), 50);
    assert!(
        seen.iter()
            .enumerate()
            .all(|(i, (n, _))| *n == i as u64 + 1)
    );
    let names = input_properties(4);
    let value = |name: &str| seen[49].1[names.iter().position(|n| n == name).unwrap()];
    assert!((value("bridge/rotor2-thrust-lbs") * N_PER_LBF - 2.0).abs() < 1e-12);
    assert!((value("bridge/rotor2-torque-lbsft") * N_PER_LBF * M_PER_FT + 0.1).abs() < 1e-12);
    assert!((value("bridge/aero-x-lbs") * N_PER_LBF - 1.0).abs() < 1e-12);
    assert!((value("bridge/aero-n-lbsft") * N_PER_LBF * M_PER_FT - 0.02).abs() < 1e-12);
}

#[test]
fn a_silent_bridge_fails_the_step_in_time_naming_the_request() {
    let (mut b, _) = bridge(Fault::SilentAfter(3), Duration::from_millis(300));
    for _ in 0..3 {
        b.advance(&loads(2.0)).unwrap();
    }
    let started = Instant::now();
    let e = b.advance(&loads(2.0)).unwrap_err().to_string();
    assert!(e.contains("no reply to request 4 within 300ms"), "{e}");
    assert!(started.elapsed() < Duration::from_secs(3));
}

#[test]
fn a_reply_out_of_step_fails_the_step() {
    let (mut b, _) = bridge(Fault::OutOfStep, Duration::from_secs(5));
    let e = b.advance(&loads(2.0)).unwrap_err().to_string();
    assert!(e.contains("reply 2 to request 1"), "{e}");
}

#[test]
fn non_finite_loads_are_refused_before_anything_is_sent() {
    let (mut b, fake) = bridge(Fault::None, Duration::from_secs(5));
    let mut bad = loads(2.0);
    bad.rotor.thrust_n[2] = f64::NAN;
    let e = b.advance(&bad).unwrap_err().to_string();
    assert!(
        e.contains("non-finite value for bridge/rotor3-thrust-lbs"),
        "{e}"
    );
    // The next good step is request 1, reply 1: nothing of the bad one left.
    let step = b.advance(&loads(2.0)).unwrap();
    assert!((step.body.pos_ned_m.z + 0.01).abs() < 1e-6);
    let seen = requests(&b, fake);
    assert_eq!(seen.len(), 1);
    assert_eq!(seen[0].0, 1);
}

/// A shell script standing in for the Python that runs the bridge (it gets the bridge's path and
/// arguments, and ignores them).
fn python(dir: &Path, body: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join("python");
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path
}

fn launch(python: &Path) -> Result<Jsbsim> {
    let a = quad();
    Jsbsim::launch(&Launch {
        python,
        airframe: &a,
        home: HOME,
        initial: BodyState::default(),
        rate_hz: 250.0,
        startup_timeout: Duration::from_secs(5),
        step_timeout: Duration::from_secs(2),
    })
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sitl-jsbsim-test-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_missing_python_says_how_to_get_one() {
    let e = format!(
        "{:#}",
        launch(Path::new("/nonexistent/python")).err().unwrap()
    );
    assert!(
        e.contains("jsbsim==1.3.3") && e.contains("--jsbsim-python"),
        "{e}"
    );
    assert!(e.contains("/nonexistent/python"), "{e}");
}

#[test]
fn a_bridge_that_exits_is_reported_with_its_words() {
    let dir = scratch("exits");
    let p = python(
        &dir,
        "echo 'jsbsim bridge: this Python has no jsbsim module' >&2\nexit 2",
    );
    let e = format!("{:#}", launch(&p).err().unwrap());
    assert!(
        e.contains("exited during start-up") && e.contains("has no jsbsim module"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_bridge_that_never_gets_ready_is_stopped_at_the_timeout() {
    let dir = scratch("slow");
    let p = python(&dir, "echo 'loading'\nsleep 30");
    let started = Instant::now();
    let e = format!("{:#}", launch(&p).err().unwrap());
    assert!(
        e.contains("not ready within") && e.contains("loading"),
        "{e}"
    );
    assert!(started.elapsed() < Duration::from_secs(20));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_bridge_gets_its_program_model_and_properties_and_ends_when_sitl_lets_go() {
    let dir = scratch("args");
    let args = dir.join("args");
    let ended = dir.join("ended");
    // Says where it listens (nobody: steps fail), then waits for its standard input to close.
    let p = python(
        &dir,
        &format!(
            "echo \"$@\" > {}\necho 'ready 9'\nread -r _\necho bye > {}",
            args.display(),
            ended.display()
        ),
    );
    let mut jsb = launch(&p).unwrap();
    let args = std::fs::read_to_string(&args).unwrap();
    let program = args.split_whitespace().next().unwrap();
    assert!(program.ends_with("/bridge.py"), "{args}");
    assert_eq!(std::fs::read_to_string(program).unwrap(), BRIDGE_PY);
    let root = Path::new(program).parent().unwrap().to_owned();
    let model = root.join("aircraft").join(MODEL_NAME);
    assert!(model.join(format!("{MODEL_NAME}.xml")).exists());
    assert!(args.contains(&format!("--initfile {}", model.join("start.xml").display())));
    assert!(args.contains("--rate=250 --frames=4"), "{args}");
    assert!(args.contains(&format!("--inputs={}", input_properties(4).join(","))));
    assert!(args.contains("--outputs=simulation/sim-time-sec,position/lat-geod-deg"));
    // Nobody answers on port 9: the step fails within its deadline, and says so.
    let e = jsb.advance(&loads(2.0)).unwrap_err().to_string();
    assert!(e.contains("request 1"), "{e}");
    let started = Instant::now();
    drop(jsb);
    assert_eq!(std::fs::read_to_string(&ended).unwrap(), "bye\n");
    assert!(started.elapsed() < Duration::from_secs(3));
    assert!(!root.exists(), "the root is removed");
    let _ = std::fs::remove_dir_all(dir);
}
