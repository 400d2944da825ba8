//! The accelerometer's bias learned by the tilt/heading filter from a 10 Hz GPS velocity: a
//! level vehicle hovering with a biased accelerometer, at one heading and turning.

use super::*;
use crate::estimator::tilt_heading::{
    DelayedVelocity, FilterInput, TiltHeadingFilter, TiltHeadingSettings,
};

const BIAS: Vector3<f64> = Vector3::new(0.1, -0.06, 0.05);

/// Flies `seconds` of a level hover turning at `yaw_rate` (rad/s), one way for 3 s and back the
/// next, with the accelerometer biased by [`BIAS`] and a clean field; returns the tilt error at
/// the end (deg) and the filter.
fn hover(yaw_rate: f64, seconds: f64) -> (f64, TiltHeadingFilter) {
    let mut f = TiltHeadingFilter::new(TiltHeadingSettings::default());
    let field_ned = Vector3::new(0.2, 0.0, 0.4);
    let dt = 0.004;
    let mut q = UnitQuaternion::identity();
    for i in 0..(seconds / dt) as usize {
        let back = (i as f64 * dt / 3.0) as usize % 2 == 1;
        let rate = Vector3::new(0.0, 0.0, if back { -yaw_rate } else { yaw_rate });
        q *= UnitQuaternion::from_scaled_axis(rate * dt);
        let gps = (i % 25 == 0).then_some(DelayedVelocity {
            vel_ned_m_s: Vector3::zeros(),
            age_s: 0.1,
        });
        let input = FilterInput {
            gyro: rate,
            accel: q.inverse() * Vector3::new(0.0, 0.0, -GRAVITY_M_S2) + BIAS,
            mag: (i % 4 == 0).then(|| q.inverse() * field_ned),
            vel_ned: Some(Vector3::zeros()),
            gps_vel: gps,
            armed: true,
        };
        f.update(&input, dt);
    }
    let down = |q: &UnitQuaternion<f64>| q.inverse() * Vector3::z();
    (down(&f.attitude()).angle(&down(&q)).to_degrees(), f)
}

#[test]
fn turning_back_and_forth_separates_the_bias_from_the_tilt() {
    let floor = (BIAS.xy().norm() / GRAVITY_M_S2).atan().to_degrees();
    let (tilt, f) = hover(1.0, 120.0);
    let (bias, sigma) = f.accel_bias();
    println!(
        "turning: tilt error {tilt:.3}° (the bias alone: {floor:.2}°), bias {bias:.3?} ± {sigma:.3?} gyro bias {:.4?} deg/s",
        f.bias() * 57.3
    );
    assert!((bias - BIAS).norm() < 0.02, "{bias:?}");
    assert!(tilt < 0.1, "{tilt}");
}

#[test]
fn at_one_heading_only_the_vertical_bias_is_learned() {
    let (tilt, f) = hover(0.0, 120.0);
    let (bias, sigma) = f.accel_bias();
    println!("one heading: tilt error {tilt:.3}°, bias {bias:.3?} ± {sigma:.3?}");
    assert!((bias.z - BIAS.z).abs() < 0.02, "{bias:?}");
    // Not observable: the horizontal bias is left near its prior, uncertain, not invented.
    assert!(sigma.x > 0.1 && sigma.y > 0.1, "{sigma:?}");
}
