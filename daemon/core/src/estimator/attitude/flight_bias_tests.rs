//! The gyro bias learned in flight, with no rest to learn it from: a MEMS-grade bias of about
//! 1.1°/s from the first sample, and a step of 0.01 rad/s in mid-flight (a turn-on bias and a
//! temperature change), with typical noise otherwise.

use super::*;
use crate::math::geo::LatLonAlt;
use crate::params::AttitudeParams;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, fields};

const G: f64 = crate::GRAVITY_M_S2;
const DT: f64 = 0.004;
/// When the bias steps (s).
const STEP_AT_S: f64 = 75.0;

/// A flight with no rest: rolling and pitching by up to 14° and turning at about 9°/s, on
/// thrust alone (so it accelerates whenever it tilts; the position estimator's velocity is
/// given, as the daemon gives it).
fn attitude_at(t: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(
        0.25 * (0.4 * t).sin(),
        0.2 * (0.31 * t + 1.0).sin(),
        0.15 * t + 0.5 * (0.05 * t).sin(),
    )
}

fn true_bias(t: f64) -> Vector3<f64> {
    let turn_on = Vector3::new(1.0, -0.8, 0.6).normalize() * 0.02;
    let step = Vector3::new(-0.3, 0.5, 1.0).normalize() * 0.01;
    if t < STEP_AT_S {
        turn_on
    } else {
        turn_on + step
    }
}

struct BiasRun {
    /// The bias error at each second (rad/s).
    error_by_second: Vec<f64>,
    attitude_rms_deg: f64,
    /// The attitude error (deg) at each sample with an estimate, and its time (s).
    attitude_error_deg: Vec<(f64, f64)>,
    /// The tilt resets the estimate reported.
    tilt_resets: u64,
}

fn fly(params: &AttitudeParams, duration_s: f64, bias: fn(f64) -> Vector3<f64>) -> BiasRun {
    let cfg = SensorConfig {
        gyro_bias_sigma: 0.0,
        gyro_bias_walk: 0.0,
        ..SensorConfig::preset(SensorPreset::Typical)
    };
    let mut sensors = SensorSuite::new(
        cfg,
        EarthField::default(),
        LatLonAlt::default(),
        Vector3::zeros(),
        7,
    );
    let mut est = AttitudeEstimator::new(params);
    let (mut error_by_second, mut sum_sq, mut n) = (Vec::new(), 0.0, 0usize);
    let (mut attitude_error_deg, mut tilt_resets) = (Vec::new(), 0);
    let steps = (duration_s / DT).round() as usize;
    let mut vel = Vector3::zeros();
    for k in 1..=steps {
        let t = k as f64 * DT;
        let q = attitude_at(t);
        let rate = (attitude_at(t - DT).inverse() * q).scaled_axis() / DT;
        let up = q * Vector3::new(0.0, 0.0, -1.0);
        let a_ned = up * (G / -up.z) + Vector3::new(0.0, 0.0, G);
        vel += a_ned * DT;
        let f = super::tests::sample_at(&mut sensors, t, q, rate, a_ned);
        let input = AttitudeInput {
            gyro: f.gyro_frd_rad_s + bias(t),
            accel: f.accel_frd_m_s2,
            mag: (f.fields_updated & fields::MAG != 0).then_some(f.mag_frd_gauss),
            accel_ned_hint: Some(a_ned),
            vel_ned_hint: Some(vel),
            gps_vel: None,
            thrust_fraction: 0.0,
            armed: true,
        };
        let Some(e) = est.update(&input, DT) else {
            continue;
        };
        if k % (1.0 / DT).round() as usize == 0 {
            error_by_second.push((e.gyro_bias - bias(t)).norm());
        }
        let err = e.q.angle_to(&q);
        attitude_error_deg.push((t, err.to_degrees()));
        tilt_resets = e.reset.tilt;
        if t > 10.0 {
            sum_sq += err * err;
            n += 1;
        }
    }
    BiasRun {
        error_by_second,
        attitude_rms_deg: (sum_sq / n as f64).sqrt().to_degrees(),
        attitude_error_deg,
        tilt_resets,
    }
}

/// The second from which the error stays within `bound` until `until_s` (exclusive).
fn settled_at(errors: &[f64], from_s: usize, until_s: usize, bound: f64) -> Option<usize> {
    let window = &errors[from_s..until_s - 1];
    match window.iter().rposition(|e| *e > bound) {
        None => Some(from_s),
        Some(i) if from_s + i + 2 < until_s => Some(from_s + i + 2),
        Some(_) => None,
    }
}

/// The must-hold: within 0.002 rad/s of a 0.02 rad/s bias within 60 s of flight, and
/// again within 60 s of a 0.01 rad/s step.
#[test]
fn the_bias_is_learned_in_flight_and_tracks_a_step() {
    let params = AttitudeParams {
        mode: 1,
        ..AttitudeParams::default()
    };
    let duration = 2.0 * STEP_AT_S;
    let run = fly(&params, duration, true_bias);
    let e = &run.error_by_second;
    let step = STEP_AT_S as usize;
    let first = settled_at(e, 0, step, 0.002);
    let second = settled_at(e, step, duration as usize, 0.002).map(|s| s - step);
    println!(
        "in-flight bias: within 0.002 rad/s after {first:?} s, after the step within {second:?} s; \
         errors at 30/60/{}/{} s: {:.4} {:.4} {:.4} {:.4} rad/s; attitude RMS {:.2} deg",
        step + 30,
        step + 60,
        e[29],
        e[59],
        e[step + 29],
        e[step + 59],
        run.attitude_rms_deg
    );
    assert!(first.is_some_and(|s| s <= 60), "{first:?}");
    assert!(second.is_some_and(|s| s <= 60), "{second:?}");
}

/// A start in motion with a MEMS gyro's turn-on bias of 1.2°/s on every axis, in a clean field:
/// the first seconds fitted at once (`motion_start.rs`). This flight is the hard case: on thrust
/// alone the accelerometer shows the tilt only through the known acceleration, and in 4 s the
/// bias about the field's axis is seen only through that tilt. Without the fit the largest error
/// is 10.7° from 5 s to 12 s and 4.6° after; with it 6.2° and 1.7°.
#[test]
fn a_start_in_motion_with_a_large_bias_converges_at_once() {
    let params = AttitudeParams {
        mode: 1,
        ..AttitudeParams::default()
    };
    let run = fly(&params, 30.0, |_| Vector3::repeat(1.2f64.to_radians()));
    let worst = |from: f64, to: f64| {
        run.attitude_error_deg
            .iter()
            .filter(|(t, _)| (from..to).contains(t))
            .map(|(_, e)| *e)
            .fold(0.0, f64::max)
    };
    let (early, late) = (worst(5.0, 12.0), worst(12.0, 30.0));
    println!("start in motion: largest error 5–12 s {early:.2}°, from 12 s {late:.2}°");
    // The fit's jump of the estimate is reported, once.
    assert_eq!(run.tilt_resets, 1);
    assert!(early <= 7.0, "{early}");
    assert!(late <= 2.0, "{late}");
}
