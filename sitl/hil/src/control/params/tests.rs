use super::*;

fn wind_of(actions: &[SimAction]) -> (Vector3<f64>, f64) {
    match actions {
        [
            SimAction::Wind {
                mean_ned_m_s,
                turbulence_w20_m_s,
            },
        ] => (*mean_ned_m_s, *turbulence_w20_m_s),
        other => panic!("{other:?}"),
    }
}

#[test]
fn wind_parameters_read_the_scenario_and_set_where_the_wind_comes_from() {
    let w = Weather::new(
        &WindConfig {
            mean_ned_m_s: [0.0, -5.0, 0.5],
            turbulence_w20_m_s: 7.7,
            roughness_m: None,
        },
        true,
    );
    // Air moving west comes from the east.
    assert!((w.get("SIM_WIND_SPD").unwrap() - 5.0).abs() < 1e-12);
    assert!((w.get("SIM_WIND_DIR").unwrap() - 90.0).abs() < 1e-9);
    assert_eq!(w.get("SIM_WIND_TURB"), Some(7.7));
    let mut w = w;
    let (mean, turb) = wind_of(&w.set("SIM_WIND_DIR", 180.0, 3.0).unwrap());
    assert!((mean - Vector3::new(5.0, 0.0, 0.5)).norm() < 1e-9, "{mean}");
    assert_eq!(turb, 7.7);
    let (mean, _) = wind_of(&w.set("SIM_WIND_SPD", 10.0, 3.0).unwrap());
    assert!(
        (mean - Vector3::new(10.0, 0.0, 0.5)).norm() < 1e-9,
        "{mean}"
    );
    let (_, turb) = wind_of(&w.set("SIM_WIND_TURB", 0.0, 3.0).unwrap());
    assert_eq!(turb, 0.0);
}

#[test]
fn bad_values_keep_the_old_one() {
    let mut w = Weather::new(&WindConfig::default(), true);
    for (name, v) in [
        ("SIM_WIND_SPD", -1.0),
        ("SIM_WIND_SPD", f64::NAN),
        ("SIM_WIND_DIR", 361.0),
        ("SIM_GUST_T", 0.0),
    ] {
        let e = w.set(name, v, 0.0).unwrap_err();
        assert!(e.starts_with(name) && e.contains("must be within"), "{e}");
    }
    assert!(w.set("SIM_NOPE", 1.0, 0.0).is_err());
    assert_eq!(w, Weather::new(&WindConfig::default(), true));
}

#[test]
fn a_gust_starts_when_set_and_repeats_with_a_period() {
    let mut w = Weather::new(&WindConfig::default(), true);
    w.set("SIM_GUST_DIR", 270.0, 0.0).unwrap();
    w.set("SIM_GUST_T", 3.0, 0.0).unwrap();
    let a = w.set("SIM_GUST_SPD", 6.0, 10.0).unwrap();
    match a.as_slice() {
        [
            SimAction::Gust {
                peak_ned_m_s,
                duration_s,
            },
        ] => {
            // From the west: toward the east.
            assert!((peak_ned_m_s - Vector3::new(0.0, 6.0, 0.0)).norm() < 1e-9);
            assert_eq!(*duration_s, 3.0);
        }
        other => panic!("{other:?}"),
    }
    // Once only without a period.
    assert!(w.due(100.0).is_empty());
    w.set("SIM_GUST_PER", 20.0, 100.0).unwrap();
    assert_eq!(w.due(100.0).len(), 1);
    assert!(w.due(119.9).is_empty());
    assert_eq!(w.due(120.0).len(), 1);
    assert_eq!(w.due(140.0).len(), 1);
    w.set("SIM_GUST_SPD", 0.0, 141.0).unwrap();
    assert!(w.due(1000.0).is_empty());
}

#[test]
fn a_paused_clock_holds_and_runs_a_stretch_unpaced() {
    let mut p = Pace::new(Some(3.0), false);
    assert!(!p.holds(1.0));
    assert_eq!(p.speedup_at(1.0), Some(3.0));
    // SIM_RUN_S only means something while paused.
    assert!(p.set("SIM_RUN_S", 2.0, 1.0).is_err());
    p.set("SIM_PAUSE", 1.0, 1.0).unwrap();
    assert!(p.holds(1.0));
    p.set("SIM_RUN_S", 2.0, 1.0).unwrap();
    assert!(!p.holds(1.0) && !p.holds(2.99));
    assert_eq!(p.speedup_at(2.0), None, "a stretch runs unpaced");
    assert_eq!(p.get("SIM_RUN_S", 2.5), Some(0.5));
    assert!(p.holds(3.0));
    assert_eq!(p.get("SIM_RUN_S", 3.0), Some(0.0));
    // Resuming forgets the stretch and runs at the pace again.
    p.set("SIM_PAUSE", 0.0, 3.0).unwrap();
    assert!(!p.holds(3.0));
    assert_eq!(p.speedup_at(3.0), Some(3.0));
    p.set("SIM_SPEEDUP", 0.0, 3.0).unwrap();
    assert_eq!(
        (p.speedup_at(3.0), p.get("SIM_SPEEDUP", 3.0)),
        (None, Some(0.0))
    );
    for (name, v) in [
        ("SIM_SPEEDUP", -1.0),
        ("SIM_PAUSE", 2.0),
        ("SIM_RUN_S", f64::NAN),
    ] {
        assert!(p.set(name, v, 3.0).unwrap_err().contains("must be within"));
    }
    assert!(
        p.set("SIM_WIND_SPD", 1.0, 3.0).is_err(),
        "not a clock parameter"
    );
}
