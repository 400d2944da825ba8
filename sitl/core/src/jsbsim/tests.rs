#![allow(clippy::unwrap_used)]
use super::*;
use nalgebra::Matrix3;

fn shipped(name: &str) -> Airframe {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    Airframe::load(&dir.join(format!("{name}.toml"))).unwrap()
}

const ORIGIN: LatLonAlt = LatLonAlt {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 500.0,
};

/// The text between `<tag…>` and `</tag>` of the first `tag` element after `from`.
fn element<'a>(xml: &'a str, from: &str, tag: &str) -> &'a str {
    let at = xml.find(from).unwrap();
    let open = at + xml[at..].find(&format!("<{tag}")).unwrap();
    let start = open + xml[open..].find('>').unwrap() + 1;
    let end = start + xml[start..].find(&format!("</{tag}>")).unwrap();
    &xml[start..end]
}

fn number(xml: &str, from: &str, tag: &str) -> f64 {
    element(xml, from, tag).trim().parse().unwrap()
}

#[test]
fn the_model_carries_mass_inertia_and_a_reaction_per_rotor_driven_by_the_inputs() {
    for name in ["quad_x", "hexa_x", "dodeca"] {
        let a = shipped(name);
        let xml = aircraft_xml(&a);
        assert!((number(&xml, "<mass_balance>", "emptywt") - a.mass_kg).abs() < 1e-6);
        assert!((number(&xml, "<mass_balance>", "izz") - a.inertia_kg_m2[(2, 2)]).abs() < 1e-9);
        let n = a.rotors.len();
        assert_eq!(xml.matches("<force name=\"rotor").count(), n, "{name}");
        assert_eq!(xml.matches("<moment name=\"rotor").count(), n, "{name}");
        assert_eq!(xml.matches("<contact ").count(), 3);
        // Every input is declared and drives one reaction's magnitude.
        let inputs = input_properties(n);
        assert_eq!(inputs.len(), 2 * n + 6);
        for p in &inputs {
            assert!(
                xml.contains(&format!("    <property>{p}</property>")),
                "{p}"
            );
            assert_eq!(
                xml.matches(&format!("<function><property>{p}</property></function>"))
                    .count(),
                1,
                "{p}"
            );
        }
        assert!(
            xml.contains("<aerodynamics/>"),
            "JSBSim refuses a model without"
        );
        assert!(xml.trim_end().ends_with("</fdm_config>"));
    }
    // quad_x's rotor 1, front right in FRD, is aft-negative, right-positive in the structural
    // frame; its thrust points up (body -z).
    let xml = aircraft_xml(&shipped("quad_x"));
    assert!(xml.contains("<force name=\"rotor1\" frame=\"BODY\">"));
    assert!((number(&xml, "<force name=\"rotor1\"", "x") + 0.159).abs() < 1e-9);
    assert!((number(&xml, "<force name=\"rotor1\"", "y") - 0.159).abs() < 1e-9);
    let dir = element(&xml, "<force name=\"rotor1\"", "direction");
    assert_eq!(dir, "<x>0</x><y>0</y><z>-1</z>");
}

/// JSBSim's tensor is `[[ixx, -ixy, ixz], [-ixy, iyy, -iyz], [ixz, -iyz, izz]]` (measured: a
/// roll moment with ixz > 0 yaws the body negative, with ixy > 0 pitches it positive).
#[test]
fn products_of_inertia_follow_jsbsims_signs() {
    let mut a = shipped("quad_x");
    a.inertia_kg_m2 = Matrix3::new(
        0.03, 0.002, 0.004, //
        0.002, 0.03, -0.001, //
        0.004, -0.001, 0.05,
    );
    let xml = aircraft_xml(&a);
    assert!((number(&xml, "<mass_balance>", "ixy") + 0.002).abs() < 1e-12);
    assert!((number(&xml, "<mass_balance>", "ixz") - 0.004).abs() < 1e-12);
    assert!((number(&xml, "<mass_balance>", "iyz") - 0.001).abs() < 1e-12);
}

