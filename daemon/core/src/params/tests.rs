//! The parameter groups' metadata, reference and shipped file.

use super::*;

#[test]
fn defaults_are_valid_and_names_fit_mavlink() {
    assert!(AttitudeParams::default().validate().is_empty());
    for m in ATTITUDE_META {
        assert!(m.name.len() <= 16, "{}", m.name);
        assert!(m.min <= m.default && m.default <= m.max, "{}", m.name);
    }
}

#[test]
fn every_parameter_has_a_unique_mavlink_name_that_fits_and_a_valid_default() {
    let mut names = std::collections::HashSet::new();
    let mut count = 0;
    for (group, m) in FlightParams::metadata() {
        assert!(
            m.name.len() <= 16 && !m.name.is_empty(),
            "{group}.{}: {}",
            m.key,
            m.name
        );
        assert!(names.insert(m.name), "duplicate MAVLink name {}", m.name);
        assert!(
            m.min <= m.default && m.default <= m.max,
            "{group}.{}",
            m.key
        );
        count += 1;
    }
    assert!(count >= 40, "{count}");
    let ints: Vec<&str> = FlightParams::metadata()
        .filter(|(_, m)| m.kind == ParamKind::Int32)
        .map(|(_, m)| m.name)
        .collect();
    assert_eq!(
        ints,
        [
            "ATT_MODE",
            "ATT_MAG_LEARN",
            "ATT_ALIGN_N",
            "CAL_MAG0_ID",
            "MC_ATT_LAW",
            "MC_RATE_CTRL",
            "NAV_RCL_ACT",
            "COM_OBL_RC_ACT",
            "FLW_TGT_ALT_M",
            "NAV_DLL_ACT",
            "COM_LOW_BAT_ACT",
            "GF_ACTION",
            "FD_ACT_EN",
            "FD_ACT_MOT_TOUT",
            "CA_FAILURE_MODE",
            "COM_ACT_FAIL_ACT",
            "SYS_FAILURE_EN",
            "BAT1_N_CELLS",
            "CAL_GYRO0_ID",
            "CAL_ACC0_ID",
            "RC_MAP_ROLL",
            "RC_MAP_PITCH",
            "RC_MAP_THROTTLE",
            "RC_MAP_YAW",
            "RC_MAP_FLTMODE",
            "RC_MAP_ARM_SW",
            "COM_FLTMODE1",
            "COM_FLTMODE2",
            "COM_FLTMODE3",
            "COM_FLTMODE4",
            "COM_FLTMODE5",
            "COM_FLTMODE6",
            "COM_RC_IN_MODE",
            "COM_RC_OVERRIDE",
            "MAN_ARM_GESTURE",
            "SDLOG_DIRS_MAX",
            "SDLOG_MIN_FREE",
            "SDLOG_MAX_SIZE",
            "SDLOG_ROTATE"
        ]
    );
    assert!(FlightParams::default().validate().is_empty());
}

/// `params/README.md` is what the metadata says now; `UPDATE_PARAM_REFERENCE=1` rewrites it.
#[test]
fn the_parameter_reference_is_up_to_date() {
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/README.md");
    let text = FlightParams::reference_markdown();
    let groups: Vec<_> = FlightParams::metadata().map(|(g, _)| g).collect();
    for (g, _) in GROUP_TITLES {
        assert!(
            groups.contains(&g),
            "a title for a group that is not there: {g}"
        );
    }
    assert_eq!(
        text.matches("\n| `").count(),
        FlightParams::count(),
        "one row per parameter"
    );
    if std::env::var_os("UPDATE_PARAM_REFERENCE").is_some() {
        std::fs::write(&path, &text).unwrap();
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == text,
        "params/README.md is stale: regenerate it with \
         `UPDATE_PARAM_REFERENCE=1 cargo test -p flight-core parameter_reference`"
    );
}

#[test]
fn the_shipped_parameter_file_loads_and_bad_files_are_refused_naming_the_key() {
    let path =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/flight.toml");
    assert_eq!(
        FlightParams::load(&path).unwrap(),
        FlightParams::default(),
        "params/flight.toml holds the defaults"
    );
    let err = FlightParams::from_toml_str("[position]\nmax_tilt_deg = 95.0\n", "f.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("f.toml: `position.max_tilt_deg`: must be within [5, 80] deg, got 95"),
        "{err}"
    );
    let err = FlightParams::from_toml_str("[rate]\nadrc_betta = 50.0\n", "f.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("adrc_betta"), "{err}");
    let err = FlightParams::from_toml_str("[motor]\nk_p = \"high\"\n", "f.toml")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("f.toml:") && err.contains("k_p"), "{err}");
}

