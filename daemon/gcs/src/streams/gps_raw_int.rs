//! `GPS_RAW_INT`: the GPS solution as the receiver gave it, with what a receiver on a serial
//! port says beyond `HIL_GPS` (dilutions, vertical, speed and heading accuracies, its UTC
//! time).

use super::prelude::*;

/// `GPS_RAW_INT` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let t = s.t;
    let g = s.v.and_then(|v| v.gps)?;
    let d = &g.details;
    let speed = g.vel_ned_m_s.xy().norm();
    let cog = g.vel_ned_m_s.y.atan2(g.vel_ned_m_s.x).to_degrees();
    let scaled = |x: f64, k: f64| (x * k).round().clamp(0.0, 65534.0) as u16;
    let wide = |x: f64, k: f64| (x * k).round().clamp(0.0, f64::from(u32::MAX - 1)) as u32;
    let (eph, epv) = match d.dop {
        Some((h, v)) => (scaled(h, 100.0), scaled(v, 100.0)),
        // HIL_GPS carries the horizontal accuracy in its HDOP field (cm), as PX4's simulators do.
        None => (scaled(g.h_acc_m, 100.0), u16::MAX),
    };
    let no_velocity = d.no_horizontal_velocity;
    Some(MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
        time_usec: d.time_utc_usec.unwrap_or((t.link.t_s * 1e6) as u64),
        lat: e7(g.position.lat_deg),
        lon: e7(g.position.lon_deg),
        alt: (g.position.alt_m * 1e3).round() as i32,
        eph,
        epv,
        vel: if no_velocity {
            u16::MAX
        } else {
            scaled(speed, 100.0)
        },
        cog: if no_velocity {
            u16::MAX
        } else {
            (cog.rem_euclid(360.0) * 100.0) as u16
        },
        fix_type: match g.fix_type {
            0 => GpsFixType::GPS_FIX_TYPE_NO_GPS,
            1 => GpsFixType::GPS_FIX_TYPE_NO_FIX,
            2 => GpsFixType::GPS_FIX_TYPE_2D_FIX,
            3 => GpsFixType::GPS_FIX_TYPE_3D_FIX,
            4 => GpsFixType::GPS_FIX_TYPE_DGPS,
            5 => GpsFixType::GPS_FIX_TYPE_RTK_FLOAT,
            _ => GpsFixType::GPS_FIX_TYPE_RTK_FIXED,
        },
        satellites_visible: g.satellites,
        h_acc: wide(g.h_acc_m, 1e3),
        v_acc: d.v_acc_m.map_or(0, |v| wide(v, 1e3)),
        vel_acc: d.s_acc_m_s.map_or(0, |v| wide(v, 1e3)),
        hdg_acc: d.heading_acc_deg.map_or(0, |v| wide(v, 1e5)),
        ..Default::default()
    }))
}
