//! Recovery from a large error: a gyro glitch turns the estimate by up to 179° in one sample
//! while the vehicle stays still (a gyro that saturated in a tumble, a bump, an estimator
//! restarted wrong). A still vehicle's accelerometer says where "down" is: the tilt must be
//! within 2° in 2 s, and with a clean magnetometer the heading within 5° in 5 s; armed and
//! steady (a hover), a 30° error within 2° in 3 s.

use super::*;
use crate::math::geo::LatLonAlt;
use crate::params::AttitudeParams;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, fields};
use std::f64::consts::PI;

const DT: f64 = 0.004;

/// Angle between the vertical as `a` and `b` see it in the body (rad): the tilt error,
/// whatever the heading's.
fn tilt_error(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.inverse_transform_vector(&Vector3::z())
        .angle(&b.inverse_transform_vector(&Vector3::z()))
}

fn heading_error(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    let d = a.euler_angles().2 - b.euler_angles().2;
    (d + PI).rem_euclid(2.0 * PI) - PI
}

/// Still at `truth` for 15 s; at 10 s one gyro sample turns the estimate by `glitch` (a
/// rotation vector, rad). Returns the times (s after the glitch) after which the tilt stays
/// within 2° and the heading within 5°, and the tilt resets counted.
fn glitch_at_rest(
    truth: UnitQuaternion<f64>,
    glitch: Vector3<f64>,
    armed: bool,
) -> (f64, f64, u64) {
    let mut sensors = SensorSuite::new(
        SensorConfig::preset(SensorPreset::Typical),
        EarthField::default(),
        LatLonAlt::default(),
        Vector3::zeros(),
        3,
    );
    let mut est = AttitudeEstimator::new(&AttitudeParams::default());
    let (mut tilt_ok, mut heading_ok) = (f64::NAN, f64::NAN);
    let glitch_k = (10.0 / DT) as usize;
    for k in 1..=(25.0 / DT) as usize {
        let t = k as f64 * DT;
        let f = super::tests::sample_at(&mut sensors, t, truth, Vector3::zeros(), Vector3::zeros());
        let mut gyro = f.gyro_frd_rad_s;
        if k == glitch_k {
            gyro += glitch / DT;
        }
        let input = AttitudeInput {
            gyro,
            accel: f.accel_frd_m_s2,
            mag: (f.fields_updated & fields::MAG != 0).then_some(f.mag_frd_gauss),
            accel_ned_hint: armed.then_some(Vector3::zeros()),
            vel_ned_hint: armed.then_some(Vector3::zeros()),
            gps_vel: None,
            thrust_fraction: 0.0,
            armed,
        };
        let Some(e) = est.update(&input, DT) else {
            continue;
        };
        if k < glitch_k {
            continue;
        }
        let since = t - glitch_k as f64 * DT;
        if tilt_error(&e.q, &truth) > 2f64.to_radians() {
            tilt_ok = f64::NAN;
        } else if tilt_ok.is_nan() {
            tilt_ok = since;
        }
        if heading_error(&e.q, &truth).abs() > 5f64.to_radians() {
            heading_ok = f64::NAN;
        } else if heading_ok.is_nan() {
            heading_ok = since;
        }
    }
    let resets = est.status().tilt_heading.reset.tilt;
    (tilt_ok, heading_ok, resets)
}

#[test]
fn any_error_at_rest_is_gone_within_seconds() {
    let truth = UnitQuaternion::from_euler_angles(0.05, -0.03, 0.7);
    for (deg, axis) in [
        (3.0, Vector3::x()),
        (10.0, Vector3::x()),
        (45.0, Vector3::new(1.0, 1.0, 0.0)),
        (90.0, Vector3::y()),
        (135.0, Vector3::new(1.0, -0.5, 0.3)),
        (179.0, Vector3::new(0.2, 1.0, 0.1)),
        (120.0, Vector3::z()), // heading alone
    ] {
        let glitch = axis.normalize() * f64::to_radians(deg);
        let (tilt_s, heading_s, resets) = glitch_at_rest(truth, glitch, false);
        println!(
            "{deg:5.0}° about {axis:?}: tilt within 2° after {tilt_s:.2} s, heading within 5° after {heading_s:.2} s, {resets} tilt resets"
        );
        assert!(tilt_s <= 2.0, "{deg}°: tilt after {tilt_s} s");
        assert!(heading_s <= 5.0, "{deg}°: heading after {heading_s} s");
    }
}

#[test]
fn a_thirty_degree_error_in_a_steady_hover_is_gone_within_three_seconds() {
    let truth = UnitQuaternion::from_euler_angles(0.0, 0.0, -1.2);
    let glitch = Vector3::new(1.0, 0.4, 0.0).normalize() * 30f64.to_radians();
    let (tilt_s, _, resets) = glitch_at_rest(truth, glitch, true);
    println!("30° armed: tilt within 2° after {tilt_s:.2} s, {resets} tilt resets");
    assert!(tilt_s <= 3.0, "tilt after {tilt_s} s");
}
