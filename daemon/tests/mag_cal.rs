//! `autopilot calibrate-mag` on simulator data, run as a user runs it: the simulator's noisy
//! magnetometer (hard and soft iron, noise) recorded while the vehicle is turned through every
//! orientation, the fit written into a copy of params/flight.toml, and the written calibration
//! compared with the distortion the simulator applied.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use flight_core::math::geo::LatLonAlt;
use flight_core::params::FlightParams;
use nalgebra::{UnitQuaternion, Vector3};
use sitl_core::environment::isa;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, Truth, fields};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::Command;

/// A calibration dance, as a person does it: the vehicle turned about its three axes in turn
/// while it is slowly tipped over, 60 s.
fn attitude(t: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(0.9 * t, 0.37 * t, 0.23 * t)
}

#[test]
fn a_calibration_from_a_log_recovers_the_simulated_distortion() {
    let dir = std::env::temp_dir().join(format!("autopilot-magcal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = SensorConfig::preset(SensorPreset::Noisy);
    let field = EarthField::default();
    let strength = field.ned().norm();
    let mut sensors = SensorSuite::new(
        cfg.clone(),
        field,
        LatLonAlt::default(),
        Vector3::zeros(),
        5,
    );
    let speeds = [0.0; 4];
    let max = [950.0; 4];
    let dt = 0.004;
    // The flight-data CSV's columns that matter here, among others.
    let mut csv = String::from("t_s,mode,gx,gy,gz,mx,my,mz,motor1\n");
    for k in 1..=15_000 {
        let t = k as f64 * dt;
        let q = attitude(t);
        let tr = Truth {
            time_usec: (t * 1e6).round() as u64,
            pos_ned_m: Vector3::zeros(),
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            q_ned_from_frd: q,
            rate_frd_rad_s: (attitude(t - dt).inverse() * q).scaled_axis() / dt,
            ang_accel_frd_rad_s2: Vector3::zeros(),
            air: isa(500.0),
            rotor_speed_rad_s: &speeds,
            rotor_max_speed_rad_s: &max,
        };
        let f = sensors.sample(&tr).clone();
        let (g, m) = (f.gyro_frd_rad_s, f.mag_frd_gauss);
        if f.fields_updated & fields::MAG != 0 {
            writeln!(
                csv,
                "{t},LOITER,{},{},{},{},{},{},0",
                g.x, g.y, g.z, m.x, m.y, m.z
            )
            .unwrap();
        } else {
            writeln!(csv, "{t},LOITER,{},{},{},,,,0", g.x, g.y, g.z).unwrap();
        }
    }
    let log = dir.join("flight.csv");
    std::fs::write(&log, csv).unwrap();
    let params: PathBuf = dir.join("flight.toml");
    let shipped = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params/flight.toml");
    let original = std::fs::read_to_string(&shipped).unwrap();
    std::fs::write(&params, &original).unwrap();

    let out = Command::new(env!("CARGO_BIN_EXE_autopilot"))
        .args(["calibrate-mag", "--input"])
        .arg(&log)
        .arg("--params")
        .arg(&params)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{stdout}");

    let written = std::fs::read_to_string(&params).unwrap();
    let p = FlightParams::load(&params).unwrap();
    assert_ne!(p.attitude.mag_calibration_id, 0, "calibrated");
    let cal = p.attitude.mag_calibration();
    // Hard iron within 1 % of the field.
    let offset_error = (cal.offset - cfg.mag_hard_iron).norm();
    assert!(
        offset_error < 0.01 * strength,
        "offset {:?} vs {:?}",
        cal.offset,
        cfg.mag_hard_iron
    );
    // Soft iron within 2 %: the correction R E Rᵀ undoes the simulator's matrix S (scaled to
    // the field strength ATT_MAG_STR, which is the simulator's), i.e. R E Rᵀ S ≈ I.
    let residual = cal.correction * cfg.mag_soft_iron - nalgebra::Matrix3::identity();
    assert!(
        residual.norm() < 0.02,
        "R E Rᵀ S − I = {residual} (norm {})",
        residual.norm()
    );
    println!(
        "offset error {:.5} gauss ({:.2} % of the field); ‖R E Rᵀ S − I‖ = {:.4}",
        offset_error,
        100.0 * offset_error / strength,
        residual.norm()
    );
    // Only the calibration's lines changed, comments kept, everything else as shipped.
    let changed: Vec<_> = original
        .lines()
        .zip(written.lines())
        .filter(|(a, b)| a != b)
        .map(|(a, _)| a.split('=').next().unwrap().trim().to_owned())
        .collect();
    assert_eq!(
        changed,
        [
            "mag_calibration_id",
            "mag_offset",
            "mag_scale",
            "mag_offdiag"
        ]
    );
    assert_eq!(original.lines().count(), written.lines().count());
    assert!(written.contains("mag_offset = [") && written.contains("# CAL_MAG0_XOFF, YOFF, ZOFF"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_log_without_turns_or_magnetometer_columns_is_refused_clearly() {
    let dir = std::env::temp_dir().join(format!("autopilot-magcal-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |csv: &str| {
        let log = dir.join("log.csv");
        std::fs::write(&log, csv).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_autopilot"))
            .args(["calibrate-mag", "--input"])
            .arg(&log)
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(run("t,a,b\n1,2,3\n").contains("no `mx` column"));
    // Turned about the vertical only (a vehicle on a table).
    let mut csv = String::from("t,mx,my,mz\n");
    for k in 0..500 {
        let a = k as f64 * 0.05;
        writeln!(csv, "{k},{},{},0.43", 0.2 * a.cos(), 0.2 * a.sin()).unwrap();
    }
    let err = run(&csv);
    assert!(err.contains("no calibration"), "{err}");
    assert!(run("t,mx,my,mz\n1,x,2,3\n").contains("not a number"));
    std::fs::remove_dir_all(&dir).unwrap();
}
