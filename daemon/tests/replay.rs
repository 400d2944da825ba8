//! `autopilot replay` on simulated logs, run as a user runs it.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use flight_core::math::geo::LatLonAlt;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use sitl_core::environment::isa;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, Truth, fields};
use std::fmt::Write as _;
use std::process::Command;

/// Two seconds on the ground, then wobbling through a 23 °/s turn.
fn attitude(t: f64) -> UnitQuaternion<f64> {
    let f = (t - 2.0).max(0.0);
    UnitQuaternion::from_euler_angles(
        0.3 * (0.5 * f).sin(),
        0.2 * (1.0 - (0.3 * f).cos()),
        0.4 * f,
    )
}

/// Writes a log of 40 s with a distorted magnetometer; returns (csv, params, truth by time).
fn make_log(
    dir: &std::path::Path,
) -> (
    std::path::PathBuf,
    std::path::PathBuf,
    Vec<(f64, UnitQuaternion<f64>)>,
) {
    let mut cfg = SensorConfig::preset(SensorPreset::Typical);
    let noisy = SensorConfig::preset(SensorPreset::Noisy);
    cfg.mag_hard_iron = noisy.mag_hard_iron;
    cfg.mag_soft_iron = noisy.mag_soft_iron;
    let mut sensors = SensorSuite::new(
        cfg.clone(),
        EarthField::default(),
        LatLonAlt::default(),
        Vector3::zeros(),
        11,
    );
    let speeds = [520.0; 4];
    let max = [950.0; 4];
    let dt = 0.004;
    // Shuffled columns and one extra: the header decides.
    let mut csv = String::from("ax,ay,az,t,extra,mz,my,mx,gx,gy,gz\n");
    let mut truth = Vec::new();
    for k in 1..=10_000 {
        let t = k as f64 * dt;
        let q = attitude(t);
        let rate = (attitude(t - dt).inverse() * q).scaled_axis() / dt;
        let tr = Truth {
            time_usec: (t * 1e6).round() as u64,
            pos_ned_m: Vector3::zeros(),
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            q_ned_from_frd: q,
            rate_frd_rad_s: rate,
            ang_accel_frd_rad_s2: Vector3::zeros(),
            air: isa(500.0),
            rotor_speed_rad_s: &speeds,
            rotor_max_speed_rad_s: &max,
        };
        let f = sensors.sample(&tr).clone();
        let (a, g, m) = (f.accel_frd_m_s2, f.gyro_frd_rad_s, f.mag_frd_gauss);
        let mag = f.fields_updated & fields::MAG != 0;
        let ms = |x: f64| if mag { format!("{x}") } else { String::new() };
        writeln!(
            csv,
            "{},{},{},{t},7,{},{},{},{},{},{}",
            a.x,
            a.y,
            a.z,
            ms(m.z),
            ms(m.y),
            ms(m.x),
            g.x,
            g.y,
            g.z
        )
        .unwrap();
        truth.push((t, q));
    }
    let path = dir.join("log.csv");
    std::fs::write(&path, csv).unwrap();
    // The calibration that undoes raw = S m + offset: R E Rᵀ = S⁻¹ (Castillo (75) in body form).
    let s: Matrix3<f64> = cfg.mag_soft_iron.try_inverse().unwrap();
    let o = cfg.mag_hard_iron;
    let params = format!(
        "[attitude]\nmag_offset = [{}, {}, {}]\nmag_scale = [{}, {}, {}]\nmag_offdiag = [{}, {}, {}]\n",
        o.x,
        o.y,
        o.z,
        s[(0, 0)],
        s[(1, 1)],
        s[(2, 2)],
        s[(0, 1)],
        s[(0, 2)],
        s[(1, 2)]
    );
    let params_path = dir.join("params.toml");
    std::fs::write(&params_path, params).unwrap();
    (path, params_path, truth)
}

fn replay(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_autopilot"))
        .arg("replay")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn replay_follows_the_truth_with_the_calibration_from_a_params_file() {
    let dir = tempfile::tempdir().unwrap();
    let (log, params, truth) = make_log(dir.path());
    let out_path = dir.path().join("out.csv");
    let run = |with_params: bool| {
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "--input".as_ref(),
            log.as_os_str(),
            "--output".as_ref(),
            out_path.as_os_str(),
        ];
        if with_params {
            args.extend(["--params".as_ref(), params.as_os_str()]);
        }
        let o = replay(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let text = std::fs::read_to_string(&out_path).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next().unwrap(), "t,qw,qx,qy,qz,bx,by,bz");
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), truth.len(), "a row for every sample");
        let mut sum = 0.0;
        let mut n = 0;
        for (row, (t, q)) in rows.iter().zip(&truth) {
            assert!((row[0] - t).abs() < 1e-9);
            if *t > 5.0 {
                let est = UnitQuaternion::new_normalize(nalgebra::Quaternion::new(
                    row[1], row[2], row[3], row[4],
                ));
                sum += est.angle_to(q).powi(2);
                n += 1;
            }
        }
        (sum / n as f64).sqrt().to_degrees()
    };
    let calibrated = run(true);
    let raw = run(false);
    println!(
        "replay of a 40 s log: attitude RMS {calibrated:.3} deg with the calibration, {raw:.2} deg without"
    );
    assert!(calibrated < 0.5);
    assert!(raw > 2.0 * calibrated, "the calibration must matter");
}

#[test]
fn bad_logs_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.csv");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "t,gx,gy,gz,ax,ay,az,mx,my\n0,0,0,0,0,0,-9.8,0.2,0\n").unwrap();
    let o = replay(&[
        "--input".as_ref(),
        bad.as_os_str(),
        "--output".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("lacks the column `mz`"));
    std::fs::write(&bad, "t,gx,gy,gz,ax,ay,az,mx,my,mz\n0,0,0,0,0,0,-9.8,0.2,0,0.4\n0.004,0,zero,0,0,0,-9.8,0.2,0,0.4\n").unwrap();
    let o = replay(&[
        "--input".as_ref(),
        bad.as_os_str(),
        "--output".as_ref(),
        out.as_os_str(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("bad.csv:3: column `gy`: not a number"),
        "{err}"
    );
}