/// The `f64`s of a request after its sequence number.
fn request_values(bytes: &[u8]) -> Vec<f64> {
    bytes[8..]
        .chunks(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn a_request_carries_its_number_and_every_input_in_english_units_in_order() {
    let inputs = BridgeInputs {
        thrust_n: vec![N_PER_LBF, 2.0 * N_PER_LBF],
        yaw_moment_n_m: vec![N_PER_LBF * M_PER_FT, -N_PER_LBF * M_PER_FT],
        aero_force_frd_n: Vector3::new(N_PER_LBF, 0.0, -N_PER_LBF),
        aero_moment_frd_n_m: Vector3::new(0.0, 0.0, 3.0 * N_PER_LBF * M_PER_FT),
    };
    let mut out = vec![0xAA];
    inputs.encode(7, &mut out).unwrap();
    let bytes = &out[1..];
    assert_eq!(bytes.len(), 8 * (1 + 2 * 2 + 6));
    assert_eq!(u64::from_le_bytes(bytes[..8].try_into().unwrap()), 7);
    let names = input_properties(2);
    let values = request_values(bytes);
    let value = |name: &str| values[names.iter().position(|n| n == name).unwrap()];
    assert!((value("bridge/rotor1-thrust-lbs") - 1.0).abs() < 1e-12);
    assert!((value("bridge/rotor2-thrust-lbs") - 2.0).abs() < 1e-12);
    assert!((value("bridge/rotor1-torque-lbsft") - 1.0).abs() < 1e-12);
    assert!((value("bridge/rotor2-torque-lbsft") + 1.0).abs() < 1e-12);
    assert!((value("bridge/aero-x-lbs") - 1.0).abs() < 1e-12);
    assert!((value("bridge/aero-z-lbs") + 1.0).abs() < 1e-12);
    assert!((value("bridge/aero-n-lbsft") - 3.0).abs() < 1e-12);
    // A NaN would poison JSBSim's state: refused here, named, nothing appended.
    let bad = BridgeInputs {
        thrust_n: vec![1.0, f64::NAN],
        ..inputs
    };
    let mut out = vec![0xAA];
    assert_eq!(
        bad.encode(8, &mut out).unwrap_err().to_string(),
        "a non-finite value for bridge/rotor2-thrust-lbs"
    );
    assert_eq!(out, [0xAA]);
}

/// A reply as the bridge packs it.
fn reply(sequence: u64, values: &[f64]) -> Vec<u8> {
    let mut out = sequence.to_le_bytes().to_vec();
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[test]
fn replies_convert_to_si_ned_frd() {
    let values = [
        0.5, // time
        47.001, 7.998, 1673.2284, // lat, lon (deg), height (ft: 510 m)
        10.0, -20.0, 1.0, // v north, east, down (ft/s)
        0.1, -0.2, 1.5, // phi, theta, psi
        0.01, 0.02, 0.03, // p q r
        1.0, 2.0, 3.0, // pdot qdot rdot
        0.0, 0.0, -3.3069, // forces (lbf): 1.5 kg hovering
        0.0, 0.5, -1.0, // of which the ground's (lbf)
        2116.22, 518.67, 0.0023769, // sea-level air
    ];
    let (sequence, s) = decode_reply(&reply(125, &values), 1.5).unwrap();
    assert_eq!((sequence, s.time_s), (125, 0.5));
    assert!((s.position.alt_m - 510.0).abs() < 1e-4);
    assert_eq!((s.position.lat_deg, s.position.lon_deg), (47.001, 7.998));
    assert!((s.vel_ned_m_s - Vector3::new(3.048, -6.096, 0.3048)).norm() < 1e-9);
    let (r, p, y) = s.q_ned_from_frd.euler_angles();
    assert!((r - 0.1).abs() < 1e-12 && (p + 0.2).abs() < 1e-12 && (y - 1.5).abs() < 1e-12);
    assert_eq!(s.rate_frd_rad_s, Vector3::new(0.01, 0.02, 0.03));
    assert!((s.specific_force_frd_m_s2.z + 9.8066).abs() < 1e-3, "{s:?}");
    assert_eq!(
        s.ground_force_frd_n,
        Vector3::new(0.0, 0.5, -1.0) * N_PER_LBF
    );
    assert!((s.air.pressure_pa - 101_325.0).abs() < 1.0);
    assert!((s.air.temperature_k - 288.15).abs() < 1e-3);
    assert!((s.air.density_kg_m3 - 1.225).abs() < 1e-3);
    // The origin's local frame: 10 m up, a millidegree north (and 152 m west); the tangent
    // plane lies d²/2R (3 mm) above the curved Earth there.
    let step = s.body_step(&navmath::geo::LocalFrame::new(ORIGIN));
    let d = step.body.pos_ned_m.xy().norm();
    let curvature_m = d * d / (2.0 * 6.371e6);
    assert!(
        (step.body.pos_ned_m.z + 10.0 - curvature_m).abs() < 1e-4,
        "{step:?}"
    );
    assert!((step.body.pos_ned_m.x - 111.2).abs() < 0.5, "{step:?}");
    assert!(step.on_ground);
    // Broken replies are refused with the reason.
    let short = reply(1, &values[..10]);
    assert!(
        decode_reply(&short, 1.5)
            .unwrap_err()
            .0
            .contains("88 bytes, 208 expected")
    );
    let mut nan = values;
    nan[4] = f64::NAN;
    assert_eq!(
        decode_reply(&reply(2, &nan), 1.5).unwrap_err().0,
        "velocities/v-north-fps is not finite in reply 2"
    );
}

/// The start file puts the vehicle where the scenario says: the ground `rest_height_m` below
/// the NED origin, the centre of mass above it by its height and altitude, in JSBSim's units.
#[test]
fn the_start_file_places_the_vehicle_in_the_scenarios_state() {
    let a = shipped("quad_x");
    let home = LatLonAlt {
        lat_deg: 47.0,
        lon_deg: 8.0,
        alt_m: 500.0,
    };
    let initial = crate::body::BodyState {
        pos_ned_m: Vector3::new(100.0, 0.0, -10.0),
        vel_ned_m_s: Vector3::new(3.048, 0.0, -0.3048),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(0.1, -0.2, 1.0),
        rate_frd_rad_s: Vector3::new(0.0, 0.0, 0.5),
    };
    let x = init_xml(&a, &home, &initial);
    let rest = rest_height_m(&a);
    assert!(rest > 0.05 && rest < 0.3, "{rest}");
    assert!((number(&x, "", "elevation") - (500.0 - rest)).abs() < 1e-6);
    assert!((number(&x, "", "altitude") - (10.0 + rest)).abs() < 1e-6);
    let north = home.offset_by_ned(&initial.pos_ned_m).lat_deg;
    assert!((number(&x, "", "latitude") - north).abs() < 1e-11);
    assert!((number(&x, "", "longitude") - 8.0).abs() < 1e-11);
    assert!((number(&x, "", "phi") - 0.1).abs() < 1e-9);
    assert!((number(&x, "", "theta") + 0.2).abs() < 1e-9);
    assert!((number(&x, "", "psi") - 1.0).abs() < 1e-9);
    assert!((number(&x, "", "vnorth") - 10.0).abs() < 1e-9);
    assert!((number(&x, "", "vdown") + 1.0).abs() < 1e-9);
    assert!((number(&x, "", "r") - 0.5).abs() < 1e-9);
}

#[test]
fn jsbsim_runs_at_a_kilohertz_or_more_whatever_the_step_rate() {
    assert_eq!(frames_per_step(250.0), 4);
    assert_eq!(frames_per_step(400.0), 3);
    assert_eq!(frames_per_step(1000.0), 1);
    assert_eq!(frames_per_step(2000.0), 1);
    assert_eq!(frames_per_step(1.0), 1000);
    for rate in [100.0, 250.0, 333.0, 400.0, 500.0, 800.0] {
        assert!(rate * f64::from(frames_per_step(rate)) >= MIN_FRAME_RATE_HZ);
    }
}
