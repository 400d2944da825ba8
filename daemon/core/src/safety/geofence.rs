//! The uploaded geofence (`MAV_MISSION_TYPE_FENCE`): inclusion and exclusion polygons and
//! circles, as the MAVLink mission protocol carries them and PX4 reads them — the vehicle must be
//! inside at least one inclusion zone (when there are any) and inside no exclusion zone.
//!
//! Zones arrive in latitude/longitude; the vehicle checks them in its local NED frame once the
//! estimator has an origin. (The cylinder about home, `GF_MAX_HOR_DIST`/`GF_MAX_VER_DIST`, is
//! the commander's.)

use crate::math::geo::{LatLonAlt, LocalFrame};
use nalgebra::Vector2;

/// One zone of an uploaded fence, in geodetic coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum GeoZone {
    /// A polygon (`MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`/`_EXCLUSION`): its vertices in
    /// order, (latitude, longitude) in degrees.
    Polygon {
        /// The vehicle must stay inside (true) or outside (false).
        inclusion: bool,
        /// Vertices (deg), at least three.
        vertices_deg: Vec<(f64, f64)>,
    },
    /// A circle (`MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION`/`_EXCLUSION`).
    Circle {
        /// The vehicle must stay inside (true) or outside (false).
        inclusion: bool,
        /// Centre (latitude, longitude, deg).
        center_deg: (f64, f64),
        /// Radius (m).
        radius_m: f64,
    },
}

/// One zone in the local frame (north, east in m).
#[derive(Debug, Clone, PartialEq)]
enum Zone {
    Polygon {
        inclusion: bool,
        vertices: Vec<Vector2<f64>>,
    },
    Circle {
        inclusion: bool,
        center: Vector2<f64>,
        radius_m: f64,
    },
}

impl Zone {
    fn inclusion(&self) -> bool {
        match self {
            Self::Polygon { inclusion, .. } | Self::Circle { inclusion, .. } => *inclusion,
        }
    }

    fn contains(&self, p: &Vector2<f64>) -> bool {
        match self {
            Self::Polygon { vertices, .. } => inside_polygon(vertices, p),
            Self::Circle {
                center, radius_m, ..
            } => (p - center).norm() <= *radius_m,
        }
    }
}

/// Even-odd ray casting: whether `p` is inside the polygon `v` (any orientation, not
/// necessarily convex).
fn inside_polygon(v: &[Vector2<f64>], p: &Vector2<f64>) -> bool {
    let mut inside = false;
    let mut j = v.len().wrapping_sub(1);
    for i in 0..v.len() {
        let (a, b) = (v[i], v[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// The fence in the local frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Geofence {
    zones: Vec<Zone>,
}

impl Geofence {
    /// The zones placed in `frame` (the estimator's origin).
    pub fn new(zones: &[GeoZone], frame: &LocalFrame) -> Self {
        let at = |(lat, lon): (f64, f64)| {
            frame
                .to_ned(&LatLonAlt {
                    lat_deg: lat,
                    lon_deg: lon,
                    alt_m: frame.origin().alt_m,
                })
                .xy()
        };
        Self {
            zones: zones
                .iter()
                .map(|z| match z {
                    GeoZone::Polygon {
                        inclusion,
                        vertices_deg,
                    } => Zone::Polygon {
                        inclusion: *inclusion,
                        vertices: vertices_deg.iter().map(|v| at(*v)).collect(),
                    },
                    GeoZone::Circle {
                        inclusion,
                        center_deg,
                        radius_m,
                    } => Zone::Circle {
                        inclusion: *inclusion,
                        center: at(*center_deg),
                        radius_m: *radius_m,
                    },
                })
                .collect(),
        }
    }

    /// No zones.
    pub fn is_empty(&self) -> bool {
        self.zones.is_empty()
    }

    /// Whether the horizontal position `north_east_m` is allowed: inside at least one
    /// inclusion zone, if there is any, and in no exclusion zone.
    pub fn allows(&self, north_east_m: &Vector2<f64>) -> bool {
        let mut inclusions = self.zones.iter().filter(|z| z.inclusion()).peekable();
        let included = inclusions.peek().is_none() || inclusions.any(|z| z.contains(north_east_m));
        included
            && !self
                .zones
                .iter()
                .any(|z| !z.inclusion() && z.contains(north_east_m))
    }
}

/// How far back inside (m) the vehicle must be for a breach to end: without it, a vehicle
/// stopped on the fence line would flicker in and out and re-trigger its failsafe.
pub const CLEAR_MARGIN_M: f64 = 1.0;

/// The breach check with PX4's prediction (`GF_PREDICT`) and a hysteresis.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FenceMonitor {
    /// The fence.
    pub fence: Geofence,
    breached: bool,
}

impl FenceMonitor {
    /// Watching `fence`, nothing breached.
    pub fn new(fence: Geofence) -> Self {
        Self {
            fence,
            breached: false,
        }
    }

    /// Whether the vehicle at `pos` (north, east, m) moving at `vel` (m/s) is in breach: outside
    /// the fence, or (`in_air`) about to be — where it would stop braking at `brake_m_s2` is
    /// outside. A breach lasts until the vehicle is [`CLEAR_MARGIN_M`] back inside.
    pub fn update(
        &mut self,
        pos: &Vector2<f64>,
        vel: &Vector2<f64>,
        in_air: bool,
        brake_m_s2: f64,
    ) -> bool {
        let f = &self.fence;
        let stop = pos + vel * vel.norm() / (2.0 * brake_m_s2.max(0.1));
        let outside = !f.allows(pos) || (in_air && !f.allows(&stop));
        let m = CLEAR_MARGIN_M;
        let well_inside = [(m, 0.0), (-m, 0.0), (0.0, m), (0.0, -m)]
            .iter()
            .all(|&(n, e)| f.allows(&(pos + Vector2::new(n, e))));
        self.breached = outside || (self.breached && !well_inside);
        self.breached
    }
}

#[cfg(test)]
mod tests;
