//! `EXTENDED_SYS_STATE`.

use super::prelude::*;

/// `EXTENDED_SYS_STATE` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let status = s.status;
    let landed = match status?.landed {
        LandedState::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
        LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
        LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
        LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
    };
    Some(MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
        vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
        landed_state: landed,
    }))
}
