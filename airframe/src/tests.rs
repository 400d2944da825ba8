use super::*;
use std::path::PathBuf;

pub(crate) fn airframe_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params/airframes")
}

pub(crate) fn shipped(name: &str) -> Airframe {
    Airframe::load(&airframe_dir().join(format!("{name}.toml"))).unwrap()
}

pub(crate) const SHIPPED: [&str; 5] = ["quad_x", "quad_plus", "hexa_x", "octa_x", "dodeca"];

const MINIMAL: &str = r#"
name = "t"
mass_kg = 1.0
inertia_kg_m2 = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.02]]
[drag]
linear_n_s_m = [0.1, 0.1, 0.1]
quadratic_n_s2_m2 = [0.0, 0.0, 0.0]
rotational_n_m_s_rad = [0.0, 0.0, 0.0]
[battery]
cells = 3
capacity_mah = 2200.0
internal_resistance_ohm = 0.03
efficiency = 0.7
idle_current_a = 0.3
[rotor_defaults]
k_t = 0.1
k_q = 0.007
diameter_m = 0.2
time_constant_s = 0.02
max_speed_rad_s = 1200.0
motor_gain_rad_s_per_v = 100.0
inertia_kg_m2 = 2e-5
[[rotors]]
position_m = [0.1, 0.1, 0.0]
spin = "ccw"
[[rotors]]
position_m = [-0.1, -0.1, 0.0]
spin = "ccw"
[[rotors]]
position_m = [0.1, -0.1, 0.0]
spin = "cw"
[[rotors]]
position_m = [-0.1, 0.1, 0.0]
spin = "cw"
"#;

fn invalid_keys(text: &str) -> Vec<String> {
    match Airframe::from_toml_str(text, "bad.toml") {
        Err(ConfigError::Invalid { file, violations }) => {
            assert_eq!(file, "bad.toml");
            violations.into_iter().map(|v| v.key).collect()
        }
        other => panic!("expected Invalid, got {other:?}"),
    }
}

#[test]
fn every_shipped_airframe_loads_with_full_authority() {
    for name in SHIPPED {
        let a = shipped(name);
        assert_eq!(a.name, name);
        assert_eq!(a.effectiveness().rank(1e-9), 4, "{name}");
    }
    assert_eq!(shipped("dodeca").rotors.len(), 12);
}

#[test]
fn minimal_airframe_parses() {
    let a = Airframe::from_toml_str(MINIMAL, "m.toml").unwrap();
    assert_eq!(a.rotors.len(), 4);
    assert_eq!(a.rotors[2].spin, Spin::Cw);
}

#[test]
fn unknown_key_is_refused_naming_file_and_key() {
    let text = MINIMAL.replace("mass_kg = 1.0", "mass_kg = 1.0\nmass_lb = 2.2");
    let err = Airframe::from_toml_str(&text, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("bad.toml:"), "{err}");
    assert!(err.contains("mass_lb"), "{err}");
}

#[test]
fn missing_field_is_refused() {
    let text = MINIMAL.replace("mass_kg = 1.0\n", "");
    let err = Airframe::from_toml_str(&text, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("mass_kg"), "{err}");
}

#[test]
fn missing_rotor_property_names_the_rotor() {
    let text = MINIMAL.replace("k_t = 0.1\n", "");
    let keys = invalid_keys(&text);
    assert_eq!(
        keys,
        [
            "rotors[0].k_t",
            "rotors[1].k_t",
            "rotors[2].k_t",
            "rotors[3].k_t"
        ]
    );
}

#[test]
fn negative_mass_is_refused_with_its_range() {
    let text = MINIMAL.replace("mass_kg = 1.0", "mass_kg = -1.0");
    let err = Airframe::from_toml_str(&text, "bad.toml").unwrap_err();
    assert!(
        err.to_string()
            .contains("`mass_kg`: must be a finite number > 0, got -1"),
        "{err}"
    );
}

#[test]
fn bad_inertia_tensors_are_refused() {
    // Not symmetric.
    let t = MINIMAL.replace(
        "[[0.01, 0.0, 0.0], [0.0, 0.01, 0.0]",
        "[[0.01, 0.001, 0.0], [0.0, 0.01, 0.0]",
    );
    assert_eq!(invalid_keys(&t), ["inertia_kg_m2"]);
    // Not positive definite.
    let t = MINIMAL.replace("[0.0, 0.0, 0.02]]", "[0.0, 0.0, -0.02]]");
    assert_eq!(invalid_keys(&t), ["inertia_kg_m2"]);
    // Positive definite but no physical body has it (I_z > I_x + I_y).
    let t = MINIMAL.replace("[0.0, 0.0, 0.02]]", "[0.0, 0.0, 0.05]]");
    assert_eq!(invalid_keys(&t), ["inertia_kg_m2"]);
}

#[test]
fn zero_and_too_many_rotors_are_refused() {
    let head = &MINIMAL[..MINIMAL.find("[[rotors]]").unwrap()];
    assert_eq!(invalid_keys(head), ["rotors"]);
    let rotor = "[[rotors]]\nposition_m = [0.1, 0.1, 0.0]\nspin = \"ccw\"\n";
    let many = format!("{head}{}", rotor.repeat(17));
    let err = Airframe::from_toml_str(&many, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("1 to 16 rotors, got 17"), "{err}");
}

