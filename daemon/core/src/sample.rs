//! What the flight core takes and gives: one sample of the flight board's sensors, and what
//! one step produced. The sensor checks, the calibrations and the failure injection work on
//! samples too; every one of them imports from here, not from the flight core.

use crate::control::disturbance::WindEstimate;
use crate::control::position::AttitudeSetpoint;
use crate::estimator::attitude::AttitudeEstimate;
use crate::estimator::translation::{GpsMeasurement, TranslationEstimate};
use crate::mixer::MixerOutput;
use crate::safety::motor_failure::MotorFailure;
use airframe::MAX_ROTORS;
use nalgebra::Vector3;

/// One sample of the flight board's sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSample {
    /// Time of the sample (µs).
    pub t_usec: u64,
    /// Mean gyro rate over the interval, FRD (rad/s).
    pub gyro: Vector3<f64>,
    /// Mean specific force over the interval, FRD (m/s²).
    pub accel: Vector3<f64>,
    /// Magnetometer, when fresh.
    pub mag: Option<Vector3<f64>>,
    /// Barometric altitude (m AMSL), when fresh.
    pub baro_alt_m: Option<f64>,
    /// GPS solution, when one arrived.
    pub gps: Option<GpsMeasurement>,
    /// Battery voltage (V), when the board (or simulator) reports it; the pack's nominal
    /// voltage is flown otherwise.
    pub battery_v: Option<f64>,
    /// Current per ESC (A) by rotor, when reported (their sum is the pack's current).
    pub esc_current_a: Option<[f64; MAX_ROTORS]>,
    /// Rotor speeds from ESC telemetry (rad/s), when fresh.
    pub rotor_speed_rad_s: Option<[f64; MAX_ROTORS]>,
}

impl SensorSample {
    /// The IMU's readings alone, at time 0: every other sensor absent.
    pub fn imu(gyro: Vector3<f64>, accel: Vector3<f64>) -> Self {
        Self {
            t_usec: 0,
            gyro,
            accel,
            mag: None,
            baro_alt_m: None,
            gps: None,
            battery_v: None,
            esc_current_a: None,
            rotor_speed_rad_s: None,
        }
    }
}

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepOutput {
    /// Motor commands ∈ [0, 1] (all zero when disarmed or not aligned).
    pub commands: [f64; MAX_ROTORS],
    /// Attitude estimate, once aligned.
    pub attitude: Option<AttitudeEstimate>,
    /// Translation estimate.
    pub translation: TranslationEstimate,
    /// Position loop output (when flying).
    pub attitude_setpoint: Option<AttitudeSetpoint>,
    /// Rate reference (rad/s).
    pub rate_reference: Vector3<f64>,
    /// The allocation (when flying).
    pub mixer: Option<MixerOutput>,
    /// A rotor declared failed at this step.
    pub motor_failure: Option<MotorFailure>,
    /// The wind the outside force on the vehicle means (armed, once it has flown).
    pub wind: Option<WindEstimate>,
}
