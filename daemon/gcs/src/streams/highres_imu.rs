//! `HIGHRES_IMU`.

use super::prelude::*;

/// `HIGHRES_IMU` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let s = s.v.and_then(|v| v.held_sample)?;
    let mag = s.mag.unwrap_or(nalgebra::Vector3::repeat(f64::NAN));
    let alt = s.baro_alt_m.unwrap_or(f64::NAN);
    use HighresImuUpdatedFlags as F;
    Some(MavMessage::HIGHRES_IMU(HIGHRES_IMU_DATA {
        time_usec: s.t_usec,
        xacc: s.accel.x as f32,
        yacc: s.accel.y as f32,
        zacc: s.accel.z as f32,
        xgyro: s.gyro.x as f32,
        ygyro: s.gyro.y as f32,
        zgyro: s.gyro.z as f32,
        xmag: mag.x as f32,
        ymag: mag.y as f32,
        zmag: mag.z as f32,
        abs_pressure: isa_pressure_hpa(alt) as f32,
        diff_pressure: 0.0,
        pressure_alt: alt as f32,
        temperature: f32::NAN,
        fields_updated: F::HIGHRES_IMU_UPDATED_XACC
            | F::HIGHRES_IMU_UPDATED_YACC
            | F::HIGHRES_IMU_UPDATED_ZACC
            | F::HIGHRES_IMU_UPDATED_XGYRO
            | F::HIGHRES_IMU_UPDATED_YGYRO
            | F::HIGHRES_IMU_UPDATED_ZGYRO
            | F::HIGHRES_IMU_UPDATED_XMAG
            | F::HIGHRES_IMU_UPDATED_YMAG
            | F::HIGHRES_IMU_UPDATED_ZMAG
            | F::HIGHRES_IMU_UPDATED_ABS_PRESSURE
            | F::HIGHRES_IMU_UPDATED_PRESSURE_ALT,
        id: 0,
    }))
}
