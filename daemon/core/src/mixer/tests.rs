use super::*;
use sitl_core::powertrain::{Rotors, steady_wrench};
use std::path::PathBuf;

fn shipped(name: &str) -> Airframe {
    Airframe::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../params/airframes/{name}.toml")),
    )
    .unwrap()
}

const ALL: [&str; 5] = ["quad_x", "quad_plus", "hexa_x", "octa_x", "dodeca"];
const RHO: f64 = 1.17;
const V: f64 = 16.0;

/// The pack's nominal voltage (3.8 V per cell): a 6S airframe cannot be flown on 4S volts.
fn nominal_v(a: &Airframe) -> f64 {
    a.battery.cells as f64 * 3.8
}

fn input(thrust: f64, torque: Vector3<f64>, v: f64) -> MixerInput {
    MixerInput {
        request: WrenchRequest {
            thrust_n: thrust,
            torque_frd_n_m: torque,
        },
        battery_v: v,
        air_density: RHO,
    }
}

/// Lewis (4.35)–(4.38) for the "+" quad with F_z counted up:
/// F₁ = M_z/4c − M_y/2d + F_z/4, F₂ = −M_z/4c − M_x/2d + F_z/4, F₃ = M_z/4c + M_y/2d + F_z/4,
/// F₄ = −M_z/4c + M_x/2d + F_z/4.
#[test]
fn quad_plus_allocation_is_lewis_closed_form_inverse() {
    let a = shipped("quad_plus");
    let m = Mixer::new(&a).unwrap();
    let (d, c) = (
        0.225,
        a.rotors[0].k_q * a.rotors[0].diameter_m / a.rotors[0].k_t,
    );
    let (fz, mx, my, mz) = (14.0, 0.3, -0.2, 0.05);
    let lewis = [
        mz / (4.0 * c) - my / (2.0 * d) + fz / 4.0,
        -mz / (4.0 * c) - mx / (2.0 * d) + fz / 4.0,
        mz / (4.0 * c) + my / (2.0 * d) + fz / 4.0,
        -mz / (4.0 * c) + mx / (2.0 * d) + fz / 4.0,
    ];
    let out = m.mix(&input(fz, Vector3::new(mx, my, mz), V));
    for (i, expected) in lewis.iter().enumerate() {
        let got = out.thrust_n[i];
        assert!(
            (got - expected).abs() < 1e-9,
            "rotor {}: {got} vs {expected}",
            i + 1
        );
    }
}

/// The request, allocated, commanded, turned into rotor speeds by the simulator's motor model
/// and into a wrench by its force model, comes back unchanged on every airframe. A motor-order or
/// spin-direction mistake anywhere fails this.
#[test]
fn requested_wrench_comes_back_through_the_simulators_force_model() {
    let mut rng = sitl_core::rng::Rng::stream(5, 5);
    for name in ALL {
        let a = shipped(name);
        let m = Mixer::new(&a).unwrap();
        let w = a.weight_n();
        for _ in 0..50 {
            let thrust = w * (0.6 + 0.8 * rng.uniform());
            let torque = Vector3::new(rng.normal() * 0.1, rng.normal() * 0.1, rng.normal() * 0.02)
                * (w / 15.0);
            let v = nominal_v(&a);
            let out = m.mix(&input(thrust, torque, v));
            assert!(
                out.unallocated.thrust_n.abs() < 1e-9
                    && out.unallocated.torque_frd_n_m.norm() < 1e-9,
                "{name}: feasible request not met: {:?}",
                out.unallocated
            );
            let speeds: Vec<f64> = a
                .rotors
                .iter()
                .enumerate()
                .map(|(i, r)| Rotors::commanded_speed(r, out.commands[i], v))
                .collect();
            let got = steady_wrench(&a, &speeds, RHO); // [F_z, M_x, M_y, M_z]
            let rel = |x: f64, y: f64| (x - y).abs() / (1.0 + y.abs());
            assert!(
                rel(-got[0], thrust) < 1e-9,
                "{name}: thrust {} vs {thrust}",
                -got[0]
            );
            for k in 0..3 {
                assert!(
                    rel(got[k + 1], torque[k]) < 1e-9,
                    "{name}: moment {k}: {} vs {}",
                    got[k + 1],
                    torque[k]
                );
            }
        }
    }
}

