//! `WIND_COV`: the wind the outside force on the vehicle means (`control::disturbance`), as PX4
//! sends its estimator's wind.

use super::prelude::*;

/// `WIND_COV` once the vehicle has flown and learned the wind (none before).
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let w = s.out?.wind?;
    let tr = s.tr?;
    let alt = s
        .frame
        .map_or(-tr.pos_ned_m.z, |f| f.to_geodetic(&tr.pos_ned_m).alt_m);
    Some(MavMessage::WIND_COV(WIND_COV_DATA {
        time_usec: s.usec,
        wind_x: w.wind_ned_m_s.x as f32,
        wind_y: w.wind_ned_m_s.y as f32,
        wind_z: w.wind_ned_m_s.z as f32,
        var_horiz: w.var_horiz_m2_s2 as f32,
        // Not estimated: MAVLink's "unknown".
        var_vert: f32::NAN,
        wind_alt: alt as f32,
        horiz_accuracy: w.var_horiz_m2_s2.sqrt() as f32,
        vert_accuracy: 0.0,
    }))
}
