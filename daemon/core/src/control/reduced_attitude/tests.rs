//! What the reduced-attitude controller refuses, and how bad inputs are met (its flights are
//! `tests/three_rotors.rs`).
#![allow(clippy::unwrap_used)]
use super::*;
use crate::control::relaxed_hover;

fn airframe(name: &str) -> Airframe {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    Airframe::load(&dir.join(format!("{name}.toml"))).unwrap()
}

#[test]
fn what_it_cannot_fly_is_refused_and_bad_inputs_hold_the_hover() {
    let a = airframe("quad_x");
    let hover = relaxed_hover::solve(&a, 0, 1.0, 1.225).unwrap();
    for rate in [0.0, -5.0, f64::NAN] {
        assert!(matches!(
            ReducedAttitude::new(&a, hover.clone(), rate),
            Err(ReducedAttitudeError::Rate(_))
        ));
    }
    let hexa = airframe("hexa_x");
    assert!(matches!(
        ReducedAttitude::new(&hexa, hover.clone(), 500.0),
        Err(ReducedAttitudeError::NotThisAirframe)
    ));
    let mut thinner = hover.clone();
    thinner.air_density = 1.0;
    assert!(matches!(
        ReducedAttitude::new(&a, thinner, 500.0),
        Err(ReducedAttitudeError::NotAnEquilibrium(_))
    ));
    let control = ReducedAttitude::new(&a, hover.clone(), 500.0).unwrap();
    let q = UnitQuaternion::identity();
    for (up, lift, rate) in [
        (Vector3::zeros(), 10.0, Vector3::zeros()),
        (Vector3::new(f64::NAN, 0.0, -1.0), 10.0, Vector3::zeros()),
        (-Vector3::z(), f64::NAN, Vector3::zeros()),
        (-Vector3::z(), 10.0, Vector3::new(0.0, f64::INFINITY, 0.0)),
    ] {
        assert_eq!(
            control.update(&up, lift, &q, &rate)[..4],
            hover.thrust_n[..]
        );
    }
    // Asked the opposite way (the axis upside down from the asked direction): a full turn is
    // still asked, every thrust within the rotor's range.
    let flipped = UnitQuaternion::rotation_between(&hover.axis_frd, &Vector3::z()).unwrap();
    let rate = hover.axis_frd * hover.spin_rad_s;
    let f = control.update(&-Vector3::z(), a.weight_n(), &flipped, &rate);
    assert_ne!(f[..4], hover.thrust_n[..]);
    assert!(f.iter().all(|t| t.is_finite() && *t >= 0.0));
}
