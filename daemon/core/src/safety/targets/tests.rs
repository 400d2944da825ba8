use super::*;

fn origin() -> LatLonAlt {
    LatLonAlt {
        lat_deg: 47.397742,
        lon_deg: 8.545594,
        alt_m: 488.0,
    }
}

fn limits() -> TargetLimits {
    TargetLimits::new(&SafetyParams::default())
}

#[test]
fn the_lowest_ceiling_and_range_set_are_the_limits() {
    let l = limits();
    assert_eq!(l.ceiling, (500.0, "LNDMC_ALT_MAX"));
    assert_eq!(l.range, (PLAUSIBLE_RANGE_M, "the plausible range"));
    let p = SafetyParams {
        max_altitude_m: -1.0,
        fence_max_vertical_m: 80.0,
        fence_max_horizontal_m: 300.0,
        ..SafetyParams::default()
    };
    let l = TargetLimits::new(&p);
    assert_eq!(l.ceiling, (80.0, "GF_MAX_VER_DIST"));
    assert_eq!(l.range, (300.0, "GF_MAX_HOR_DIST"));
    let none = SafetyParams {
        max_altitude_m: -1.0,
        ..SafetyParams::default()
    };
    assert_eq!(
        TargetLimits::new(&none).ceiling,
        (HARD_CEILING_M, "the hard ceiling")
    );
}

#[test]
fn heights_below_the_ground_above_the_ceiling_or_not_finite_are_refused() {
    let l = limits();
    for ok in [GROUND_CLEARANCE_M, 10.0, 500.0] {
        assert_eq!(l.check_height(ok), Ok(()), "{ok}");
    }
    for bad in [f64::NAN, f64::INFINITY, 1e30, 500.1, 0.5, 0.0, -50.0, -1e6] {
        let e = l.check_height(bad).unwrap_err();
        assert_eq!(e.mission_param(), 7, "{bad}: {e}");
    }
    assert_eq!(
        l.check_height(1e30).unwrap_err().to_string(),
        "1.0e30 m above home, above the 500 m ceiling (LNDMC_ALT_MAX)"
    );
    assert_eq!(
        l.check_height(-50.0).unwrap_err().to_string(),
        "-50.0 m above home, below the 1 m ground clearance"
    );
}

#[test]
fn places_off_the_earth_or_far_from_home_are_refused() {
    assert_eq!(check_lat_lon(47.0, 8.0), Ok(()));
    assert_eq!(check_lat_lon(-90.0, 180.0), Ok(()));
    assert_eq!(
        check_lat_lon(1000.0, 8.0),
        Err(TargetError::Latitude(1000.0))
    );
    assert_eq!(
        check_lat_lon(0.0, -5000.0),
        Err(TargetError::Longitude(-5000.0))
    );
    assert!(check_lat_lon(f64::NAN, 0.0).is_err());
    let home = Vector3::new(10.0, 0.0, -1.0);
    let l = limits();
    assert_eq!(
        l.check_target(&Vector3::new(40_000.0, 0.0, -21.0), &home),
        Ok(())
    );
    let far = l
        .check_target(&Vector3::new(60_000.0, 0.0, -21.0), &home)
        .unwrap_err();
    assert_eq!(far.mission_param(), 5);
    assert!(
        l.check_target(&Vector3::new(f64::INFINITY, 0.0, -21.0), &home)
            .is_err()
    );
    // Parts left open (NaN) are where the vehicle is: not checked.
    assert_eq!(l.check_target(&Vector3::repeat(f64::NAN), &home), Ok(()));
    assert!(
        l.check_target(&Vector3::new(f64::NAN, f64::NAN, 49.0), &home)
            .is_err()
    );
}

#[test]
fn a_new_home_is_near_the_vehicle_and_near_the_height_of_the_current_one() {
    let l = limits();
    let (here, home) = (Vector3::new(0.0, 0.0, -30.0), Vector3::zeros());
    assert_eq!(
        l.check_home(&Vector3::new(100.0, 0.0, -20.0), &here, &home),
        Ok(())
    );
    // 488 m underground (home at sea level) and far up: every target would move with it.
    for z in [488.0, -2.0e9, -101.0] {
        let e = l
            .check_home(&Vector3::new(0.0, 0.0, z), &here, &home)
            .unwrap_err();
        assert!(matches!(e, TargetError::HomeShift { .. }), "{z}: {e}");
    }
    assert_eq!(
        l.check_home(&Vector3::new(0.0, 0.0, 488.0), &here, &home)
            .unwrap_err()
            .to_string(),
        "new home -488.0 m above the current one: more than 100 m up or down"
    );
    assert!(
        l.check_home(&Vector3::new(1e7, 0.0, 0.0), &here, &home)
            .is_err()
    );
    assert!(
        l.check_home(&Vector3::repeat(f64::NAN), &here, &home)
            .is_err()
    );
    // Within GF_MAX_HOR_DIST of the vehicle when it is set.
    let fenced = TargetLimits::new(&SafetyParams {
        fence_max_horizontal_m: 300.0,
        ..SafetyParams::default()
    });
    let far = fenced
        .check_home(&Vector3::new(400.0, 0.0, 0.0), &here, &home)
        .unwrap_err();
    assert!(
        matches!(
            far,
            TargetError::TooFar {
                by: "GF_MAX_HOR_DIST",
                ..
            }
        ),
        "{far}"
    );
}

