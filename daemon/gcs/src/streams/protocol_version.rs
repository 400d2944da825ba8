//! `PROTOCOL_VERSION`: MAVLink 2 spoken (and 1 understood), as the spec asks a MAVLink 2
//! system to answer.

use super::prelude::*;

/// `PROTOCOL_VERSION`: 200, from 100 to 200; no hashes of the definitions.
pub(super) fn message(_: &StreamInput) -> Option<MavMessage> {
    Some(MavMessage::PROTOCOL_VERSION(PROTOCOL_VERSION_DATA {
        version: 200,
        min_version: 100,
        max_version: 200,
        spec_version_hash: [0; 8],
        library_version_hash: [0; 8],
    }))
}
