//! `SCALED_IMU`.

use super::prelude::*;

/// `SCALED_IMU` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let ms = s.ms;
    // mg, mrad/s, mgauss.
    let s = s.v.and_then(|v| v.held_sample)?;
    let mg = |x: f64| i16_sat(x / flight_core::GRAVITY_M_S2 * 1e3);
    let mag = s.mag.unwrap_or_default() * 1e3;
    Some(MavMessage::SCALED_IMU(SCALED_IMU_DATA {
        time_boot_ms: ms,
        xacc: mg(s.accel.x),
        yacc: mg(s.accel.y),
        zacc: mg(s.accel.z),
        xgyro: i16_sat(s.gyro.x * 1e3),
        ygyro: i16_sat(s.gyro.y * 1e3),
        zgyro: i16_sat(s.gyro.z * 1e3),
        xmag: i16_sat(mag.x),
        ymag: i16_sat(mag.y),
        zmag: i16_sat(mag.z),
        temperature: 0,
    }))
}