#[test]
fn mission_items_are_checked_where_they_go_and_a_landing_altitude_is_not() {
    let o = origin();
    let home = Vector3::zeros();
    let l = limits();
    let frame = LocalFrame::new(o);
    let near = frame.to_geodetic(&Vector3::new(100.0, 50.0, 0.0));
    let at = |alt| MissionPoint {
        lat_lon_deg: Some((near.lat_deg, near.lon_deg)),
        alt: Some(alt),
    };
    let wp = |alt| MissionItem::Waypoint {
        at: at(alt),
        hold_s: 0.0,
        acceptance_m: None,
        yaw_rad: None,
    };
    let good = [
        MissionItem::Takeoff {
            at: at(MissionAltitude::AboveHome(10.0)),
            yaw_rad: None,
        },
        wp(MissionAltitude::Amsl(o.alt_m + 30.0)),
        MissionItem::Land {
            at: at(MissionAltitude::AboveHome(-1e6)),
            yaw_rad: None,
        },
    ];
    assert_eq!(check_mission(&good, &l, &o, &home), Ok(()));
    let mut bad = good.to_vec();
    bad.insert(1, wp(MissionAltitude::AboveHome(1e30)));
    let (k, e) = check_mission(&bad, &l, &o, &home).unwrap_err();
    assert_eq!((k, e.mission_param()), (1, 7));
    bad[1] = wp(MissionAltitude::Amsl(o.alt_m - 1e6));
    assert_eq!(check_mission(&bad, &l, &o, &home).unwrap_err().0, 1);
    bad[1] = MissionItem::LoiterUnlimited {
        at: MissionPoint {
            lat_lon_deg: Some((1000.0, 8.0)),
            alt: None,
        },
    };
    assert_eq!(
        check_mission(&bad, &l, &o, &home),
        Err((1, TargetError::Latitude(1000.0)))
    );
    bad[1] = MissionItem::SetHome {
        at: Some(MissionPoint {
            lat_lon_deg: Some((-80.0, 40.0)),
            alt: Some(MissionAltitude::Amsl(o.alt_m)),
        }),
    };
    assert_eq!(
        check_mission(&bad, &l, &o, &home)
            .unwrap_err()
            .1
            .mission_param(),
        5
    );
    // A DO_SET_HOME item moves the home later items are measured from: with home 90 m up (a
    // hill), a waypoint 50 m above the first home is 40 m below the new one.
    let up = frame.to_geodetic(&Vector3::new(0.0, 0.0, -90.0));
    let moved = [
        MissionItem::SetHome {
            at: Some(MissionPoint {
                lat_lon_deg: Some((up.lat_deg, up.lon_deg)),
                alt: Some(MissionAltitude::Amsl(up.alt_m)),
            }),
        },
        wp(MissionAltitude::Amsl(o.alt_m + 50.0)),
    ];
    assert_eq!(check_mission(&moved[1..], &l, &o, &home), Ok(()));
    assert_eq!(check_mission(&moved, &l, &o, &home).unwrap_err().0, 1);
    // Without home: the height above home is checked, an altitude above sea level waits.
    let high = wp(MissionAltitude::AboveHome(1e30));
    assert_eq!(l.check_item(&high, None).unwrap_err().mission_param(), 7);
    assert_eq!(l.check_item(&wp(MissionAltitude::Amsl(1e30)), None), Ok(()));
}

#[test]
fn a_global_position_reaches_the_local_frame_only_on_the_earth() {
    let o = origin();
    let p = LatLonAlt {
        alt_m: o.alt_m + 10.0,
        ..o
    };
    let ned = global_to_ned(&p, &o).unwrap();
    assert!((ned - Vector3::new(0.0, 0.0, -10.0)).norm() < 1e-6);
    let off = LatLonAlt {
        lat_deg: 1000.0,
        ..o
    };
    assert_eq!(global_to_ned(&off, &o), Err(TargetError::Latitude(1000.0)));
    let high = LatLonAlt {
        alt_m: f64::INFINITY,
        ..o
    };
    assert!(global_to_ned(&high, &o).is_err());
}
