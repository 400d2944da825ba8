//! The simulator's ground truth as `HIL_STATE_QUATERNION` carries it: what the records score a
//! flight against and a ground station may be shown.

use airframe::GRAVITY_M_S2;
use mavlink::dialects::common::HIL_STATE_QUATERNION_DATA;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// The simulator's ground truth as `HIL_STATE_QUATERNION` carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthReport {
    /// Time of the truth (µs).
    pub time_usec: u64,
    /// Attitude, `q_ned_from_frd`.
    pub q: UnitQuaternion<f64>,
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude (m AMSL).
    pub alt_m: f64,
    /// Velocity NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Body rate FRD (rad/s).
    pub rate_frd_rad_s: Vector3<f64>,
    /// Specific force FRD (m/s²), from the message's milli-g.
    pub specific_force_frd_m_s2: Vector3<f64>,
}

impl From<&HIL_STATE_QUATERNION_DATA> for TruthReport {
    fn from(q: &HIL_STATE_QUATERNION_DATA) -> Self {
        let a = q.attitude_quaternion;
        let v = |x: i16, y: i16, z: i16| Vector3::new(x as f64, y as f64, z as f64);
        Self {
            time_usec: q.time_usec,
            q: UnitQuaternion::new_normalize(Quaternion::new(
                a[0] as f64,
                a[1] as f64,
                a[2] as f64,
                a[3] as f64,
            )),
            lat_deg: q.lat as f64 * 1e-7,
            lon_deg: q.lon as f64 * 1e-7,
            alt_m: q.alt as f64 * 1e-3,
            vel_ned_m_s: v(q.vx, q.vy, q.vz) * 0.01,
            rate_frd_rad_s: Vector3::new(
                q.rollspeed as f64,
                q.pitchspeed as f64,
                q.yawspeed as f64,
            ),
            specific_force_frd_m_s2: v(q.xacc, q.yacc, q.zacc) * (GRAVITY_M_S2 / 1000.0),
        }
    }
}