#[test]
fn parameters_are_read_and_set_by_their_mavlink_name_with_every_check() {
    let mut p = FlightParams::default();
    let n = FlightParams::count();
    for (i, (group, m)) in FlightParams::metadata().enumerate() {
        assert_eq!(FlightParams::find(m.name).map(|f| f.0), Some(i));
        assert_eq!(p.value(m.name), Some(m.default), "{group}.{}", m.key);
    }
    assert_eq!(
        FlightParams::find("MIS_TAKEOFF_ALT").unwrap().1,
        "commander"
    );
    p.set("MIS_TAKEOFF_ALT", 12.5).unwrap();
    p.set("ATT_ALIGN_N", 100.0).unwrap();
    p.set("ATT_OBS_K", 2.0).unwrap();
    assert_eq!(
        (
            p.commander.takeoff_alt_m,
            p.attitude.align_samples,
            p.attitude.observer_gain
        ),
        (12.5, 100, 2.0)
    );
    let before = p.clone();
    for (name, value, says) in [
        ("MIS_TAKEOFF_ALT", f64::NAN, "not a number"),
        ("MIS_TAKEOFF_ALT", f64::INFINITY, "not a number"),
        ("MIS_TAKEOFF_ALT", 1000.0, "outside [0.5, 100] m"),
        ("ATT_ALIGN_N", 10.5, "not an integer"),
        ("ATT_ALIGN_N", 0.0, "outside [1, 10000]"),
        // Each within its own range, but the soft limit above the gate.
        ("ATT_ACC_SOFT", 0.5, "must be below accel_gate_g"),
    ] {
        let err = p.set(name, value).unwrap_err();
        assert!(
            matches!(&err, ParamRejection::Invalid(w) if w.starts_with(name) && w.contains(says)),
            "{name} = {value}: {err}"
        );
    }
    assert_eq!(
        p.set("NO_SUCH_PARAM", 1.0),
        Err(ParamRejection::Unknown("NO_SUCH_PARAM".into()))
    );
    assert_eq!(p, before, "a refused value changes nothing");
    assert_eq!(FlightParams::count(), n);
}

/// A calibration's nine values go in together: one at a time, a valid result may pass
/// through a soft-iron matrix that is not positive definite, which is refused.
#[test]
fn a_calibration_is_set_all_at_once_and_a_folding_correction_is_refused() {
    let mut p = FlightParams::default();
    p.set_many(&[("CAL_MAG0_XODIAG", 0.9)]).unwrap();
    let shrink = [
        ("CAL_MAG0_XSCALE", 0.3),
        ("CAL_MAG0_YSCALE", 0.3),
        ("CAL_MAG0_XODIAG", 0.0),
    ];
    let mut one_by_one = p.clone();
    let err = one_by_one.set(shrink[0].0, shrink[0].1).unwrap_err();
    assert!(err.to_string().contains("positive definite"), "{err}");
    p.set_many(&shrink).unwrap();
    assert_eq!(p.value("CAL_MAG0_XSCALE"), Some(0.3));
    assert_eq!(
        p.attitude.mag_correction(),
        Matrix3::from_diagonal(&Vector3::new(0.3, 0.3, 1.0))
    );
    // All or nothing: one bad value leaves every other as it was.
    let before = p.clone();
    assert!(
        p.set_many(&[("CAL_MAG0_XOFF", 0.1), ("CAL_MAG0_YOFF", 7.0)])
            .is_err()
    );
    assert!(
        p.set_many(&[("CAL_MAG0_XODIAG", 0.5)]).is_err(),
        "0.3 diagonal, 0.5 off it"
    );
    assert_eq!(p, before);
}

#[test]
fn every_violation_is_reported_with_its_range() {
    let p: AttitudeParams =
        toml::from_str("observer_gain = -1.0\naccel_gate_g = 0.01\nmag_scale = [1.0, 0.0, 1.0]\n")
            .unwrap();
    let v = p.validate();
    let keys: Vec<&str> = v.iter().map(|x| x.key.as_str()).collect();
    assert_eq!(
        keys,
        [
            "attitude.observer_gain",
            "attitude.accel_deweight_g",
            "attitude.mag_scale[1]"
        ]
    );
    assert!(v[0].reason.contains("[0.05, 50] 1/s, got -1"));
    assert!(
        toml::from_str::<AttitudeParams>("observer_k = 1.0").is_err(),
        "unknown keys are refused"
    );
}