#[test]
fn rank_deficient_layout_is_refused() {
    // All four rotors spin the same way: no yaw authority.
    let t = MINIMAL.replace("spin = \"cw\"", "spin = \"ccw\"");
    let err = Airframe::from_toml_str(&t, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("rank 3 < 4"), "{err}");
    // Rotors on a line: no pitch authority.
    let t = MINIMAL
        .replace("[0.1, 0.1, 0.0]", "[0.0, 0.1, 0.0]")
        .replace("[-0.1, -0.1, 0.0]", "[0.0, -0.1, 0.0]")
        .replace("[0.1, -0.1, 0.0]", "[0.0, -0.2, 0.0]")
        .replace("[-0.1, 0.1, 0.0]", "[0.0, 0.2, 0.0]");
    assert!(
        Airframe::from_toml_str(&t, "bad.toml")
            .unwrap_err()
            .to_string()
            .contains("rank")
    );
}

#[test]
fn a_missing_file_names_the_file() {
    let err = Airframe::load(Path::new("/nonexistent/x.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("/nonexistent/x.toml: cannot read"), "{err}");
}

/// Lewis (4.31)/(6.9) with d = 0.225 m and c = K_Q D / K_T (4.34): our matrix is his with the
/// F_z row negated (FRD z points down; Lewis counts thrust up).
#[test]
fn quad_plus_reproduces_lewis_allocation_matrix() {
    let a = shipped("quad_plus");
    let b = a.effectiveness();
    let d = 0.225;
    let c = a.rotors[0].yaw_moment_per_thrust_m();
    assert!((c - 0.0072 * 0.254 / 0.11).abs() < 1e-15);
    let lewis = nalgebra::DMatrix::from_row_slice(
        4,
        4,
        &[
            1.0, 1.0, 1.0, 1.0, //
            0.0, -d, 0.0, d, //
            -d, 0.0, d, 0.0, //
            c, -c, c, -c,
        ],
    );
    let mut ours = b.clone();
    ours.row_mut(0).neg_mut();
    assert!((ours - lewis).abs().max() < 1e-15);
}

/// The dodeca's hexagonal lattice with alternating spins: a pure yaw command (ccw rotors up, cw
/// down) makes no roll or pitch moment, and equal thrusts make no moment at all.
#[test]
fn dodeca_geometry_decouples_yaw_from_tilt() {
    let a = shipped("dodeca");
    let b = a.effectiveness();
    let equal = b.clone() * nalgebra::DVector::from_element(12, 1.0);
    assert!(
        equal[1].abs() < 1e-3 && equal[2].abs() < 1e-3 && equal[3].abs() < 1e-12,
        "{equal}"
    );
    let yaw = nalgebra::DVector::from_iterator(12, a.rotors.iter().map(|r| r.spin.sign()));
    let w = b * yaw;
    assert!(
        w[1].abs() < 1e-3 && w[2].abs() < 1e-3,
        "yaw leaks into tilt: {w}"
    );
    assert!(w[3] > 0.1);
    // Every rotor is one lattice spacing (0.28 m) from its nearest neighbour, and discs do not overlap.
    for (i, r) in a.rotors.iter().enumerate() {
        let nearest = a
            .rotors
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, o)| (o.position_frd_m - r.position_frd_m).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(
            (nearest - 0.28).abs() < 1e-3 && nearest > r.diameter_m,
            "rotor {i}: {nearest}"
        );
    }
}

#[test]
fn the_landing_gear_defaults_under_the_arms_or_is_read_from_the_file() {
    // No [landing_gear]: four feet on 0.6 of the 0.141 m arm, a tenth of a metre down.
    let a = Airframe::from_toml_str(MINIMAL, "m.toml").unwrap();
    let g = &a.landing_gear;
    assert_eq!(g.feet_frd_m.len(), 4);
    for f in &g.feet_frd_m {
        assert!(
            (f.xy().norm() - 0.6 * 0.1f64.hypot(0.1)).abs() < 1e-12,
            "{f}"
        );
        assert_eq!(f.z, 0.1);
    }
    assert_eq!((g.sag_m, g.damping_ratio, g.friction), (0.005, 0.7, 0.8));
    let text = format!(
        "{MINIMAL}\n[landing_gear]\nfeet_m = [[0.2, 0.0, 0.15], [-0.1, 0.15, 0.15], [-0.1, -0.15, 0.15]]\nsag_m = 0.01\nfriction = 0.4\n"
    );
    let g = Airframe::from_toml_str(&text, "t.toml")
        .unwrap()
        .landing_gear;
    assert_eq!(g.feet_frd_m[0], Vector3::new(0.2, 0.0, 0.15));
    assert_eq!((g.sag_m, g.damping_ratio, g.friction), (0.01, 0.7, 0.4));
}

#[test]
fn a_landing_gear_that_cannot_stand_the_vehicle_is_refused() {
    let gear = |body: &str| format!("{MINIMAL}\n[landing_gear]\n{body}\n");
    for (body, key) in [
        (
            "feet_m = [[0.1, 0.1, 0.1], [-0.1, -0.1, 0.1]]",
            "landing_gear.feet_m",
        ),
        // A foot above the centre of mass.
        (
            "feet_m = [[0.1, 0.1, 0.1], [-0.1, 0.1, -0.1], [0.0, -0.1, 0.1]]",
            "landing_gear.feet_m[1]",
        ),
        // All feet on one side: the vehicle would fall over.
        (
            "feet_m = [[0.1, 0.1, 0.1], [0.2, 0.1, 0.1], [0.15, -0.1, 0.1]]",
            "landing_gear.feet_m",
        ),
        ("sag_m = 0.0", "landing_gear.sag_m"),
        ("damping_ratio = -1.0", "landing_gear.damping_ratio"),
        ("friction = 5.0", "landing_gear.friction"),
    ] {
        assert_eq!(invalid_keys(&gear(body)), [key], "{body}");
    }
}