/// Saturation: roll/pitch kept whole, the collective moved to make room, yaw given what is left.
#[test]
fn saturation_keeps_attitude_authority_before_thrust_before_yaw() {
    let a = shipped("quad_x");
    let m = Mixer::new(&a).unwrap();
    let w = a.weight_n();
    // A large roll moment at hover thrust and a yaw request far beyond the margin.
    let out = m.mix(&input(w, Vector3::new(3.0, 0.0, 2.0), V));
    assert_eq!(out.tilt_scale, 1.0);
    assert!(
        (out.achieved.torque_frd_n_m.x - 3.0).abs() < 1e-9,
        "roll kept whole"
    );
    assert!(out.yaw_scale < 0.5, "yaw gives way: {}", out.yaw_scale);
    assert!(
        out.unallocated.torque_frd_n_m.z > 0.5 && out.unallocated.torque_frd_n_m.x.abs() < 1e-9
    );
    // Full-throttle climb with a roll demand: the collective gives way, roll does not.
    let out = m.mix(&input(4.0 * w, Vector3::new(2.0, 0.0, 0.0), V));
    assert!((out.achieved.torque_frd_n_m.x - 2.0).abs() < 1e-9);
    assert!(out.unallocated.thrust_n > 0.0);
    // An impossible roll moment is scaled down, keeping its direction, never exceeding limits.
    let out = m.mix(&input(w, Vector3::new(50.0, 25.0, 0.0), V));
    assert!(out.tilt_scale < 1.0 && out.tilt_scale > 0.0);
    let got = out.achieved.torque_frd_n_m;
    assert!((got.y / got.x - 0.5).abs() < 1e-9, "direction kept");
    assert!(out.commands[..4].iter().all(|&c| (0.0..=1.0).contains(&c)));
}

/// After one rotor fails, hexa, octa and dodeca still produce the hover wrench exactly (every
/// failed rotor tried); the dodeca also with two non-adjacent rotors out. A quad gives up yaw and
/// keeps thrust, roll and pitch.
#[test]
fn failed_rotors_still_allow_hover() {
    for name in ["hexa_x", "octa_x", "dodeca"] {
        let a = shipped(name);
        let n = a.rotors.len();
        let mut sets: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
        if name == "dodeca" {
            // Two non-adjacent rotors: every pair farther apart than the lattice spacing.
            for i in 0..n {
                for j in i + 1..n {
                    if (a.rotors[i].position_frd_m - a.rotors[j].position_frd_m).norm() > 0.3 {
                        sets.push(vec![i, j]);
                    }
                }
            }
        }
        let mut worst = 0.0f64;
        for set in &sets {
            let mut m = Mixer::new(&a).unwrap();
            let mut failed = vec![false; n];
            for &i in set {
                failed[i] = true;
            }
            m.set_failed(&failed).unwrap();
            let out = m.mix(&input(a.weight_n(), Vector3::zeros(), nominal_v(&a)));
            assert!(
                out.unallocated.thrust_n.abs() < 1e-9
                    && out.unallocated.torque_frd_n_m.norm() < 1e-9,
                "{name} without {set:?}: {:?}",
                out.unallocated
            );
            assert!(set.iter().all(|&i| out.thrust_n[i] == 0.0));
            worst = worst.max(out.commands[..n].iter().cloned().fold(0.0, f64::max));
        }
        println!(
            "{name}: hover after {} failure cases, highest command {worst:.2}",
            sets.len()
        );
    }
    let a = shipped("quad_x");
    let mut m = Mixer::new(&a).unwrap();
    m.set_failed(&[true, false, false, false]).unwrap();
    assert!(!m.yaw_controllable());
    let out = m.mix(&input(a.weight_n(), Vector3::new(0.0, 0.0, 0.1), V));
    assert!(
        out.unallocated.thrust_n.abs() < 1e-9 && out.unallocated.torque_frd_n_m.xy().norm() < 1e-9
    );
    assert_eq!(out.yaw_scale, 0.0);
    // Two opposite rotors out: thrust, roll and pitch are no longer all controllable.
    assert!(m.set_failed(&[true, true, false, false]).is_err());
}

#[test]
fn nonsense_requests_give_safe_commands() {
    let m = Mixer::new(&shipped("hexa_x")).unwrap();
    let out = m.mix(&input(f64::NAN, Vector3::new(f64::INFINITY, 0.0, -1e12), V));
    assert!(
        out.commands
            .iter()
            .all(|c| c.is_finite() && (0.0..=1.0).contains(c))
    );
    let out = m.mix(&input(-5.0, Vector3::zeros(), 0.0));
    assert!(out.commands.iter().all(|c| *c == 0.0));
}
