//! The attitude estimator on a quad spinning at 30 rad/s on three rotors: the simulator flies
//! the relaxed hover under the reduced-attitude controller (on the truth), its `typical` IMU at
//! 250 Hz feeds the tilt/heading filter through the autopilot's IMU correction (the lever arm
//! off), with the velocity hint the position estimator gives (here the truth's) and no
//! magnetometer. In relaxed hover the accelerometer reads the thrust's direction, 3° off
//! gravity and turning with the body; the filter's low-pass in its inertial frame must average
//! that out, and the lever arm's 9 m/s² with it.
#![allow(clippy::unwrap_used, missing_docs)]

mod spinning_hover;

use flight_core::core::SensorSample;
use flight_core::estimator::tilt_heading::{FilterInput, TiltHeadingFilter, TiltHeadingSettings};
use flight_core::sensors::imu_correction::{ImuCalParams, ImuCorrection};
use nalgebra::Vector3;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::sim::SimConfig;
use spinning_hover::SpinningHover;

const G: f64 = 9.806_65;

/// Mean and largest tilt error (deg) over 15 s after the first 5 s of a 20 s spinning hover,
/// the accelerometer's lever arm taken off or not.
fn tilt_errors_deg(lever_arm_off: bool) -> (f64, f64) {
    let cfg = SimConfig {
        sensors: SensorConfig::preset(SensorPreset::Typical),
        seed: 3,
        ..SimConfig::default()
    };
    let mut flight = SpinningHover::new("quad_x", 0, 0.0, cfg);
    let g = Vector3::new(0.0, 0.0, G);
    // Aligned at rest on the start's tilt, as before a take-off.
    let q0 = flight.sim.truth().body.q_ned_from_frd;
    let mut filter = TiltHeadingFilter::new(TiltHeadingSettings::default());
    for _ in 0..2500 {
        let at_rest = q0.inverse_transform_vector(&-g);
        let input = FilterInput {
            gyro: Vector3::zeros(),
            accel: at_rest,
            mag: None,
            vel_ned: None,
            gps_vel: None,
            armed: false,
        };
        filter.update(&input, 0.004);
    }
    let arm = if lever_arm_off {
        flight.airframe.imu_position_frd_m
    } else {
        Vector3::zeros()
    };
    let correction = ImuCorrection::new(&ImuCalParams::default(), arm);
    let (mut worst, mut sum, mut count) = (0.0_f64, 0.0, 0);
    for step in 0..20_000 {
        flight.step();
        if step % 4 != 3 {
            continue;
        }
        let frame = flight.sim.sample_sensors().clone();
        let sample = correction.apply(&SensorSample::imu(
            frame.gyro_frd_rad_s,
            frame.accel_frd_m_s2,
        ));
        let truth = flight.sim.truth().body;
        let velocity = truth.vel_ned_m_s;
        let input = FilterInput {
            gyro: sample.gyro,
            accel: sample.accel,
            mag: None,
            vel_ned: Some(velocity),
            gps_vel: None,
            armed: true,
        };
        filter.update(&input, 0.004);
        let down_true = truth.q_ned_from_frd.inverse_transform_vector(&g);
        let down_estimated = filter.attitude().inverse_transform_vector(&g);
        let error = down_true.angle(&down_estimated).to_degrees();
        if step >= 5_000 {
            worst = worst.max(error);
            sum += error;
            count += 1;
        }
    }
    (sum / f64::from(count), worst)
}

#[test]
fn the_tilt_holds_on_a_quad_spinning_at_30_rad_s() {
    let (mean, worst) = tilt_errors_deg(true);
    let (mean_raw, worst_raw) = tilt_errors_deg(false);
    println!(
        "tilt error at 30 rad/s: {mean:.3}° mean, {worst:.3}° largest; with the lever arm \
         left in: {mean_raw:.3}°, {worst_raw:.3}°"
    );
    assert!(mean < 0.05 && worst < 0.12, "{mean} {worst}");
    assert!(worst < worst_raw, "the lever arm taken off helps");
}
