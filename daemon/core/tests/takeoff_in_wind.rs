//! A take-off into a 10 m/s wind, the whole autopilot in lockstep with the simulator on its
//! `typical` sensors: the spool-up at idle keeps the vehicle on its feet where it stands (near
//! the hover thrust the wind slid it 1.7 m before the climb began, and the climb then came back
//! at 34° of tilt), and the climb leans into the wind without overshooting the tilt it hovers at.
#![allow(clippy::unwrap_used, missing_docs)]

use airframe::MAX_ROTORS;
use nalgebra::Vector3;
use sitl_core::environment::WindConfig;
use sitl_core::sim::SimConfig;

mod common;
use common::airframe;

/// What one take-off came to.
#[derive(Debug, Default)]
struct Takeoff {
    /// The farthest the vehicle went from where it stood before it first left the ground (m).
    slid_on_ground_m: f64,
    /// The largest tilt from arming to the end of the climb (deg).
    largest_tilt_deg: f64,
    /// The tilt it hovers at once there, the mean over the last 5 s (deg).
    hover_tilt_deg: f64,
    /// Horizontal distance from the take-off spot, the mean over the last 5 s (m): the
    /// `typical` GPS's error as much as the control's.
    hold_error_m: f64,
}

fn take_off_in_wind(seed: u64) -> Takeoff {
    let a = airframe("quad_x");
    let cfg = SimConfig {
        seed,
        wind: WindConfig {
            mean_ned_m_s: [-10.0, 0.0, 0.0],
            turbulence_w20_m_s: 0.0,
            roughness_m: None,
        },
        ..SimConfig::default()
    };
    let (mut sim, mut autopilot) = common::auto_flight(&a, cfg, 10.0, 60.0);
    let mut commands = [0.0; MAX_ROTORS];
    let mut out = Takeoff::default();
    let start = sim.truth().body.pos_ned_m;
    let mut airborne = false;
    let mut hover = Vec::new();
    while sim.time_s() < 30.0 {
        common::autopilot_interval(&mut sim, &mut autopilot, &mut commands, 4, true);
        let body = sim.truth().body;
        let tilt = (body.q_ned_from_frd * Vector3::z())
            .angle(&Vector3::z())
            .to_degrees();
        let off = (body.pos_ned_m - start).xy().norm();
        airborne |= !sim.truth().landed;
        if !airborne {
            out.slid_on_ground_m = out.slid_on_ground_m.max(off);
        }
        out.largest_tilt_deg = out.largest_tilt_deg.max(tilt);
        if sim.time_s() > 25.0 {
            hover.push((tilt, off));
        }
    }
    let n = hover.len() as f64;
    out.hover_tilt_deg = hover.iter().map(|h| h.0).sum::<f64>() / n;
    out.hold_error_m = hover.iter().map(|h| h.1).sum::<f64>() / n;
    out
}

#[test]
fn a_take_off_into_a_10_m_s_wind_stays_put_on_the_ground_and_leans_no_further_than_it_hovers() {
    for seed in 1..=2 {
        let t = take_off_in_wind(seed);
        println!("seed {seed}: {t:?}");
        assert!(t.slid_on_ground_m < 0.1, "seed {seed}: {t:?}");
        // The tilt the wind needs (about 20° for quad_x at 10 m/s) and not much more;
        // ArduCopter leans 21.5° on the same physics.
        assert!(
            t.largest_tilt_deg <= 25.0 && t.largest_tilt_deg < t.hover_tilt_deg + 5.0,
            "seed {seed}: {t:?}"
        );
        // Held above its spot as well as the `typical` GPS tells it (its error is 0.2-0.7 m
        // here over 5 s); a vehicle blown away would be metres off.
        assert!(t.hold_error_m < 1.0, "seed {seed}: {t:?}");
    }
}
