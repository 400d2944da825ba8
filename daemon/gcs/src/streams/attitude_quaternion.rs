//! `ATTITUDE_QUATERNION`.

use super::prelude::*;

/// `ATTITUDE_QUATERNION` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let att = s.att;
    let ms = s.ms;
    let a = att?;
    let q = a.q.quaternion();
    let w = a.rate;
    Some(MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
        time_boot_ms: ms,
        q1: q.w as f32,
        q2: q.i as f32,
        q3: q.j as f32,
        q4: q.k as f32,
        rollspeed: w.x as f32,
        pitchspeed: w.y as f32,
        yawspeed: w.z as f32,
        repr_offset_q: [0.0; 4],
    }))
}
