//! `SYSTEM_TIME`.

use super::prelude::*;

/// `SYSTEM_TIME` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let ms = s.ms;
    let unix_usec = s.unix_usec;
    Some(MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
        time_unix_usec: unix_usec,
        time_boot_ms: ms,
    }))
}
