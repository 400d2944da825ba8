//! The sensor models' parameters and their presets.

use crate::GRAVITY_M_S2;
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;

/// `HIL_SENSOR.fields_updated` bits (MAVLink `HIL_SENSOR_UPDATED_FLAGS`).
pub mod fields {
    /// x, y, z accelerometer.
    pub const ACCEL: u32 = 0b111;
    /// x, y, z gyroscope.
    pub const GYRO: u32 = 0b111 << 3;
    /// x, y, z magnetometer.
    pub const MAG: u32 = 0b111 << 6;
    /// Absolute pressure.
    pub const ABS_PRESSURE: u32 = 1 << 9;
    /// Pressure altitude.
    pub const PRESSURE_ALT: u32 = 1 << 11;
    /// Temperature.
    pub const TEMPERATURE: u32 = 1 << 12;
    /// Everything the barometer provides.
    pub const BARO: u32 = ABS_PRESSURE | PRESSURE_ALT | TEMPERATURE;
}

/// Sensor noise presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorPreset {
    /// Perfect sensors: truth, quantised only by f64.
    Ideal,
    /// Datasheet-like MEMS on a soft-mounted flight board (the default).
    #[default]
    Typical,
    /// A poor installation: more noise and vibration, larger biases, a distorted magnetometer.
    Noisy,
    /// What real recordings show and the typical preset spares: a turn-on gyro bias of about
    /// 1°/s that drifts, rotor-frequency vibration, and a magnetic field from the motor currents.
    Realistic,
    /// The typical board before its owner calibrates it: what the gyro, accelerometer and
    /// level-horizon calibrations correct — accelerometer offsets of about 35 mg and scale
    /// errors of 1.5 %, a gyro turn-on bias of about 1°/s, a board mounted 1.5° off level.
    Uncalibrated,
}

impl SensorPreset {
    /// Parses `ideal`, `typical`, `noisy`, `realistic` or `uncalibrated`.
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "ideal" => Some(Self::Ideal),
            "typical" => Some(Self::Typical),
            "noisy" => Some(Self::Noisy),
            "realistic" => Some(Self::Realistic),
            "uncalibrated" => Some(Self::Uncalibrated),
            _ => None,
        }
    }
}

/// Every sensor parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorConfig {
    /// Accelerometer white-noise density (m/s²/√Hz).
    pub accel_noise_density: f64,
    /// Standard deviation of the accelerometer's turn-on bias per axis (m/s²).
    pub accel_bias_sigma: f64,
    /// Accelerometer bias random walk (m/s³/√Hz).
    pub accel_bias_walk: f64,
    /// Standard deviation of the per-axis scale-factor error (fraction).
    pub accel_scale_sigma: f64,
    /// Vibration amplitude per rotor at its top speed (m/s²), scaling with speed².
    pub accel_vibration: f64,
    /// Accelerometer full scale (m/s²).
    pub accel_range: f64,
    /// Standard deviation of the flight board's mounting error in roll and in pitch (deg): the
    /// IMU measures in the board's axes, tilted so from the body's (what PX4's
    /// `SENS_BOARD_X_OFF`/`Y_OFF` correct).
    pub board_tilt_sigma_deg: f64,
    /// Gyroscope white-noise density (rad/s/√Hz).
    pub gyro_noise_density: f64,
    /// Standard deviation of the gyroscope's turn-on bias per axis (rad/s).
    pub gyro_bias_sigma: f64,
    /// Gyroscope bias random walk, the bias instability (rad/s²/√Hz).
    pub gyro_bias_walk: f64,
    /// Gyroscope full scale (rad/s).
    pub gyro_range: f64,
    /// Magnetometer output rate (Hz).
    pub mag_rate_hz: f64,
    /// Magnetometer noise per axis (gauss).
    pub mag_noise: f64,
    /// Hard-iron offset added to the reading (gauss): Castillo (75)'s `offset`.
    pub mag_hard_iron: Vector3<f64>,
    /// Soft-iron matrix S: `raw = S m_body + offset`. Castillo (75)'s calibration
    /// `R E Rᵀ` is `S⁻¹`.
    pub mag_soft_iron: Matrix3<f64>,
    /// Field of the motor currents at full thrust (gauss, body frame), scaled by the mean thrust
    /// fraction `(ω/ω_max)²`: what PX4's `CAL_MAG0_COMP` compensates.
    pub mag_motor_field: Vector3<f64>,
    /// Barometer output rate (Hz).
    pub baro_rate_hz: f64,
    /// Barometer white noise (Pa).
    pub baro_noise_pa: f64,
    /// The weather's pressure change the barometer reads: its rate of change is a Gauss–Markov
    /// process of this stationary σ (Pa/s; 0.014 is 0.5 hPa an hour, a passing front about
    /// twice that) and correlation time `weather_rate_tau_s`, and the change returns to zero
    /// over `weather_tau_s`: smooth, bounded (σ ≈ rate σ · √(τ_rate · τ), about 1.7 hPa or
    /// 14 m for the typical sensors) and seeded.
    pub weather_rate_pa_s: f64,
    /// Correlation time of the pressure's rate of change (s).
    pub weather_rate_tau_s: f64,
    /// Time over which the pressure change returns to zero (s).
    pub weather_tau_s: f64,
    /// GPS output rate (Hz).
    pub gps_rate_hz: f64,
    /// GPS horizontal position error, 1σ (m), correlated over `gps_correlation_s`.
    pub gps_h_sigma: f64,
    /// GPS vertical position error, 1σ (m).
    pub gps_v_sigma: f64,
    /// Correlation time of the GPS position error (s).
    pub gps_correlation_s: f64,
    /// GPS velocity noise per axis (m/s).
    pub gps_vel_sigma: f64,
    /// Age of a GPS solution when it is delivered (s).
    pub gps_latency_s: f64,
    /// Satellites reported while the fix is good.
    pub gps_satellites: u8,
    /// ESC telemetry rate (Hz).
    pub rpm_rate_hz: f64,
    /// Relative noise of the reported rotor speed.
    pub rpm_noise: f64,
}

