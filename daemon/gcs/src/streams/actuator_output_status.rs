//! `ACTUATOR_OUTPUT_STATUS`.

use super::prelude::*;

/// `ACTUATOR_OUTPUT_STATUS` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let out = s.out;
    let usec = s.usec;
    let o = out?;
    let mut actuator = [0.0f32; 32];
    for (a, c) in actuator.iter_mut().zip(o.commands.iter()) {
        *a = *c as f32;
    }
    Some(MavMessage::ACTUATOR_OUTPUT_STATUS(
        ACTUATOR_OUTPUT_STATUS_DATA {
            time_usec: usec,
            active: (1u32 << o.commands.len().min(31)) - 1,
            actuator,
        },
    ))
}
