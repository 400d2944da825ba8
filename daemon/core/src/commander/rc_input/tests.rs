use super::*;

fn frame(channels: &[u16]) -> RcFrame {
    let mut f = RcFrame {
        channels: [1500; RC_CHANNELS],
        count: 16,
        failsafe: false,
        link: None,
    };
    f.channels[..channels.len()].copy_from_slice(channels);
    f
}

#[test]
fn sticks_are_the_mapped_channels_about_their_trims_and_dead_zones() {
    let rc = RcGroup::default();
    // Roll full right, pitch half forward, throttle a quarter, yaw inside the dead zone.
    let d = rc.demand(&frame(&[2000, 1755, 1250, 1505]));
    assert_eq!(d.sticks.right, 1.0);
    assert!((d.sticks.forward - 245.0 / 490.0).abs() < 1e-12, "{d:?}");
    assert_eq!(d.sticks.throttle, 0.25);
    assert_eq!(d.sticks.yaw, 0.0);
    let reversed = RcGroup {
        rc1_rev: -1.0,
        ..RcGroup::default()
    };
    assert_eq!(reversed.demand(&frame(&[2000])).sticks.right, -1.0);
    // A channel the frame does not carry, or none mapped: centred.
    let mut short = frame(&[1000, 1000, 1000, 1000]);
    short.count = 2;
    let d = rc.demand(&short);
    assert_eq!((d.sticks.throttle, d.sticks.yaw), (0.5, 0.0));
}

#[test]
fn a_three_position_switch_selects_slots_one_four_and_six_and_the_arm_switch_its_threshold() {
    let rc = RcGroup {
        map_arm: 6,
        ..RcGroup::default()
    };
    let slot = |us| rc.demand(&frame(&[1500, 1500, 1000, 1500, us])).mode_slot;
    assert_eq!(
        [slot(1000), slot(1500), slot(2000)],
        [Some(0), Some(3), Some(5)]
    );
    assert_eq!(rc.slot_mode(0), Some(FlightMode::Posctl));
    assert_eq!(rc.slot_mode(3), Some(FlightMode::Loiter));
    assert_eq!(rc.slot_mode(5), Some(FlightMode::Land));
    let arm = |us| {
        rc.demand(&frame(&[1500, 1500, 1000, 1500, 1500, us]))
            .arm_switch
    };
    assert_eq!(
        [arm(1000), arm(1740), arm(1760)],
        [Some(false), Some(false), Some(true)]
    );
    assert_eq!(px4_mode(7), None, "Offboard is not a switch's mode");
}

#[test]
fn the_gesture_arms_after_a_second_held_and_says_so_once() {
    let mut g = Gesture::default();
    let held = Sticks {
        throttle: 0.0,
        yaw: 1.0,
        ..Sticks::CENTRED
    };
    assert_eq!(g.update(0.0, &held), None);
    assert_eq!(g.update(0.9, &held), None);
    assert_eq!(g.update(1.0, &held), Some(true));
    assert_eq!(g.update(1.5, &held), None, "once");
    assert_eq!(g.update(1.6, &Sticks::CENTRED), None);
    let left = Sticks { yaw: -1.0, ..held };
    assert_eq!(g.update(2.0, &left), None);
    assert_eq!(g.update(3.0, &left), Some(false));
}
