//! The relaxed hover solved for every quad airframe and lost rotor, checked against the
//! simulator's own rigid body and rotors.
#![allow(clippy::unwrap_used)]
use super::*;
use nalgebra::UnitQuaternion;
use sitl_core::body::BodyState;
use sitl_core::powertrain::Rotors;
use sitl_core::sim::{SimConfig, Simulator};

const RHO: f64 = 1.225;

fn airframe(name: &str) -> Airframe {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    Airframe::load(&dir.join(format!("{name}.toml"))).unwrap()
}

#[test]
fn every_quad_airframe_has_a_relaxed_hover_for_each_lost_rotor() {
    for name in ["quad_x", "quad_plus"] {
        let a = airframe(name);
        for share in [0.5, 1.0] {
            let spins: Vec<f64> = (0..4)
                .map(|lost| {
                    let h = solve(&a, lost, share, RHO).unwrap();
                    let total: f64 = h.thrust_n.iter().sum();
                    assert!((-total * h.axis_frd.z - a.weight_n()).abs() < 1e-6);
                    assert!((h.axis_frd.norm() - 1.0).abs() < 1e-9);
                    assert_eq!(h.thrust_n[lost], 0.0);
                    let o = h.thrust_n[h.opposite];
                    let others = total - o;
                    assert!((o - share * others / 2.0).abs() < 1e-6, "{h:?}");
                    // The lost rotor's partner across the diagonal spins the same way.
                    assert_eq!(a.rotors[h.opposite].spin, a.rotors[lost].spin);
                    println!(
                        "{name} rotor {} lost, share {share}: spin {:6.2} rad/s, axis tilted \
                         {:5.2}°, thrusts {:.2?} N",
                        lost + 1,
                        h.spin_rad_s,
                        h.tilt_deg(),
                        h.thrust_n
                    );
                    h.spin_rad_s
                })
                .collect();
            // A symmetric airframe: the same spin for every lost rotor. The body yaws against
            // the two rotors that spin against the lost one (they now outweigh the one with
            // it): about body z (down) opposite the lost rotor's reaction torque, so about the
            // axis (up) with it.
            for (lost, spin) in spins.iter().enumerate() {
                assert!((spin.abs() - spins[0].abs()).abs() < 1e-6 * spins[0].abs());
                let s = a.rotors[lost].spin.sign();
                assert!(
                    spin * s > 0.0,
                    "{name} rotor {lost}: spin {spin}, rotor sign {s}"
                );
            }
        }
    }
}

/// The simulator started in the solved state with the solved rotor speeds: its body neither
/// turns faster nor tilts its spin (angular acceleration) and neither climbs nor sinks, by the
/// simulator's own rigid body, rotors and drag; and it holds the spin for 0.2 s. A state a
/// little off (the opposite rotor 10 % stronger) is told apart at once.
#[test]
fn the_simulator_holds_the_relaxed_hover_it_was_solved_for() {
    let a = airframe("quad_x");
    let at = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -50.0),
        ..BodyState::default()
    };
    // The air where the simulator flies it (its home is above the sea).
    let probe = Simulator::new(&a, SimConfig::default(), at).unwrap();
    let rho = sitl_core::environment::isa(probe.truth().position().alt_m).density_kg_m3;
    let h = solve(&a, 0, 0.5, rho).unwrap();
    let fly = |thrusts: &[f64], steps: usize| {
        // Any heading: the axis up.
        let q = UnitQuaternion::rotation_between(&h.axis_frd, &-Vector3::z()).unwrap();
        let initial = BodyState {
            q_ned_from_frd: q,
            rate_frd_rad_s: h.axis_frd * h.spin_rad_s,
            ..at
        };
        let mut sim = Simulator::new(&a, SimConfig::default(), initial).unwrap();
        let speeds: Vec<f64> = a
            .rotors
            .iter()
            .zip(thrusts)
            .map(|(r, &t)| r.speed_for_thrust_rad_s(rho, t))
            .collect();
        sim.set_rotor_speeds(&speeds);
        let v = sim.truth().battery_voltage_v;
        let commands: Vec<f64> = a
            .rotors
            .iter()
            .zip(&speeds)
            .map(|(r, &w)| Rotors::command_for_speed(r, w, v))
            .collect();
        sim.step(&commands);
        let t = sim.truth();
        let dt = SimConfig::default().dt_s;
        let spin_accel = (t.body.rate_frd_rad_s - initial.rate_frd_rad_s).norm() / dt;
        let climb_accel = t.accel_ned_m_s2.z.abs();
        for _ in 1..steps {
            sim.step(&commands);
        }
        let rate = sim.truth().body.rate_frd_rad_s;
        let rate_error = (rate - initial.rate_frd_rad_s).norm() / h.spin_rad_s.abs();
        (spin_accel, climb_accel, rate_error)
    };
    let (spin_accel, climb_accel, rate_error) = fly(&h.thrust_n, 200);
    println!(
        "solved: {spin_accel:.3} rad/s² and {climb_accel:.3} m/s² at the start, the rate {:.2} % \
         off after 0.2 s",
        100.0 * rate_error
    );
    assert!(spin_accel < 0.005 && climb_accel < 0.005 && rate_error < 0.005);
    let mut off = h.thrust_n.clone();
    off[h.opposite] *= 1.1;
    let (spin_accel, climb_accel, _) = fly(&off, 1);
    println!("10 % off: {spin_accel:.3} rad/s², {climb_accel:.3} m/s²");
    assert!(spin_accel > 1.0 && climb_accel > 0.1);
}

#[test]
fn a_spin_limit_picks_the_least_share_that_keeps_under_it() {
    let a = airframe("quad_x");
    let free = solve(&a, 0, 0.0, RHO).unwrap();
    let limit = 0.8 * 2000f64.to_radians();
    let h = solve_within_spin(&a, 0, limit, RHO).unwrap();
    println!(
        "no share: {:.1} rad/s; within {limit:.1} rad/s: share {:.3}, {:.1} rad/s, tilt {:.1}°",
        free.spin_rad_s,
        h.share,
        h.spin_rad_s,
        h.tilt_deg()
    );
    assert!(h.spin_rad_s.abs() <= limit && h.spin_rad_s.abs() > 0.95 * limit);
    assert!((h.share - 0.98).abs() < 0.02, "{}", h.share);
    assert!(free.spin_rad_s.abs() > limit, "the limit mattered");
    let e = solve_within_spin(&a, 0, 1.0, RHO).unwrap_err();
    assert!(matches!(e, RelaxedHoverError::SpinLimit { .. }), "{e}");
}

#[test]
fn what_cannot_be_solved_says_why() {
    let quad = airframe("quad_x");
    let hexa = airframe("hexa_x");
    assert_eq!(
        solve(&hexa, 0, 0.5, RHO),
        Err(RelaxedHoverError::NotAQuad { rotors: 6 })
    );
    assert_eq!(
        solve(&quad, 4, 0.5, RHO),
        Err(RelaxedHoverError::NoSuchRotor(4))
    );
    assert_eq!(
        solve(&quad, 0, -1.0, RHO),
        Err(RelaxedHoverError::Share(-1.0))
    );
    assert!(solve(&quad, 0, f64::NAN, RHO).is_err());
    for rho in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            solve(&quad, 0, 0.5, rho),
            Err(RelaxedHoverError::AirDensity(_))
        ));
    }
}