impl SensorConfig {
    /// The typical preset (the default).
    fn typical() -> Self {
        Self {
            accel_noise_density: 2.0e-3,
            // Residual after the user's accelerometer calibration (every PX4/ArduPilot setup
            // does one): ≈ 2 mg. The raw datasheet offset (±20 mg) is the noisy preset's.
            accel_bias_sigma: 0.02,
            accel_bias_walk: 2.0e-4,
            accel_scale_sigma: 0.003,
            accel_vibration: 0.3,
            accel_range: 16.0 * GRAVITY_M_S2,
            board_tilt_sigma_deg: 0.0,
            gyro_noise_density: 1.7e-4,
            gyro_bias_sigma: 0.3f64.to_radians(),
            gyro_bias_walk: 2.0e-5,
            gyro_range: 2000f64.to_radians(),
            mag_rate_hz: 100.0,
            mag_noise: 0.003,
            mag_hard_iron: Vector3::zeros(),
            mag_soft_iron: Matrix3::identity(),
            mag_motor_field: Vector3::zeros(),
            baro_rate_hz: 50.0,
            baro_noise_pa: 3.0,
            weather_rate_pa_s: 0.014,
            weather_rate_tau_s: 3600.0,
            weather_tau_s: 43_200.0,
            gps_rate_hz: 10.0,
            gps_h_sigma: 0.3,
            gps_v_sigma: 0.6,
            gps_correlation_s: 60.0,
            gps_vel_sigma: 0.05,
            gps_latency_s: 0.1,
            gps_satellites: 14,
            rpm_rate_hz: 50.0,
            rpm_noise: 0.005,
        }
    }

    /// The parameters of a preset.
    pub fn preset(p: SensorPreset) -> Self {
        let typical = Self::typical();
        match p {
            SensorPreset::Typical => typical,
            SensorPreset::Ideal => Self {
                accel_noise_density: 0.0,
                accel_bias_sigma: 0.0,
                accel_bias_walk: 0.0,
                accel_scale_sigma: 0.0,
                accel_vibration: 0.0,
                gyro_noise_density: 0.0,
                gyro_bias_sigma: 0.0,
                gyro_bias_walk: 0.0,
                mag_noise: 0.0,
                baro_noise_pa: 0.0,
                weather_rate_pa_s: 0.0,
                gps_h_sigma: 0.0,
                gps_v_sigma: 0.0,
                gps_vel_sigma: 0.0,
                gps_latency_s: 0.0,
                rpm_noise: 0.0,
                ..typical
            },
            SensorPreset::Noisy => Self {
                accel_noise_density: 6.0e-3,
                accel_bias_sigma: 0.2,
                accel_bias_walk: 1.0e-3,
                accel_scale_sigma: 0.01,
                accel_vibration: 1.5,
                gyro_noise_density: 5.0e-4,
                gyro_bias_sigma: 1.0f64.to_radians(),
                gyro_bias_walk: 1.0e-4,
                mag_noise: 0.008,
                mag_hard_iron: Vector3::new(0.12, -0.08, 0.2),
                mag_soft_iron: Matrix3::new(1.08, 0.04, -0.02, 0.04, 0.95, 0.03, -0.02, 0.03, 1.02),
                baro_noise_pa: 10.0,
                weather_rate_pa_s: 0.028,
                gps_h_sigma: 1.5,
                gps_v_sigma: 3.0,
                gps_vel_sigma: 0.2,
                gps_latency_s: 0.2,
                gps_satellites: 8,
                rpm_noise: 0.02,
                ..typical
            },
            SensorPreset::Realistic => Self {
                // BROAD's gyros: a turn-on bias of 0.5–1.5°/s, not the one seen at the last
                // calibration, drifting by about 0.05°/s a minute.
                gyro_bias_sigma: 0.6f64.to_radians(),
                gyro_bias_walk: 1.0e-4,
                // Rotor imbalance: 0.6 m/s² per rotor at hover, at the rotor frequency.
                accel_vibration: 1.5,
                mag_noise: 0.004,
                // A battery lead under the board: 0.08 gauss at full thrust, about 0.03 (7 % of
                // the Earth's field) at hover.
                mag_motor_field: Vector3::new(0.03, -0.02, 0.07),
                ..typical
            },
            SensorPreset::Uncalibrated => Self {
                // An MPU-6000-class part as delivered: zero-g offset ±35 mg 1σ (datasheet
                // ±50 mg), sensitivity ±1.5 %, zero-rate offset ±1°/s at turn-on.
                accel_bias_sigma: 0.35,
                accel_scale_sigma: 0.015,
                gyro_bias_sigma: 1.0f64.to_radians(),
                board_tilt_sigma_deg: 1.5,
                ..typical
            },
        }
    }
}
