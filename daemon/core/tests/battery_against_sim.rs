//! The battery estimator against the simulator's pack, whose discharge curve is not the
//! estimator's (a different LiPo table, internal resistance from the airframe file): the
//! figures a user would see on a real pack whose curve differs from the typical one.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use airframe::Airframe;
use flight_core::sensors::battery::{BatteryConfig, BatteryEstimator, BatteryGroup};
use sitl_core::powertrain::Battery;
use std::path::PathBuf;

fn quad() -> Airframe {
    Airframe::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes/quad_x.toml"),
    )
    .unwrap()
}

/// The largest error of the estimate while the truth is in `range`, for a pack charged to
/// `start` flown at the quad's hover power with a climb every minute: (optimistic: estimate
/// above the truth, conservative: below), both ≥ 0.
fn fly_down(params: &BatteryGroup, start: f64, range: (f64, f64)) -> (f64, f64) {
    let a = quad();
    let mut pack = Battery::charged_to(&a.battery, start);
    let mut e = BatteryEstimator::new(BatteryConfig::from_params(params, &a.battery));
    let dt = 0.01;
    let (mut optimistic, mut conservative) = (0.0f64, 0.0f64);
    // At rest for 2 s (the idle current), then flying.
    for k in 0.. {
        let t = k as f64 * dt;
        let power = if t < 2.0 {
            0.0
        } else if (t % 60.0) < 5.0 {
            320.0
        } else {
            160.0
        };
        pack.draw(power, dt);
        let truth = pack.remaining();
        if truth < range.0 {
            break;
        }
        let throttle = (power / 400.0).min(1.0);
        let s = e.step(pack.voltage(), Some(pack.current_a), throttle, dt);
        if t > 2.0 && truth <= range.1 {
            let error = s.remaining.unwrap() - truth;
            optimistic = optimistic.max(error);
            conservative = conservative.max(-error);
        }
    }
    (optimistic, conservative)
}

/// What matters for the failsafe is that the estimate is never optimistic: it must not read
/// more than 2 % above the truth anywhere. Where the counted charge rules (capacity known, above
/// 20 %), it is within 1 % of the truth. Below, and wherever the voltage rules (the start of a
/// partly charged pack, no capacity), the two curves' difference shows as a conservative error,
/// reported and bounded (the typical curve reads this pack low: 3.6 V is 10 % for the simulator's
/// cell and 5 % for the typical one).
#[test]
fn estimate_against_the_simulators_pack() {
    let p = BatteryGroup::default();
    let pct = |(o, c): (f64, f64)| format!("+{:.1} %/−{:.1} %", 100.0 * o, 100.0 * c);
    let full = fly_down(&p, 1.0, (0.2, 1.0));
    let full_low = fly_down(&p, 1.0, (0.03, 0.2));
    let partial = fly_down(&p, 0.4, (0.03, 0.4));
    let voltage_only = fly_down(
        &BatteryGroup {
            capacity_mah: -1.0,
            ..p
        },
        1.0,
        (0.03, 1.0),
    );
    println!(
        "battery estimate against the simulator's pack (quad_x, 5000 mAh, hover and climbs), error optimistic/conservative: capacity known, from full: {} above 20 %, {} below; from a 40 % pack: {}; voltage only: {}",
        pct(full),
        pct(full_low),
        pct(partial),
        pct(voltage_only)
    );
    for (name, (optimistic, conservative), bound) in [
        ("from full, above 20 %", full, 0.01),
        ("from full, below 20 %", full_low, 0.08),
        ("from 40 %", partial, 0.12),
        ("voltage only", voltage_only, 0.12),
    ] {
        assert!(optimistic <= 0.02, "{name}: optimistic by {optimistic}");
        assert!(
            conservative <= bound,
            "{name}: conservative by {conservative}"
        );
    }
}
