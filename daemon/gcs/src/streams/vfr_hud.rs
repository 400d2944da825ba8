//! `VFR_HUD`.

use super::prelude::*;

/// `VFR_HUD` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let out = s.out;
    let att = s.att;
    let tr = s.tr;
    let frame = s.frame;
    let tr = tr?;
    let o = out?;
    let alt = frame.map_or(-tr.pos_ned_m.z, |f| f.to_geodetic(&tr.pos_ned_m).alt_m);
    let yaw = att.map_or(0.0, |a| a.q.euler_angles().2);
    let n = o.commands.iter().filter(|c| **c > 0.0).count().max(1);
    let throttle = o.commands.iter().sum::<f64>() / n as f64;
    // The air-relative speed where the wind is known, the ground speed before.
    let air = o
        .wind
        .map_or(tr.vel_ned_m_s, |w| tr.vel_ned_m_s - w.wind_ned_m_s);
    Some(MavMessage::VFR_HUD(VFR_HUD_DATA {
        airspeed: air.xy().norm() as f32,
        groundspeed: tr.vel_ned_m_s.xy().norm() as f32,
        alt: alt as f32,
        climb: -tr.vel_ned_m_s.z as f32,
        heading: yaw.to_degrees().rem_euclid(360.0) as i16,
        throttle: (throttle * 100.0).clamp(0.0, 100.0) as u16,
    }))
}
