#![allow(clippy::unwrap_used)]
use super::*;
use nalgebra::Matrix3;

fn shipped(name: &str) -> Airframe {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    Airframe::load(&dir.join(format!("{name}.toml"))).unwrap()
}

const ORIGIN: Geodetic = Geodetic {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 500.0,
};

const PORTS: BridgePorts = BridgePorts {
    command_tcp: 5601,
    state_udp: 5602,
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
fn the_model_carries_mass_inertia_a_reaction_per_rotor_and_the_ports() {
    for name in ["quad_x", "hexa_x", "dodeca"] {
        let a = shipped(name);
        let xml = aircraft_xml(&a, &ORIGIN, PORTS, 250.0);
        assert!((number(&xml, "<mass_balance>", "emptywt") - a.mass_kg).abs() < 1e-6);
        assert!((number(&xml, "<mass_balance>", "izz") - a.inertia_kg_m2[(2, 2)]).abs() < 1e-9);
        let n = a.rotors.len();
        assert_eq!(xml.matches("<force name=\"rotor").count(), n, "{name}");
        assert_eq!(xml.matches("<moment name=\"rotor").count(), n, "{name}");
        assert_eq!(xml.matches("<contact ").count(), 3);
        // Every reaction's magnitude comes from a declared bridge property.
        for i in 0..n {
            let (t, q) = rotor_properties(i);
            assert!(xml.contains(&format!("<property>{t}</property>")));
            assert!(xml.contains(&format!("<function><property>{q}</property></function>")));
        }
        assert!(xml.contains("<input port=\"5601\"/>"));
        assert!(xml.contains("port=\"5602\" rate=\"250\""));
        for p in STATE_PROPERTIES {
            assert!(xml.contains(&format!("<property>{p}</property>")), "{p}");
        }
        assert!(
            xml.contains("<aerodynamics/>"),
            "JSBSim refuses a model without"
        );
        assert!(xml.trim_end().ends_with("</fdm_config>"));
    }
    // quad_x's rotor 1, front right in FRD, is aft-negative, right-positive in the structural
    // frame; its thrust points up (body -z).
    let xml = aircraft_xml(&shipped("quad_x"), &ORIGIN, PORTS, 250.0);
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
    let xml = aircraft_xml(&a, &ORIGIN, PORTS, 250.0);
    assert!((number(&xml, "<mass_balance>", "ixy") + 0.002).abs() < 1e-12);
    assert!((number(&xml, "<mass_balance>", "ixz") - 0.004).abs() < 1e-12);
    assert!((number(&xml, "<mass_balance>", "iyz") - 0.001).abs() < 1e-12);
}

#[test]
fn a_batch_sets_every_bridge_property_in_english_units_then_iterates_once() {
    let inputs = BridgeInputs {
        thrust_n: vec![N_PER_LBF, 2.0 * N_PER_LBF],
        yaw_moment_n_m: vec![N_PER_LBF * M_PER_FT, -N_PER_LBF * M_PER_FT],
        aero_force_frd_n: Vector3::new(N_PER_LBF, 0.0, -N_PER_LBF),
        aero_moment_frd_n_m: Vector3::zeros(),
    };
    let batch = inputs.encode().unwrap();
    let lines: Vec<&str> = batch.lines().collect();
    assert_eq!(lines.len(), 2 * 2 + 6 + 1);
    assert_eq!(*lines.last().unwrap(), "iterate 1");
    let value = |name: &str| -> f64 {
        let line = lines
            .iter()
            .find(|l| l.starts_with(&format!("set {name} ")))
            .unwrap();
        line.rsplit(' ').next().unwrap().parse().unwrap()
    };
    assert!((value("bridge/rotor1-thrust-lbs") - 1.0).abs() < 1e-9);
    assert!((value("bridge/rotor2-thrust-lbs") - 2.0).abs() < 1e-9);
    assert!((value("bridge/rotor2-torque-lbsft") + 1.0).abs() < 1e-9);
    assert!((value("bridge/aero-x-lbs") - 1.0).abs() < 1e-9);
    assert!((value("bridge/aero-z-lbs") + 1.0).abs() < 1e-9);
    // A NaN would cancel the iterate without a word from JSBSim: refused here, named.
    let bad = BridgeInputs {
        thrust_n: vec![1.0, f64::NAN],
        ..inputs
    };
    assert_eq!(
        bad.encode().unwrap_err().to_string(),
        "a non-finite value for bridge/rotor2-thrust-lbs"
    );
}

/// A line as JSBSim sends it (recorded layout: right-aligned, comma-separated, `Time` first).
fn line(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:>12}"))
        .collect::<Vec<_>>()
        .join(",")
}

