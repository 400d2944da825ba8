//! `POSITION_TARGET_LOCAL_NED`.

use super::prelude::*;

/// `POSITION_TARGET_LOCAL_NED` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let ms = s.ms;
    let sp = *s.v.and_then(|v| v.setpoint)?.position()?;
    use PositionTargetTypemask as M;
    let mut mask = M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE;
    let ignore = [
        (sp.pos_ned_m.x, M::POSITION_TARGET_TYPEMASK_X_IGNORE),
        (sp.pos_ned_m.y, M::POSITION_TARGET_TYPEMASK_Y_IGNORE),
        (sp.pos_ned_m.z, M::POSITION_TARGET_TYPEMASK_Z_IGNORE),
        (sp.vel_ned_m_s.x, M::POSITION_TARGET_TYPEMASK_VX_IGNORE),
        (sp.vel_ned_m_s.y, M::POSITION_TARGET_TYPEMASK_VY_IGNORE),
        (sp.vel_ned_m_s.z, M::POSITION_TARGET_TYPEMASK_VZ_IGNORE),
    ];
    for (v, m) in ignore {
        if v.is_nan() {
            mask |= m;
        }
    }
    Some(MavMessage::POSITION_TARGET_LOCAL_NED(
        POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms: ms,
            x: sp.pos_ned_m.x as f32,
            y: sp.pos_ned_m.y as f32,
            z: sp.pos_ned_m.z as f32,
            vx: sp.vel_ned_m_s.x as f32,
            vy: sp.vel_ned_m_s.y as f32,
            vz: sp.vel_ned_m_s.z as f32,
            afx: sp.accel_ned_m_s2.x as f32,
            afy: sp.accel_ned_m_s2.y as f32,
            afz: sp.accel_ned_m_s2.z as f32,
            yaw: sp.yaw_rad as f32,
            yaw_rate: 0.0,
            type_mask: mask,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        },
    ))
}
