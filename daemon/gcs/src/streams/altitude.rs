//! `ALTITUDE`.

use super::prelude::*;

/// `ALTITUDE` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let t = s.t;
    let tr = s.tr;
    let status = s.status;
    let frame = s.frame;
    let tr = tr.filter(|t| t.vertical_valid)?;
    let amsl = frame.map_or(f64::NAN, |f| f.to_geodetic(&tr.pos_ned_m).alt_m);
    let home_down = status.and_then(|s| s.home).map_or(0.0, |h| h.0.z);
    Some(MavMessage::ALTITUDE(ALTITUDE_DATA {
        time_usec: (t.link.t_s * 1e6) as u64,
        altitude_monotonic: amsl as f32,
        altitude_amsl: amsl as f32,
        altitude_local: -tr.pos_ned_m.z as f32,
        altitude_relative: (home_down - tr.pos_ned_m.z) as f32,
        altitude_terrain: f32::NAN,
        bottom_clearance: f32::NAN,
    }))
}
