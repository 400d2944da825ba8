use super::*;
use crate::sensors::{SensorHealth, SensorKind};
use crate::sim::SimAction;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes")
}

const FULL: &str = r#"
airframe = "hexa_x"
seed = 7
duration_s = 20.0
rate_hz = 500.0
integrator = "exp_map"
sensors = "noisy"
[home]
lat_deg = -33.9
lon_deg = 18.4
alt_m = 10.0
[initial]
position_ned_m = [1.0, 2.0, -3.0]
attitude_euler_deg = [0.0, 0.0, 90.0]
rotors_at_hover = true
[wind]
mean_ned_m_s = [3.0, 0.0, 0.0]
turbulence_w20_m_s = 7.7
[battery]
charge = 0.3
capacity_mah = 800.0
[[events]]
t_s = 5.0
kind = "motor_fail"
motor = 6
[[events]]
t_s = 6.0
kind = "sensor_off"
sensor = "gps"
duration_s = 2.0
[[events]]
t_s = 7.0
kind = "torque_pulse"
torque_frd_n_m = [1.0, 0.0, 0.0]
duration_s = 3.0
[[events]]
t_s = 12.0
kind = "tumble"
duration_s = 60.0
[[open_loop]]
t_s = 1.0
hover_delta = 0.02
[[open_loop]]
t_s = 0.0
throttle = 0.1
"#;

#[test]
fn a_full_scenario_resolves() {
    let s = Scenario::from_toml_str(FULL, "full.toml", &dir()).unwrap();
    assert_eq!(s.airframe.name, "hexa_x");
    assert_eq!((s.sim.seed, s.sim.integrator), (7, Integrator::ExpMap));
    assert!((s.sim.dt_s - 0.002).abs() < 1e-15);
    assert_eq!(s.sim.home.lat_deg, -33.9);
    assert!(s.rotors_at_hover);
    assert_eq!(
        (s.sim.battery_charge, s.airframe.battery.capacity_mah),
        (0.3, 800.0)
    );
    assert!(
        (s.initial.q_ned_from_frd.euler_angles().2 - std::f64::consts::FRAC_PI_2).abs() < 1e-12
    );
    // motor 6 is index 5; the GPS comes back after its duration.
    assert_eq!(s.events[0].action, SimAction::MotorFail { index: 5 });
    assert!(s.events.contains(&Event {
        t_s: 8.0,
        action: SimAction::Sensor {
            sensor: SensorKind::Gps,
            health: SensorHealth::Ok
        }
    }));
    assert!(s.events.contains(&Event {
        t_s: 12.0,
        action: SimAction::Tumble { duration_s: 60.0 }
    }));
    // The script is sorted by time.
    assert_eq!(s.open_loop_at(0.5), Some(&OpenLoopCommand::Throttle(0.1)));
    assert_eq!(
        s.open_loop_at(3.0),
        Some(&OpenLoopCommand::HoverDelta(0.02))
    );
}

fn err(text: &str) -> String {
    Scenario::from_toml_str(text, "bad.toml", &dir())
        .unwrap_err()
        .to_string()
}

#[test]
fn bad_scenarios_are_refused_naming_file_key_and_reason() {
    let e = err(&FULL.replace("motor = 6", "motor = 7"));
    assert!(
        e.starts_with("bad.toml:")
            && e.contains("`events[0].motor`: must be within [1, 6] for airframe hexa_x, got 7"),
        "{e}"
    );
    let e = err(&FULL.replace("kind = \"motor_fail\"", "kind = \"motor_explode\""));
    assert!(e.contains("motor_explode"), "{e}");
    let e = err(&FULL.replace("hover_delta = 0.02", "hover_delta = 0.02\nthrottle = 0.3"));
    assert!(e.contains("`open_loop[0]`: give exactly one of"), "{e}"); // index in the file
    let e = err(&FULL.replace("duration_s = 60.0", "duration_s = -1.0"));
    assert!(e.contains("`events[3].duration_s`"), "{e}");
    let e = err(&FULL.replace("rate_hz = 500.0", "rate_hz = 5.0"));
    assert!(
        e.contains("`rate_hz`: must be within [20, 10000], got 5"),
        "{e}"
    );
    let e = err(&FULL.replace("turbulence_w20_m_s = 7.7", "turbulence_w20_m_s = nan"));
    assert!(e.contains("`wind.turbulence_w20_m_s`"), "{e}");
    let e = err(&FULL.replace("integrator = \"exp_map\"", "integrator = \"verlet\""));
    assert!(e.contains("verlet"), "{e}");
    let e = err(&FULL.replace("charge = 0.3", "charge = 1.3"));
    assert!(
        e.contains("`battery.charge`: must be within [0, 1], got 1.3"),
        "{e}"
    );
    let e = err(&FULL.replace("seed = 7", "seed = 7\ncolour = \"red\""));
    assert!(e.contains("colour"), "{e}");
}
