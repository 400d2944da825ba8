//! `ATTITUDE`.

use super::prelude::*;

/// `ATTITUDE` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let att = s.att;
    let ms = s.ms;
    let a = att?;
    let (roll, pitch, yaw) = a.q.euler_angles();
    let w = a.rate;
    Some(MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: ms,
        roll: roll as f32,
        pitch: pitch as f32,
        yaw: yaw as f32,
        rollspeed: w.x as f32,
        pitchspeed: w.y as f32,
        yawspeed: w.z as f32,
    }))
}
