//! What the sensor models take and give: the truth they sample, the frame they report, the
//! site's magnetic field, each sensor's kind and injected health.

use crate::airframe::MAX_ROTORS;
use crate::environment::AirState;
use nalgebra::{UnitQuaternion, Vector3};
use navmath::geo::LatLonAlt;
use serde::Deserialize;

/// The Earth's magnetic field at the flying site.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EarthField {
    /// Total intensity (gauss).
    pub intensity_gauss: f64,
    /// Inclination, positive down (deg).
    pub inclination_deg: f64,
    /// Declination, positive east (deg).
    pub declination_deg: f64,
}

impl Default for EarthField {
    /// Zurich, PX4's default SITL home.
    fn default() -> Self {
        Self {
            intensity_gauss: 0.48,
            inclination_deg: 63.3,
            declination_deg: 3.0,
        }
    }
}

impl EarthField {
    /// The field vector in NED (gauss).
    pub fn ned(&self) -> Vector3<f64> {
        let (si, ci) = self.inclination_deg.to_radians().sin_cos();
        let (sd, cd) = self.declination_deg.to_radians().sin_cos();
        self.intensity_gauss * Vector3::new(ci * cd, ci * sd, si)
    }
}

/// What a sensor is doing: working, silent, or repeating its last value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorHealth {
    /// Working.
    #[default]
    Ok,
    /// Silent: no fresh data (a dead or disconnected sensor).
    Off,
    /// Reports fresh timestamps but the same value every time.
    Stuck,
}

/// Which sensor an injected fault targets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorKind {
    /// Accelerometer and gyroscope together.
    Imu,
    /// Magnetometer.
    Mag,
    /// Barometer.
    Baro,
    /// GPS receiver (off: no messages; see also fix loss).
    Gps,
    /// ESC rpm telemetry.
    Rpm,
}

/// The true state the sensors observe.
#[derive(Debug, Clone, Copy)]
pub struct Truth<'a> {
    /// Simulation time (µs).
    pub time_usec: u64,
    /// Centre-of-mass position in local NED (m).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity in NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Mean linear acceleration over the last step, NED (m/s²).
    pub accel_ned_m_s2: Vector3<f64>,
    /// Attitude.
    pub q_ned_from_frd: UnitQuaternion<f64>,
    /// Body rate (rad/s).
    pub rate_frd_rad_s: Vector3<f64>,
    /// Mean angular acceleration over the last step (rad/s²).
    pub ang_accel_frd_rad_s2: Vector3<f64>,
    /// Air at the vehicle.
    pub air: AirState,
    /// Rotor speeds (rad/s).
    pub rotor_speed_rad_s: &'a [f64],
    /// Rotor top speeds (rad/s), for vibration scaling.
    pub rotor_max_speed_rad_s: &'a [f64],
}

/// A GPS solution as a receiver reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsFix {
    /// Time of the solution (µs, simulation clock) — older than the delivery time by the latency.
    pub time_usec: u64,
    /// 0–1: no fix, 3: 3D fix.
    pub fix_type: u8,
    /// Position.
    pub position: LatLonAlt,
    /// Velocity in NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Horizontal position accuracy 1σ (m).
    pub h_acc_m: f64,
    /// Vertical position accuracy 1σ (m).
    pub v_acc_m: f64,
    /// Speed accuracy 1σ (m/s).
    pub s_acc_m_s: f64,
    /// Satellites used.
    pub satellites: u8,
}

/// One frame of sensor output.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorFrame {
    /// Sample time (µs).
    pub time_usec: u64,
    /// Specific force at the IMU in FRD (m/s²): level at rest reads z ≈ −9.81.
    pub accel_frd_m_s2: Vector3<f64>,
    /// Angular rate in FRD (rad/s).
    pub gyro_frd_rad_s: Vector3<f64>,
    /// Magnetic field in FRD (gauss), distorted as configured.
    pub mag_frd_gauss: Vector3<f64>,
    /// Static pressure (hPa).
    pub abs_pressure_hpa: f64,
    /// Pressure altitude (m AMSL, ISA).
    pub pressure_alt_m: f64,
    /// Air temperature (°C).
    pub temperature_c: f64,
    /// `HIL_SENSOR.fields_updated`: which of the above are fresh in this frame.
    pub fields_updated: u32,
    /// A GPS solution delivered in this frame, if any.
    pub gps: Option<GpsFix>,
    /// Rotor speeds (rpm) when fresh.
    pub rotor_rpm: Option<[f64; MAX_ROTORS]>,
}
