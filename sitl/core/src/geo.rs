//! Geodetic positions and the local NED frame around home.

use nalgebra::Vector3;
use serde::Deserialize;

const WGS84_A: f64 = 6_378_137.0;
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// Latitude, longitude (deg, WGS-84) and altitude (m AMSL).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geodetic {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude above mean sea level (m).
    pub alt_m: f64,
}

impl Default for Geodetic {
    /// PX4's default SITL home (Zurich), so ground-station users see a familiar place.
    fn default() -> Self {
        Self {
            lat_deg: 47.397_742,
            lon_deg: 8.545_594,
            alt_m: 488.0,
        }
    }
}

/// How far apart several vehicles on one machine start (m): instance N's home is N times this
/// east of the site's, so a ground station shows them side by side (`sitl -i N`,
/// `autopilot --count`).
pub const INSTANCE_SPACING_M: f64 = 3.0;

impl Geodetic {
    /// The home of instance `instance` of several vehicles around this site: [`INSTANCE_SPACING_M`]
    /// times `instance` east of it.
    pub fn for_instance(&self, instance: u16) -> Geodetic {
        self.offset_by_ned(&Vector3::new(
            0.0,
            INSTANCE_SPACING_M * f64::from(instance),
            0.0,
        ))
    }

    /// Meridian and prime-vertical radii of curvature at this latitude (m).
    fn radii(&self) -> (f64, f64) {
        let s = self.lat_deg.to_radians().sin();
        let d = 1.0 - WGS84_E2 * s * s;
        (WGS84_A * (1.0 - WGS84_E2) / d.powf(1.5), WGS84_A / d.sqrt())
    }

    /// The point `ned` metres away in the local tangent frame at `self`: meridian and
    /// prime-vertical radii at the origin, the east offset scaled by the cosine of the mean
    /// latitude (a second-order term the plain tangent plane gets wrong by 1e-4 of the
    /// distance). Within a kilometre it agrees with the autopilot's exact tangent-plane frame to
    /// centimetres; farther out the two differ at second order (e² tan(lat)/2R: 0.5 m at 4 km
    /// east), and vertically by the Earth's curvature d²/2R.
    pub fn offset_by_ned(&self, ned: &Vector3<f64>) -> Geodetic {
        let (rm, rn) = self.radii();
        let h = self.alt_m;
        let lat_deg = self.lat_deg + (ned.x / (rm + h)).to_degrees();
        let mean_lat = (0.5 * (self.lat_deg + lat_deg)).to_radians();
        Geodetic {
            lat_deg,
            lon_deg: self.lon_deg + (ned.y / ((rn + h) * mean_lat.cos())).to_degrees(),
            alt_m: self.alt_m - ned.z,
        }
    }

    /// The NED offset of `other` from `self`: the inverse of [`Geodetic::offset_by_ned`].
    pub fn ned_to(&self, other: &Geodetic) -> Vector3<f64> {
        let (rm, rn) = self.radii();
        let h = self.alt_m;
        let mean_lat = (0.5 * (self.lat_deg + other.lat_deg)).to_radians();
        Vector3::new(
            (other.lat_deg - self.lat_deg).to_radians() * (rm + h),
            (other.lon_deg - self.lon_deg).to_radians() * (rn + h) * mean_lat.cos(),
            self.alt_m - other.alt_m,
        )
    }
}
