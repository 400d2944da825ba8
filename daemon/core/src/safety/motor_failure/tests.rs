//! The detector against a rigid body it can be sure of: the airframe hovering, level, with the
//! rotors' true thrusts integrated through Euler's equation, one rotor made to lose thrust.

use super::*;
use std::path::PathBuf;

fn shipped(name: &str) -> Airframe {
    Airframe::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../params/airframes/{name}.toml")),
    )
    .unwrap()
}

/// What went wrong in the simulated hover.
#[derive(Clone, Copy)]
enum Fault {
    /// Rotor `.0` makes `1 − .1` of its thrust (its speed too when `.2`, as a stopped motor).
    Rotor(usize, f64, bool),
    /// An external moment about roll (N·m): the twist test.
    Torque(f64),
    /// An external upward force (N): an updraft.
    Lift(f64),
}

/// Hovers `name` for 1 s, then applies `fault` for 1 s; the detection and when (s after the
/// fault), with rpm reported when `rpm`, in the air when `in_air`.
fn run(name: &str, fault: Fault, rpm: bool, in_air: bool) -> Option<(MotorFailure, f64)> {
    let a = shipped(name);
    let n = a.rotors.len();
    let mut d = MotorFailureDetector::new(&a, MotorFailureParams::default());
    let hover_t = a.weight_n() / n as f64;
    let hover_w = a.rotors[0].speed_for_thrust_rad_s(1.225, hover_t);
    let thrust = vec![hover_t; n];
    let speed = vec![hover_w; n];
    let (mut omega, dt) = (Vector3::<f64>::zeros(), 0.004);
    let j = a.inertia_kg_m2;
    let mut real_t = vec![hover_t; n];
    let mut real_w = vec![hover_w; n];
    for k in 0..500 {
        let t = k as f64 * dt;
        let faulty = t >= 1.0;
        let (mut torque_ext, mut lift) = (Vector3::zeros(), 0.0);
        // The true rotors lag their set-points as the detector assumes.
        let lag = 1.0 - (-dt / a.rotors[0].time_constant_s).exp();
        for r in 0..n {
            let (mut t_goal, mut w_goal) = (thrust[r], speed[r]);
            match fault {
                Fault::Rotor(i, lost, stops) if faulty && i == r => {
                    t_goal *= 1.0 - lost;
                    if stops {
                        w_goal *= 1.0 - lost;
                    }
                }
                _ => {}
            }
            real_t[r] += lag * (t_goal - real_t[r]);
            real_w[r] += lag * (w_goal - real_w[r]);
        }
        match fault {
            Fault::Torque(m) if faulty => torque_ext.x = m,
            Fault::Lift(f) if faulty => lift = f,
            _ => {}
        }
        let mut moment = torque_ext;
        let mut total = lift;
        for (r, spec) in a.rotors.iter().enumerate() {
            moment.x += -spec.position_frd_m.y * real_t[r];
            moment.y += spec.position_frd_m.x * real_t[r];
            total += real_t[r];
        }
        // Euler's equation; the accelerometer reads the rotor force (and the updraft) over m.
        let omega_dot = j.try_inverse().unwrap() * (moment - omega.cross(&(j * omega)));
        omega += omega_dot * dt;
        let accel = Vector3::new(0.0, 0.0, -total / a.mass_kg);
        let out = d.step(&DetectorInput {
            dt,
            gyro: omega,
            accel,
            speed_setpoint: &speed,
            thrust_setpoint: &thrust,
            measured_speed: rpm.then_some(&real_w[..]),
            in_air,
        });
        if let Some(f) = out {
            return Some((f, t - 1.0));
        }
    }
    None
}

/// Every rotor of every airframe, stopped: found by the thrust imbalance alone, the right one,
/// within the 0.25 s, its whole thrust missing.
#[test]
fn a_stopped_rotor_is_found_by_thrust_imbalance_within_a_quarter_second() {
    for name in ["quad_x", "quad_plus", "hexa_x", "octa_x", "dodeca"] {
        let n = shipped(name).rotors.len();
        let mut slowest = 0.0f64;
        for r in 0..n {
            let (f, after) = run(name, Fault::Rotor(r, 1.0, true), false, true)
                .unwrap_or_else(|| panic!("{name} rotor {r}: not detected"));
            assert_eq!(
                (f.rotor, f.by),
                (r, Detection::ThrustImbalance),
                "{name} rotor {r}"
            );
            assert!(f.lost_fraction > 0.6, "{name} rotor {r}: {f:?}");
            slowest = slowest.max(after);
        }
        assert!(slowest <= 0.25, "{name}: {slowest:.3} s");
        println!("{name}: every rotor found within {slowest:.3} s");
    }
}

/// A quad has no spare rotor: one that stops is found by the imbalance alone within 0.05 s (its
/// spin-up tilts it about 5° more every 10 ms). Part of a rotor's thrust lost is not judged so
/// fast: 60 % waits for `FD_ACT_MOT_TOUT`, 40 % is left to the controllers; a hexa's stopped
/// rotor waits for the timeout too.
#[test]
fn a_quad_rotor_that_stops_is_found_at_once_a_partial_loss_is_not() {
    for name in ["quad_x", "quad_plus"] {
        let mut slowest = 0.0f64;
        for r in 0..4 {
            let (f, after) = run(name, Fault::Rotor(r, 1.0, true), false, true).unwrap();
            assert_eq!((f.rotor, f.by), (r, Detection::ThrustImbalance), "{name}");
            slowest = slowest.max(after);
        }
        println!("{name}: a stopped rotor found within {slowest:.3} s");
        assert!(slowest <= 0.05, "{name}: {slowest:.3} s");
    }
    let (f, after) = run("quad_x", Fault::Rotor(2, 0.6, false), false, true).unwrap();
    assert_eq!(f.rotor, 2);
    assert!(after >= 0.1, "60 % lost, found after {after:.3} s");
    assert!(run("quad_x", Fault::Rotor(2, 0.4, false), false, true).is_none());
    let (_, after) = run("hexa_x", Fault::Rotor(0, 1.0, true), false, true).unwrap();
    assert!(after >= 0.1, "a hexa's rotor found after {after:.3} s");
}

