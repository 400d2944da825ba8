//! `ATTITUDE_TARGET`.

use super::prelude::*;

/// `ATTITUDE_TARGET` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let out = s.out;
    let ms = s.ms;
    let sp = out?.attitude_setpoint?;
    let q = sp.q_d.quaternion();
    let w = out?.rate_reference;
    Some(MavMessage::ATTITUDE_TARGET(ATTITUDE_TARGET_DATA {
        time_boot_ms: ms,
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        body_roll_rate: w.x as f32,
        body_pitch_rate: w.y as f32,
        body_yaw_rate: w.z as f32,
        thrust: (sp.thrust_n / s.v.map_or(0.0, |v| v.max_thrust_n).max(1e-9)).clamp(0.0, 1.0)
            as f32,
        type_mask: AttitudeTargetTypemask::empty(),
    }))
}
