//! `ORBIT_EXECUTION_STATUS`: the orbit flown, in Orbit only (as PX4).

use super::prelude::*;

/// `ORBIT_EXECUTION_STATUS` while an orbit is flown: its signed radius and its centre, the
/// altitude AMSL (`MAV_FRAME_GLOBAL`).
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let orbit = s.status?.orbit?;
    let c: LatLonAlt = s.frame?.to_geodetic(&orbit.center_ned_m);
    Some(MavMessage::ORBIT_EXECUTION_STATUS(
        ORBIT_EXECUTION_STATUS_DATA {
            time_usec: s.usec,
            radius: orbit.radius_m as f32,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            x: e7(c.lat_deg),
            y: e7(c.lon_deg),
            z: c.alt_m as f32,
        },
    ))
}
