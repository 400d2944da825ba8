use super::*;

const HOME: LatLonAlt = LatLonAlt {
    lat_deg: 47.397742,
    lon_deg: 8.545594,
    alt_m: 488.0,
};

fn frame() -> LocalFrame {
    LocalFrame::new(HOME)
}

/// The latitude/longitude `north`, `east` m from home.
fn ll(north: f64, east: f64) -> (f64, f64) {
    let g = frame().to_geodetic(&nalgebra::Vector3::new(north, east, 0.0));
    (g.lat_deg, g.lon_deg)
}

fn p(north: f64, east: f64) -> Vector2<f64> {
    Vector2::new(north, east)
}

fn polygon(inclusion: bool, ne: &[(f64, f64)]) -> GeoZone {
    GeoZone::Polygon {
        inclusion,
        vertices_deg: ne.iter().map(|&(n, e)| ll(n, e)).collect(),
    }
}

#[test]
fn no_zones_allow_everything() {
    let f = Geofence::new(&[], &frame());
    assert!(f.is_empty() && f.allows(&p(1e4, -1e4)));
}

#[test]
fn an_inclusion_polygon_of_either_orientation_and_a_concave_one() {
    let square = [(-10.0, -10.0), (-10.0, 10.0), (10.0, 10.0), (10.0, -10.0)];
    for vertices in [square.to_vec(), square.iter().rev().copied().collect()] {
        let f = Geofence::new(&[polygon(true, &vertices)], &frame());
        assert!(f.allows(&p(0.0, 0.0)) && f.allows(&p(9.9, -9.9)));
        assert!(!f.allows(&p(10.1, 0.0)) && !f.allows(&p(0.0, -10.1)));
    }
    // An L: the notch at north > 0, east > 0 is outside.
    let l = [
        (-10.0, -10.0),
        (10.0, -10.0),
        (10.0, 0.0),
        (0.0, 0.0),
        (0.0, 10.0),
        (-10.0, 10.0),
    ];
    let f = Geofence::new(&[polygon(true, &l)], &frame());
    assert!(f.allows(&p(5.0, -5.0)) && f.allows(&p(-5.0, 5.0)));
    assert!(!f.allows(&p(5.0, 5.0)), "the notch");
}

#[test]
fn exclusions_cut_holes_and_inclusions_add_up() {
    let zones = [
        GeoZone::Circle {
            inclusion: true,
            center_deg: ll(0.0, 0.0),
            radius_m: 50.0,
        },
        GeoZone::Circle {
            inclusion: true,
            center_deg: ll(200.0, 0.0),
            radius_m: 100.0,
        },
        polygon(
            false,
            &[(10.0, 10.0), (10.0, 20.0), (20.0, 20.0), (20.0, 10.0)],
        ),
        GeoZone::Circle {
            inclusion: false,
            center_deg: ll(200.0, 0.0),
            radius_m: 10.0,
        },
    ];
    let f = Geofence::new(&zones, &frame());
    // In the first circle, in the second (the circles are placed through the geodetic frame:
    // within a few centimetres of their local distances), between them (not).
    assert!(f.allows(&p(49.9, 0.0)) && f.allows(&p(0.0, -49.9)));
    assert!(f.allows(&p(101.0, 0.0)) && f.allows(&p(299.9, 0.0)));
    assert!(!f.allows(&p(75.0, 0.0)) && !f.allows(&p(300.2, 0.0)));
    // The holes.
    assert!(!f.allows(&p(15.0, 15.0)) && f.allows(&p(15.0, 25.0)));
    assert!(!f.allows(&p(205.0, 0.0)) && f.allows(&p(211.0, 0.0)));
}

#[test]
fn only_exclusions_allow_everything_else() {
    let f = Geofence::new(
        &[GeoZone::Circle {
            inclusion: false,
            center_deg: ll(30.0, 0.0),
            radius_m: 5.0,
        }],
        &frame(),
    );
    assert!(f.allows(&p(0.0, 0.0)) && f.allows(&p(1e3, 1e3)));
    assert!(!f.allows(&p(30.0, 4.0)));
}

#[test]
fn a_breach_is_predicted_from_the_stopping_distance_and_ends_a_metre_back_inside() {
    let square = [(-12.0, -12.0), (-12.0, 12.0), (12.0, 12.0), (12.0, -12.0)];
    let mut m = FenceMonitor::new(Geofence::new(&[polygon(true, &square)], &frame()));
    let north = |v: f64| Vector2::new(v, 0.0);
    // At 5 m/s, braking at 2.5 m/s² takes 5 m: at 6 m it is fine, at 7.5 m no longer.
    assert!(!m.update(&p(6.0, 0.0), &north(5.0), true, 2.5));
    assert!(m.update(&p(7.5, 0.0), &north(5.0), true, 2.5));
    // On the ground, only where it is counts.
    let mut ground = FenceMonitor::new(m.fence.clone());
    assert!(!ground.update(&p(7.5, 0.0), &north(5.0), false, 2.5));
    // Stopped on the line: the breach holds while it wavers across it...
    for x in [12.2, 11.8, 12.1, 11.5] {
        assert!(m.update(&p(x, 0.0), &north(0.0), true, 2.5), "{x}");
    }
    // ... and ends a metre inside.
    assert!(!m.update(&p(10.9, 0.0), &north(-0.5), true, 2.5));
    assert!(!m.update(&p(11.5, 0.0), &north(0.0), true, 2.5));
}
