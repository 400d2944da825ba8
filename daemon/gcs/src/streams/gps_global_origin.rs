//! `GPS_GLOBAL_ORIGIN`: where the local frame's origin is.

use super::prelude::*;

/// `GPS_GLOBAL_ORIGIN` once the estimator has an origin.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let o = s.frame?.origin();
    Some(MavMessage::GPS_GLOBAL_ORIGIN(GPS_GLOBAL_ORIGIN_DATA {
        latitude: e7(o.lat_deg),
        longitude: e7(o.lon_deg),
        altitude: (o.alt_m * 1e3).round() as i32,
        time_usec: s.usec,
    }))
}
