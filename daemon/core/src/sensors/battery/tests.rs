use super::*;

fn pack() -> BatterySpec {
    BatterySpec {
        cells: 4,
        capacity_mah: 5000.0,
        internal_resistance_ohm: 0.02,
        efficiency: 0.7,
        idle_current_a: 0.5,
    }
}

fn config() -> BatteryConfig {
    BatteryConfig::from_params(&BatteryGroup::default(), &pack())
}

#[test]
fn parameters_left_open_come_from_the_airframe_pack() {
    let c = config();
    assert_eq!((c.cells, c.capacity_mah), (4, Some(5000.0)));
    assert!((c.r_cell_ohm - 0.005).abs() < 1e-12);
    let p = BatteryGroup {
        cells: 6,
        capacity_mah: -1.0,
        r_internal_ohm: 0.01,
        ..BatteryGroup::default()
    };
    let c = BatteryConfig::from_params(&p, &pack());
    assert_eq!((c.cells, c.capacity_mah, c.r_cell_ohm), (6, None, 0.01));
    let bad = BatteryGroup {
        v_empty: 4.0,
        v_charged: 4.05,
        ..BatteryGroup::default()
    };
    assert_eq!(bad.inconsistencies().len(), 1);
}

#[test]
fn the_curve_runs_from_empty_to_full_and_stretches_with_its_parameters() {
    let c = config();
    assert_eq!(c.charge_at_rest(3.0), 0.0);
    assert_eq!(c.charge_at_rest(3.27), 0.0);
    assert!((c.charge_at_rest(4.2) - 1.0).abs() < 1e-12);
    assert_eq!(c.charge_at_rest(4.35), 1.0);
    assert!((c.charge_at_rest(3.84) - 0.5).abs() < 1e-12);
    let mut last = -1.0;
    for k in 0..=100 {
        let s = c.charge_at_rest(3.2 + k as f64 * 0.01);
        assert!(s >= last, "not monotonic at {k}");
        last = s;
    }
    // A high-voltage pack (4.35 V full): the same shape, stretched.
    let hv = BatteryConfig {
        v_charged: 4.35,
        ..c
    };
    assert!((hv.charge_at_rest(4.35) - 1.0).abs() < 1e-12);
    assert!(hv.charge_at_rest(4.2) < 0.95);
}

/// A synthetic pack that follows the estimator's own curve exactly: any error is the estimator's.
fn synthetic_voltage(c: &BatteryConfig, charge: f64, current_a: f64) -> f64 {
    // Invert the curve by bisection.
    let (mut lo, mut hi) = (c.v_empty, c.v_charged);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if c.charge_at_rest(mid) < charge {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    c.cells as f64 * (0.5 * (lo + hi) - current_a * c.r_cell_ohm)
}

#[test]
fn counted_charge_follows_a_discharge_and_the_load_is_compensated() {
    let c = config();
    let mut e = BatteryEstimator::new(c);
    let (dt, mut charge) = (0.01, 0.9);
    let mut worst = 0.0f64;
    for k in 0..(600.0 / dt) as usize {
        // Hover at 20 A with 40 A climbs every minute.
        let i = if k % 6000 < 500 { 40.0 } else { 20.0 };
        let s = e.step(synthetic_voltage(&c, charge, i), Some(i), 0.5, dt);
        charge -= i * dt / 3.6 / 5000.0;
        worst = worst.max((s.remaining.unwrap() - charge).abs());
        if k > 100 {
            // Under 40 A the pack sags 0.8 V; compensated, the cell reads at rest.
            let rest = synthetic_voltage(&c, charge, 0.0) / 4.0;
            assert!((s.cell_v_at_rest - rest).abs() < 0.02, "{k}: {s:?}");
        }
    }
    assert!(worst < 0.005, "worst error {worst}");
    let s = e.state();
    // 10 minutes at ~21.7 A: 3 611 mAh.
    assert!((s.consumed_mah.unwrap() - 3611.1).abs() < 5.0, "{s:?}");
    let left = charge * 5000.0 * 3.6 / 20.0;
    assert!(
        (s.time_remaining_s.unwrap() - left).abs() < 0.1 * left,
        "{s:?} against {left}"
    );
}

#[test]
fn a_wrong_capacity_is_pulled_back_by_the_voltage_before_the_pack_is_flat() {
    // The pack is 5 000 mAh; the operator said 8 000.
    let c = BatteryConfig {
        capacity_mah: Some(8000.0),
        ..config()
    };
    let mut e = BatteryEstimator::new(c);
    let (dt, mut charge) = (0.01, 1.0);
    let mut at_true_5 = None;
    while charge > 0.02 {
        let s = e.step(synthetic_voltage(&c, charge, 20.0), Some(20.0), 0.5, dt);
        charge -= 20.0 * dt / 3.6 / 5000.0;
        if charge < 0.05 && at_true_5.is_none() {
            at_true_5 = s.remaining;
        }
    }
    // Counting alone would read 41 % at a true 5 %.
    let read = at_true_5.unwrap();
    assert!(read < 0.15, "reads {read} at a true 5 %");
    assert!(e.state().remaining.unwrap() < 0.08, "{:?}", e.state());
}

#[test]
fn without_a_current_the_throttle_stands_in_and_without_a_voltage_nothing_is_claimed() {
    let c = BatteryConfig {
        capacity_mah: None,
        ..config()
    };
    let mut e = BatteryEstimator::new(c);
    // 50 % charge; half throttle sags each cell by 0.05 V, which BAT1_V_LOAD_DROP puts back.
    let v = synthetic_voltage(&c, 0.5, 0.0) - 4.0 * 0.05;
    let mut s = e.step(v, None, 0.5, 0.01);
    for _ in 0..500 {
        s = e.step(v, None, 0.5, 0.01);
    }
    assert!((s.remaining.unwrap() - 0.5).abs() < 0.01, "{s:?}");
    assert_eq!((s.consumed_mah, s.time_remaining_s), (None, None));
    for bad in [0.0, 1.5, f64::NAN] {
        let s = e.step(bad, Some(3.0), 0.5, 0.01);
        assert_eq!(s.remaining, None, "{bad}");
    }
}
