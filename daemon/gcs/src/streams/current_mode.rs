//! `CURRENT_MODE`.

use super::prelude::*;

/// `CURRENT_MODE` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let status = s.status;
    let mode = status.map_or(FlightMode::Loiter, |s| s.mode);
    Some(MavMessage::CURRENT_MODE(CURRENT_MODE_DATA {
        custom_mode: modes::custom_mode(mode),
        intended_custom_mode: modes::custom_mode(mode),
        standard_mode: modes::standard_mode(mode),
    }))
}
