//! `LOCAL_POSITION_NED`.

use super::prelude::*;

/// `LOCAL_POSITION_NED` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let tr = s.tr;
    let ms = s.ms;
    let tr = tr.filter(|t| t.vertical_valid)?;
    let (p, v) = (tr.pos_ned_m, tr.vel_ned_m_s);
    Some(MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
        time_boot_ms: ms,
        x: p.x as f32,
        y: p.y as f32,
        z: p.z as f32,
        vx: v.x as f32,
        vy: v.y as f32,
        vz: v.z as f32,
    }))
}
