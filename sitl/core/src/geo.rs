//! Where the simulated vehicles stand on the Earth. Positions are [`LatLonAlt`], placed around
//! home by the same local frame the autopilot reads them back with ([`navmath::geo`]).

use nalgebra::Vector3;
use navmath::geo::LatLonAlt;

/// How far apart several vehicles on one machine start (m): instance N's home is N times this
/// east of the site's, so a ground station shows them side by side (`sitl -i N`,
/// `autopilot --count`).
pub const INSTANCE_SPACING_M: f64 = 3.0;

/// The home of instance `instance` of several vehicles around `site`: [`INSTANCE_SPACING_M`]
/// times `instance` east of it (instance 0 on the site itself).
pub fn home_for_instance(site: &LatLonAlt, instance: u16) -> LatLonAlt {
    site.offset_by_ned(&Vector3::new(
        0.0,
        INSTANCE_SPACING_M * f64::from(instance),
        0.0,
    ))
}
