//! Geodetic (WGS-84) ↔ local NED, through Earth-centred Earth-fixed coordinates.
//!
//! Exact at any distance (the simulator uses a tangent-plane approximation; a test checks that
//! the two agree where both apply).

use nalgebra::{Matrix3, Vector3};

const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;
const E2: f64 = F * (2.0 - F);

/// A WGS-84 position: latitude, longitude (deg), altitude above mean sea level (m; the
/// ellipsoid height is used as AMSL, as GPS receivers on small vehicles effectively do).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatLonAlt {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude (m).
    pub alt_m: f64,
}

fn to_ecef(p: &LatLonAlt) -> Vector3<f64> {
    let (sl, cl) = p.lat_deg.to_radians().sin_cos();
    let (so, co) = p.lon_deg.to_radians().sin_cos();
    let n = A / (1.0 - E2 * sl * sl).sqrt();
    Vector3::new(
        (n + p.alt_m) * cl * co,
        (n + p.alt_m) * cl * so,
        (n * (1.0 - E2) + p.alt_m) * sl,
    )
}

fn from_ecef(x: &Vector3<f64>) -> LatLonAlt {
    let lon = x.y.atan2(x.x);
    let p = x.x.hypot(x.y);
    // Bowring's initial guess, then a few fixed-point iterations (sub-millimetre).
    let mut lat = x.z.atan2(p * (1.0 - E2));
    let mut alt = 0.0;
    for _ in 0..5 {
        let s = lat.sin();
        let n = A / (1.0 - E2 * s * s).sqrt();
        alt = p / lat.cos() - n;
        lat = x.z.atan2(p * (1.0 - E2 * n / (n + alt)));
    }
    LatLonAlt {
        lat_deg: lat.to_degrees(),
        lon_deg: lon.to_degrees(),
        alt_m: alt,
    }
}

/// ECEF → NED rotation at a reference point.
fn ned_rotation(origin: &LatLonAlt) -> Matrix3<f64> {
    let (sl, cl) = origin.lat_deg.to_radians().sin_cos();
    let (so, co) = origin.lon_deg.to_radians().sin_cos();
    Matrix3::new(
        -sl * co,
        -sl * so,
        cl, //
        -so,
        co,
        0.0, //
        -cl * co,
        -cl * so,
        -sl,
    )
}

/// A local NED frame anchored at an origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin: LatLonAlt,
    origin_ecef: Vector3<f64>,
    rotation: Matrix3<f64>,
}

impl LocalFrame {
    /// The frame whose NED origin is `origin`.
    pub fn new(origin: LatLonAlt) -> Self {
        Self {
            origin,
            origin_ecef: to_ecef(&origin),
            rotation: ned_rotation(&origin),
        }
    }

    /// Its origin.
    pub fn origin(&self) -> LatLonAlt {
        self.origin
    }

    /// NED position (m) of a geodetic point.
    pub fn to_ned(&self, p: &LatLonAlt) -> Vector3<f64> {
        self.rotation * (to_ecef(p) - self.origin_ecef)
    }

    /// Geodetic position of a NED point.
    pub fn to_geodetic(&self, ned: &Vector3<f64>) -> LatLonAlt {
        from_ecef(&(self.origin_ecef + self.rotation.transpose() * ned))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_agrees_with_the_simulators_tangent_plane() {
        let home = LatLonAlt {
            lat_deg: 47.397742,
            lon_deg: 8.545594,
            alt_m: 488.0,
        };
        let frame = LocalFrame::new(home);
        let sim_home = sitl_core::geo::Geodetic {
            lat_deg: home.lat_deg,
            lon_deg: home.lon_deg,
            alt_m: home.alt_m,
        };
        // Within a kilometre (SITL flights): the simulator's curvilinear plane and this exact
        // tangent plane differ by e² tan(lat) / 2R and the like: centimetres. (At 4 km east the
        // straight tangent line has drifted 0.5 m off the parallel.)
        for ned in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(300.0, 200.0, -50.0),
            Vector3::new(800.0, -500.0, -120.0),
        ] {
            let p = frame.to_geodetic(&ned);
            assert!((frame.to_ned(&p) - ned).norm() < 1e-6, "round trip");
            let far = Vector3::new(-3000.0, 2500.0, 30.0);
            assert!(
                (frame.to_ned(&frame.to_geodetic(&far)) - far).norm() < 1e-6,
                "round trip far"
            );
            // The simulator's tangent-plane conversion of the same point, read back by ours.
            let s = sim_home.offset_by_ned(&ned);
            let back = frame.to_ned(&LatLonAlt {
                lat_deg: s.lat_deg,
                lon_deg: s.lon_deg,
                alt_m: s.alt_m,
            });
            // Over a few km the tangent plane departs from the ellipsoid by d²/2R vertically.
            let d = ned.xy().norm();
            // The simulator's plane is within centimetres per kilometre of the exact ellipsoid.
            assert!(
                (back.xy() - ned.xy()).norm() < 0.005 + 5e-5 * d,
                "{ned:?} -> {back:?}"
            );
            assert!(
                (back.z - ned.z - d * d / (2.0 * 6.371e6)).abs() < 0.05,
                "{ned:?} -> {back:?}"
            );
        }
    }
}
