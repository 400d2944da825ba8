//! `HOME_POSITION`.

use super::prelude::*;

/// `HOME_POSITION` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let t = s.t;
    let status = s.status;
    let frame = s.frame;
    let (home, yaw) = status?.home?;
    let g: LatLonAlt = frame?.to_geodetic(&home);
    let (s, c) = (yaw * 0.5).sin_cos();
    Some(MavMessage::HOME_POSITION(HOME_POSITION_DATA {
        latitude: e7(g.lat_deg),
        longitude: e7(g.lon_deg),
        altitude: (g.alt_m * 1e3).round() as i32,
        x: home.x as f32,
        y: home.y as f32,
        z: home.z as f32,
        q: [c as f32, 0.0, 0.0, s as f32],
        approach_x: 0.0,
        approach_y: 0.0,
        approach_z: 0.0,
        time_usec: (t.link.t_s * 1e6) as u64,
    }))
}
