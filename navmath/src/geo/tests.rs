#![allow(clippy::unwrap_used)]
use super::*;

fn home() -> LatLonAlt {
    LatLonAlt::default()
}

/// Meridian and prime-vertical radii of curvature (m): the textbook formulas, independent of
/// the ECEF conversions under test.
fn radii(lat_deg: f64) -> (f64, f64) {
    let s = lat_deg.to_radians().sin();
    let d = 1.0 - E2 * s * s;
    (A * (1.0 - E2) / d.powf(1.5), A / d.sqrt())
}

/// The iterated solution of ECEF → geodetic (fixed point on the latitude), as a reference.
fn from_ecef_iterated(x: &Vector3<f64>) -> LatLonAlt {
    let p = x.x.hypot(x.y);
    let mut lat = x.z.atan2(p * (1.0 - E2));
    let mut alt = 0.0;
    for _ in 0..20 {
        let s = lat.sin();
        let n = A / (1.0 - E2 * s * s).sqrt();
        alt = p / lat.cos() - n;
        lat = x.z.atan2(p * (1.0 - E2 * n / (n + alt)));
    }
    LatLonAlt {
        lat_deg: lat.to_degrees(),
        lon_deg: x.y.atan2(x.x).to_degrees(),
        alt_m: alt,
    }
}

#[test]
fn points_round_trip_to_the_micrometre_near_and_far() {
    let frame = LocalFrame::new(home());
    for ned in [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(0.3, -0.2, -5.0),
        Vector3::new(300.0, 200.0, -50.0),
        Vector3::new(800.0, -500.0, -120.0),
        Vector3::new(-3000.0, 2500.0, 30.0),
        Vector3::new(20_000.0, -15_000.0, -2_000.0),
    ] {
        let back = frame.to_ned(&frame.to_geodetic(&ned));
        if ned == Vector3::zeros() {
            assert_eq!(
                frame.to_geodetic(&ned),
                home(),
                "the origin, to the last bit"
            );
        }
        assert!((back - ned).norm() < 1e-6, "{ned:?} -> {back:?}");
        assert_eq!(home().offset_by_ned(&ned), frame.to_geodetic(&ned));
        assert_eq!(home().ned_to(&frame.to_geodetic(&ned)), back);
    }
}

#[test]
fn small_offsets_follow_the_ellipsoids_radii_of_curvature() {
    for lat_deg in [-60.0, 0.0, 30.0, 47.397_742, 75.0] {
        let origin = LatLonAlt {
            lat_deg,
            lon_deg: 8.5,
            alt_m: 488.0,
        };
        let (m, n) = radii(lat_deg);
        let frame = LocalFrame::new(origin);
        let north = frame.to_geodetic(&Vector3::new(100.0, 0.0, 0.0));
        let east = frame.to_geodetic(&Vector3::new(0.0, 100.0, 0.0));
        let dlat = (north.lat_deg - lat_deg).to_radians() * (m + origin.alt_m);
        let dlon = (east.lon_deg - origin.lon_deg).to_radians()
            * (n + origin.alt_m)
            * lat_deg.to_radians().cos();
        assert!((dlat - 100.0).abs() < 1e-4, "{lat_deg}: north {dlat}");
        assert!((dlon - 100.0).abs() < 1e-4, "{lat_deg}: east {dlon}");
    }
}

#[test]
fn the_tangent_plane_rises_above_the_curved_earth_by_d_squared_over_2r() {
    let frame = LocalFrame::new(home());
    let (m, n) = radii(home().lat_deg);
    for d in [100.0, 1_000.0, 5_000.0] {
        for (dir, r) in [
            (Vector3::new(d, 0.0, 0.0), m),
            (Vector3::new(0.0, d, 0.0), n),
        ] {
            let rise = frame.to_geodetic(&dir).alt_m - home().alt_m;
            let expected = d * d / (2.0 * (r + home().alt_m));
            assert!(
                (rise - expected).abs() < 1e-3 * expected.max(1.0),
                "{dir:?}: {rise} m, expected {expected} m"
            );
        }
    }
}

#[test]
fn the_closed_form_matches_the_iterated_solution_from_the_sea_to_20_km() {
    for lat_deg in [-89.9, -45.0, 0.0, 10.0, 47.4, 60.0, 80.0, 89.9] {
        for alt_m in [-400.0, 0.0, 488.0, 3_000.0, 20_000.0] {
            let p = LatLonAlt {
                lat_deg,
                lon_deg: 8.5,
                alt_m,
            };
            let x = to_ecef(&p);
            let (fast, slow) = (from_ecef(&x), from_ecef_iterated(&x));
            let north_m = (fast.lat_deg - slow.lat_deg).to_radians() * A;
            let tol = if alt_m <= 3_000.0 { 1e-6 } else { 1e-5 };
            assert!(north_m.abs() < tol, "{p:?}: {north_m} m");
            assert!((fast.alt_m - slow.alt_m).abs() < 1e-6, "{p:?}");
            assert!((fast.lat_deg - lat_deg).abs() < 1e-9, "{p:?} -> {fast:?}");
        }
    }
}