#[test]
fn output_lines_convert_to_si_ned_frd() {
    assert_eq!(
        parse_output("<LABELS> ,Time,frame,h-agl-ft\n", 1.5, &ORIGIN).unwrap(),
        OutputLine::Labels
    );
    let values = [
        0.5, 125.0, // time, frame
        0.001, -0.002, 32.8084, // from the origin: lat, lon (deg), height (ft, 10 m)
        10.0, -20.0, 1.0, // v north, east, down (ft/s)
        0.1, -0.2, 1.5, // phi, theta, psi
        0.01, 0.02, 0.03, // p q r
        1.0, 2.0, 3.0, // pdot qdot rdot
        0.0, 0.0, -3.3069, // forces (lbf): 1.5 kg hovering
        0.0, 0.5, -1.0, // of which the ground's (lbf)
        2116.22, 518.67, 0.0023769, // sea-level air
    ];
    let OutputLine::State(s) = parse_output(&line(&values), 1.5, &ORIGIN).unwrap() else {
        panic!()
    };
    assert_eq!((s.time_s, s.frame), (0.5, 125));
    assert!((s.position.alt_m - 510.0).abs() < 1e-3);
    assert!((s.position.lat_deg - 47.001).abs() < 1e-12);
    assert!((s.position.lon_deg - 7.998).abs() < 1e-12);
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
    // Broken lines are refused with the reason.
    let short = line(&values[..10]);
    assert!(
        parse_output(&short, 1.5, &ORIGIN)
            .unwrap_err()
            .0
            .contains("10 columns, 26 expected")
    );
    let long = format!("{},1", line(&values));
    assert!(
        parse_output(&long, 1.5, &ORIGIN)
            .unwrap_err()
            .0
            .contains("more than 26")
    );
    let text = line(&values).replacen("125", "abc", 1);
    assert!(
        parse_output(&text, 1.5, &ORIGIN)
            .unwrap_err()
            .0
            .contains("column 2")
    );
    let nan = line(&values).replacen("125", "nan", 1);
    assert!(
        parse_output(&nan, 1.5, &ORIGIN)
            .unwrap_err()
            .0
            .contains("not finite")
    );
    let mut half = values;
    half[1] = 1.5;
    assert!(
        parse_output(&line(&half), 1.5, &ORIGIN)
            .unwrap_err()
            .0
            .contains("not a count")
    );
}

/// Each `iterate` first re-sends the frame JSBSim had: only a newer frame passes.
#[test]
fn the_frame_filter_takes_each_frame_once_across_the_modulus() {
    let mut f = FrameFilter::default();
    let verdicts: Vec<FrameVerdict> = [0, 1, 1, 2, 5].into_iter().map(|k| f.check(k)).collect();
    use FrameVerdict::*;
    assert_eq!(verdicts, [Stale, Next, Stale, Next, Unexpected]);
    assert_eq!(f.next(), 3);
    // Past the modulus the counter wraps on the wire, not here.
    let mut f = FrameFilter {
        next: FRAME_MODULUS - 1,
    };
    assert_eq!(f.check(FRAME_MODULUS - 1), Next);
    assert_eq!(f.check(FRAME_MODULUS - 1), Stale);
    assert_eq!(f.check(0), Next);
    assert_eq!(f.next(), FRAME_MODULUS + 1);
}

/// A recorded transcript of the command port, cut at arbitrary points.
#[test]
fn replies_are_counted_and_errors_kept_across_reads() {
    let transcript = b"Connected to JSBSim server\r\nJSBSim> set successful\r\nJSBSim> set successful\r\nJSBSim> Iterations performed\r\nJSBSim> Unknown property\r\nJSBSim> Not a leaf property\r\nJSBSim> ";
    for cut in [1, 7, 30, 61, 100] {
        let mut r = Replies::default();
        for chunk in transcript.chunks(cut) {
            r.push(chunk);
        }
        assert_eq!((r.sets, r.iterations), (2, 1), "cut {cut}");
        assert_eq!(r.errors, ["Unknown property", "Not a leaf property"]);
    }
}

/// The start file puts the vehicle where the scenario says: the ground `rest_height_m` below
/// the NED origin, the centre of mass above it by its height and altitude, in JSBSim's units.
#[test]
fn the_start_file_places_the_vehicle_in_the_scenarios_state() {
    let a = shipped("quad_x");
    let home = Geodetic {
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