/// A quad's rotor whose thrust goes while its ESC reports it turning as told (a propeller lost):
/// the quick stop judgement stands down for the reading, and the imbalance waits its
/// `FD_ACT_MOT_TOUT`. The same loss unmeasured is judged at once.
#[test]
fn a_quad_rotor_reported_turning_as_told_is_not_judged_stopped_at_once() {
    let (f, after) = run("quad_x", Fault::Rotor(1, 1.0, false), true, true).unwrap();
    assert_eq!((f.rotor, f.by), (1, Detection::ThrustImbalance));
    assert!(after >= 0.1, "found after {after:.3} s");
    let (_, after) = run("quad_x", Fault::Rotor(1, 1.0, false), false, true).unwrap();
    assert!(after <= 0.05, "found after {after:.3} s");
}

/// With rpm reported, a stopped motor is seen by its speed as well; a chipped propeller
/// (70 % of thrust lost, speed normal) only by the imbalance; 30 % lost is left to the
/// controllers.
#[test]
fn rotor_speed_and_partial_thrust() {
    let (f, after) = run("hexa_x", Fault::Rotor(4, 1.0, true), true, true).unwrap();
    assert_eq!(f.rotor, 4);
    assert!(after <= 0.25);
    // On the ground only the rpm can tell.
    let (f, _) = run("hexa_x", Fault::Rotor(2, 1.0, true), true, false).unwrap();
    assert_eq!((f.rotor, f.by), (2, Detection::RotorSpeed));
    let (f, _) = run("octa_x", Fault::Rotor(3, 0.7, false), true, true).unwrap();
    assert_eq!((f.rotor, f.by), (3, Detection::ThrustImbalance));
    assert!((f.lost_fraction - 0.7).abs() < 0.15, "{f:?}");
    assert!(run("octa_x", Fault::Rotor(3, 0.3, false), true, true).is_none());
}

/// What is not a motor failure: the twist test's roll torque (40 rad/s² × J), an updraft of
/// a rotor's thrust, a stopped rotor felt through the ground (no rpm), a detector switched off.
#[test]
fn disturbances_ground_contact_and_disabled_detection_are_not_failures() {
    for name in ["quad_x", "hexa_x", "octa_x", "dodeca"] {
        let a = shipped(name);
        let twist = 40.0 * a.inertia_kg_m2[(0, 0)];
        assert!(
            run(name, Fault::Torque(twist), false, true).is_none(),
            "{name}"
        );
        assert!(
            run(name, Fault::Torque(-twist), false, true).is_none(),
            "{name}"
        );
        let rotor = a.weight_n() / a.rotors.len() as f64;
        assert!(
            run(name, Fault::Lift(rotor), false, true).is_none(),
            "{name}"
        );
        assert!(
            run(name, Fault::Lift(-rotor), false, true).is_none(),
            "{name}"
        );
        assert!(
            run(name, Fault::Rotor(1, 1.0, true), false, false).is_none(),
            "{name}"
        );
    }
    let a = shipped("hexa_x");
    let mut d = MotorFailureDetector::new(
        &a,
        MotorFailureParams {
            enabled: false,
            ..Default::default()
        },
    );
    let zeros = [0.0; 6];
    let thrust = [a.weight_n() / 6.0; 6];
    for _ in 0..100 {
        // Every rotor "stopped", the body in free fall: nothing is declared when off.
        let out = d.step(&DetectorInput {
            dt: 0.004,
            gyro: Vector3::zeros(),
            accel: Vector3::zeros(),
            speed_setpoint: &[900.0; 6],
            thrust_setpoint: &thrust,
            measured_speed: Some(&zeros),
            in_air: true,
        });
        assert!(out.is_none());
    }
}

/// Nonsense in (NaN, infinities, short slices) never panics, never declares a failure of a rotor
/// that does not exist and leaves no non-number in the filters; a declaration latches until
/// reset.
#[test]
fn nonsense_input_and_the_latch() {
    let a = shipped("quad_x");
    let mut d = MotorFailureDetector::new(&a, MotorFailureParams::default());
    for k in 0..200 {
        let x = if k % 2 == 0 { f64::NAN } else { f64::INFINITY };
        let found = d.step(&DetectorInput {
            dt: x,
            gyro: Vector3::repeat(x),
            accel: Vector3::repeat(-x),
            speed_setpoint: &[x, 1.0],
            thrust_setpoint: &[x],
            measured_speed: Some(&[]),
            in_air: true,
        });
        assert!(found.is_none_or(|f| f.rotor < 4));
    }
    // Nothing of it stays in the filters (a non-number there would last until disarm).
    let state = d
        .speed_lag
        .iter()
        .chain(&d.thrust_per_speed_sq)
        .chain(d.believed.iter());
    assert!(state.chain(d.rate_f.iter()).all(|x| x.is_finite()));
    assert!(d.force_f.is_finite());
    d.declare(2);
    d.declare(9);
    assert_eq!(d.failed(), [false, false, true, false]);
    d.reset();
    assert_eq!(d.failed(), [false; 4]);
}
