//! `GLOBAL_POSITION_INT`.

use super::prelude::*;

/// `GLOBAL_POSITION_INT` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let att = s.att;
    let tr = s.tr;
    let status = s.status;
    let frame = s.frame;
    let ms = s.ms;
    let tr = tr.filter(|t| t.horizontal_valid)?;
    let g = frame?.to_geodetic(&tr.pos_ned_m);
    let home_down = status.and_then(|s| s.home).map_or(0.0, |h| h.0.z);
    let v = tr.vel_ned_m_s * 100.0;
    let yaw = att.map_or(0.0, |a| a.q.euler_angles().2);
    Some(MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: ms,
        lat: e7(g.lat_deg),
        lon: e7(g.lon_deg),
        alt: (g.alt_m * 1e3).round() as i32,
        relative_alt: ((home_down - tr.pos_ned_m.z) * 1e3).round() as i32,
        vx: v.x.clamp(-32767.0, 32767.0) as i16,
        vy: v.y.clamp(-32767.0, 32767.0) as i16,
        vz: v.z.clamp(-32767.0, 32767.0) as i16,
        hdg: (yaw.to_degrees().rem_euclid(360.0) * 100.0) as u16,
    }))
}
