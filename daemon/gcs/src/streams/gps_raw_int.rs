//! `GPS_RAW_INT`.

use super::prelude::*;

/// `GPS_RAW_INT` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let t = s.t;
    let g = s.v.and_then(|v| v.gps)?;
    let speed = g.vel_ned_m_s.xy().norm();
    let cog = g.vel_ned_m_s.y.atan2(g.vel_ned_m_s.x).to_degrees();
    Some(MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
        time_usec: (t.link.t_s * 1e6) as u64,
        lat: e7(g.position.lat_deg),
        lon: e7(g.position.lon_deg),
        alt: (g.position.alt_m * 1e3).round() as i32,
        eph: (g.h_acc_m * 100.0).clamp(0.0, 65534.0) as u16,
        epv: u16::MAX,
        vel: (speed * 100.0).clamp(0.0, 65534.0) as u16,
        cog: (cog.rem_euclid(360.0) * 100.0) as u16,
        fix_type: match g.fix_type {
            0 => GpsFixType::GPS_FIX_TYPE_NO_GPS,
            1 => GpsFixType::GPS_FIX_TYPE_NO_FIX,
            2 => GpsFixType::GPS_FIX_TYPE_2D_FIX,
            _ => GpsFixType::GPS_FIX_TYPE_3D_FIX,
        },
        satellites_visible: g.satellites,
        h_acc: (g.h_acc_m * 1e3) as u32,
        ..Default::default()
    }))
}
