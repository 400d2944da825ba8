//! `HIL_STATE_QUATERNION`.

use super::prelude::*;

/// `HIL_STATE_QUATERNION` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let t = s.t;
    let g = t.link.truth?;
    let q = g.q.quaternion();
    let w = g.rate_frd_rad_s;
    let v = g.vel_ned_m_s * 100.0;
    let f = g.specific_force_frd_m_s2 / flight_core::GRAVITY_M_S2 * 1e3;
    Some(MavMessage::HIL_STATE_QUATERNION(
        HIL_STATE_QUATERNION_DATA {
            time_usec: g.time_usec,
            attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
            rollspeed: w.x as f32,
            pitchspeed: w.y as f32,
            yawspeed: w.z as f32,
            lat: e7(g.lat_deg),
            lon: e7(g.lon_deg),
            alt: (g.alt_m * 1e3).round() as i32,
            vx: i16_sat(v.x),
            vy: i16_sat(v.y),
            vz: i16_sat(v.z),
            ind_airspeed: 0,
            true_airspeed: 0,
            xacc: i16_sat(f.x),
            yacc: i16_sat(f.y),
            zacc: i16_sat(f.z),
        },
    ))
}
