//! Flight modes on the wire: PX4's `custom_mode` encoding (what MAVSDK, pymavlink and
//! QGroundControl decode for a `MAV_AUTOPILOT_PX4` vehicle) and MAVLink's standard modes.

use flight_core::commander::FlightMode;
use mavlink::dialects::common::MavStandardMode;

/// PX4's main modes (`custom_mode` bits 16–23).
mod main {
    pub const MANUAL: u8 = 1;
    pub const ALTCTL: u8 = 2;
    pub const POSCTL: u8 = 3;
    pub const AUTO: u8 = 4;
    pub const OFFBOARD: u8 = 6;
    pub const STABILIZED: u8 = 7;
}

/// PX4's sub-modes (`custom_mode` bits 24–31): of AUTO, and POSCTL's Orbit.
mod sub {
    pub const ORBIT: u8 = 1;
    pub const TAKEOFF: u8 = 2;
    pub const LOITER: u8 = 3;
    pub const MISSION: u8 = 4;
    pub const RTL: u8 = 5;
    pub const LAND: u8 = 6;
    pub const FOLLOW_TARGET: u8 = 8;
}

/// Every mode a ground station may select, in the order `AVAILABLE_MODES` lists them.
pub const SELECTABLE: [FlightMode; 12] = [
    FlightMode::Manual,
    FlightMode::Stabilized,
    FlightMode::Altctl,
    FlightMode::Posctl,
    FlightMode::Takeoff,
    FlightMode::Loiter,
    FlightMode::Mission,
    FlightMode::Rtl,
    FlightMode::Land,
    FlightMode::Offboard,
    FlightMode::Orbit,
    FlightMode::FollowTarget,
];

const fn px4(main: u8, sub: u8) -> u32 {
    ((main as u32) << 16) | ((sub as u32) << 24)
}

/// The mode as PX4's `custom_mode` (the failsafe Descend shows as AUTO.LAND, as in PX4).
pub fn custom_mode(mode: FlightMode) -> u32 {
    match mode {
        FlightMode::Manual => px4(main::MANUAL, 0),
        FlightMode::Stabilized => px4(main::STABILIZED, 0),
        FlightMode::Altctl => px4(main::ALTCTL, 0),
        FlightMode::Posctl => px4(main::POSCTL, 0),
        FlightMode::Takeoff => px4(main::AUTO, sub::TAKEOFF),
        FlightMode::Loiter => px4(main::AUTO, sub::LOITER),
        FlightMode::Mission => px4(main::AUTO, sub::MISSION),
        FlightMode::Rtl => px4(main::AUTO, sub::RTL),
        FlightMode::Land | FlightMode::Descend => px4(main::AUTO, sub::LAND),
        FlightMode::Offboard => px4(main::OFFBOARD, 0),
        FlightMode::Orbit => px4(main::POSCTL, sub::ORBIT),
        FlightMode::FollowTarget => px4(main::AUTO, sub::FOLLOW_TARGET),
    }
}

/// The mode a PX4 `custom_mode` names (`MAV_CMD_DO_SET_MODE` param2/param3, `SET_MODE`), or
/// `None` for one this vehicle does not have. The sub-mode counts for AUTO, and for POSCTL's
/// Orbit.
pub fn from_px4(main_mode: u8, sub_mode: u8) -> Option<FlightMode> {
    Some(match (main_mode, sub_mode) {
        (main::MANUAL, _) => FlightMode::Manual,
        (main::STABILIZED, _) => FlightMode::Stabilized,
        (main::ALTCTL, _) => FlightMode::Altctl,
        (main::POSCTL, sub::ORBIT) => FlightMode::Orbit,
        (main::POSCTL, _) => FlightMode::Posctl,
        (main::OFFBOARD, _) => FlightMode::Offboard,
        (main::AUTO, sub::TAKEOFF) => FlightMode::Takeoff,
        (main::AUTO, sub::LOITER) => FlightMode::Loiter,
        (main::AUTO, sub::MISSION) => FlightMode::Mission,
        (main::AUTO, sub::RTL) => FlightMode::Rtl,
        (main::AUTO, sub::LAND) => FlightMode::Land,
        (main::AUTO, sub::FOLLOW_TARGET) => FlightMode::FollowTarget,
        _ => return None,
    })
}

/// The standard mode a flight mode is, if any.
pub fn standard_mode(mode: FlightMode) -> MavStandardMode {
    match mode {
        FlightMode::Posctl => MavStandardMode::MAV_STANDARD_MODE_POSITION_HOLD,
        FlightMode::Altctl => MavStandardMode::MAV_STANDARD_MODE_ALTITUDE_HOLD,
        FlightMode::Rtl => MavStandardMode::MAV_STANDARD_MODE_SAFE_RECOVERY,
        FlightMode::Mission => MavStandardMode::MAV_STANDARD_MODE_MISSION,
        FlightMode::Land => MavStandardMode::MAV_STANDARD_MODE_LAND,
        FlightMode::Takeoff => MavStandardMode::MAV_STANDARD_MODE_TAKEOFF,
        FlightMode::Orbit => MavStandardMode::MAV_STANDARD_MODE_ORBIT,
        _ => MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD,
    }
}

/// The flight mode a standard mode selects (`MAV_CMD_DO_SET_STANDARD_MODE`), if this vehicle
/// has it.
pub fn from_standard(mode: u32) -> Option<FlightMode> {
    SELECTABLE.into_iter().find(|&m| {
        let s = standard_mode(m);
        s != MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD && s as u32 == mode
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn px4_encoding_round_trips_and_matches_px4s_numbers() {
        // PX4's px4_custom_mode.h: AUTO.LOITER is main 4, sub 3 = 0x0304_0000.
        assert_eq!(custom_mode(FlightMode::Loiter), 0x0304_0000);
        assert_eq!(custom_mode(FlightMode::Offboard), 0x0006_0000);
        assert_eq!(custom_mode(FlightMode::Takeoff), 0x0204_0000);
        for m in SELECTABLE {
            let c = custom_mode(m);
            assert_eq!(c & 0xFFFF, 0, "{m:?}: low bits reserved");
            assert_eq!(from_px4((c >> 16) as u8, (c >> 24) as u8), Some(m));
        }
        assert_eq!(
            custom_mode(FlightMode::Descend),
            custom_mode(FlightMode::Land)
        );
        // Sub-modes count for AUTO and POSCTL's Orbit (PX4's POSCTL_ORBIT = 1); AUTO.READY
        // and unknown mains are not modes here.
        assert_eq!(custom_mode(FlightMode::Orbit), 0x0103_0000);
        assert_eq!(from_px4(3, 9), Some(FlightMode::Posctl));
        assert_eq!(from_px4(4, 1), None);
        assert_eq!(from_px4(9, 0), None);
    }

    #[test]
    fn standard_modes_map_both_ways() {
        assert_eq!(from_standard(7), Some(FlightMode::Land));
        assert_eq!(from_standard(5), Some(FlightMode::Rtl));
        assert_eq!(from_standard(0), None);
        assert_eq!(from_standard(2), Some(FlightMode::Orbit));
        assert_eq!(from_standard(3), None, "no cruise");
    }
}
