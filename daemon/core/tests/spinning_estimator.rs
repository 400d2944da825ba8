//! The attitude estimator on a quad spinning at 30 rad/s on three rotors: the simulator flies
//! the relaxed hover under the reduced-attitude controller (on the truth), its `typical` IMU at
//! 250 Hz feeds the tilt/heading filter through the autopilot's IMU correction (the lever arm
//! off), with the velocity hint the position estimator gives (here the truth's) and no
//! magnetometer. In relaxed hover the accelerometer reads the thrust's direction, 3° off
//! gravity and turning with the body; the filter's low-pass in its inertial frame must average
//! that out, and the lever arm's 9 m/s² with it.
#![allow(clippy::unwrap_used)]

use flight_core::control::{reduced_attitude::ReducedAttitude, relaxed_hover};
use flight_core::core::SensorSample;
use flight_core::estimator::tilt_heading::{TiltHeadingFilter, TiltHeadingSettings};
use flight_core::sensors::imu_correction::{ImuCalParams, ImuCorrection};
use nalgebra::{UnitQuaternion, Vector3};
use sitl_core::body::BodyState;
use sitl_core::powertrain::Rotors;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::sim::{SimConfig, Simulator};

const G: f64 = 9.806_65;

/// Mean and largest tilt error (deg) over 15 s after the first 5 s of a 20 s spinning hover,
/// the accelerometer's lever arm taken off or not.
fn tilt_errors_deg(lever_arm_off: bool) -> (f64, f64) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    let a = airframe::Airframe::load(&dir.join("quad_x.toml")).unwrap();
    let at = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -20.0),
        ..BodyState::default()
    };
    let probe = Simulator::new(&a, SimConfig::default(), at).unwrap();
    let rho = sitl_core::environment::isa(probe.truth().position().alt_m).density_kg_m3;
    let hover = relaxed_hover::solve_within_spin(&a, 0, 30.0, rho).unwrap();
    let control = ReducedAttitude::new(&a, hover.clone(), 1000.0).unwrap();
    let n = hover.axis_frd;
    let q0 = UnitQuaternion::rotation_between(&n, &-Vector3::z()).unwrap();
    let initial = BodyState {
        q_ned_from_frd: q0,
        rate_frd_rad_s: n * hover.spin_rad_s,
        ..at
    };
    let cfg = SimConfig {
        sensors: SensorConfig::preset(SensorPreset::Typical),
        seed: 3,
        ..SimConfig::default()
    };
    let mut sim = Simulator::new(&a, cfg, initial).unwrap();
    let speeds: Vec<f64> = a
        .rotors
        .iter()
        .zip(&hover.thrust_n)
        .map(|(r, &t)| r.speed_for_thrust_rad_s(rho, t))
        .collect();
    sim.set_rotor_speeds(&speeds);
    let g = Vector3::new(0.0, 0.0, G);
    // Aligned at rest on the start's tilt, as before a take-off.
    let mut filter = TiltHeadingFilter::new(TiltHeadingSettings::default());
    for _ in 0..2500 {
        let at_rest = q0.inverse_transform_vector(&-g);
        filter.update(&Vector3::zeros(), &at_rest, None, None, false, 0.004);
    }
    let arm = if lever_arm_off {
        a.imu_position_frd_m
    } else {
        Vector3::zeros()
    };
    let correction = ImuCorrection::new(&ImuCalParams::default(), arm);
    let (mut worst, mut sum, mut count) = (0.0_f64, 0.0, 0);
    for step in 0..20_000 {
        let t = sim.truth();
        let body = t.body;
        let to = at.pos_ned_m - body.pos_ned_m;
        let lift = to - body.vel_ned_m_s * 1.8 - g;
        let thrusts = control.update(
            &lift.normalize(),
            a.mass_kg * lift.norm(),
            &body.q_ned_from_frd,
            &body.rate_frd_rad_s,
        );
        let v = t.battery_voltage_v;
        let commands: Vec<f64> = a
            .rotors
            .iter()
            .zip(&thrusts)
            .map(|(r, &f)| Rotors::command_for_speed(r, r.speed_for_thrust_rad_s(rho, f), v))
            .collect();
        sim.step(&commands);
        if step % 4 != 3 {
            continue;
        }
        let frame = sim.sample_sensors().clone();
        let sample = correction.apply(&SensorSample {
            t_usec: 0,
            gyro: frame.gyro_frd_rad_s,
            accel: frame.accel_frd_m_s2,
            mag: None,
            baro_alt_m: None,
            gps: None,
            battery_v: None,
            esc_current_a: None,
            rotor_speed_rad_s: None,
        });
        let truth = sim.truth().body;
        let velocity = truth.vel_ned_m_s;
        filter.update(
            &sample.gyro,
            &sample.accel,
            None,
            Some(&velocity),
            true,
            0.004,
        );
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
