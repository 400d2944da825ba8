//! The stream sets a link starts with, as PX4's `mavlink start -m MODE` chooses them: the
//! messages sent without being asked and their rates.

use mavlink::MessageData;
use mavlink::dialects::common::*;

/// Messages sent without being asked, with their default rates (Hz), PX4-like.
pub(crate) const DEFAULT_STREAMS: [(u32, f64); 20] = [
    (HEARTBEAT_DATA::ID, 1.0),
    (SYS_STATUS_DATA::ID, 1.0),
    (EXTENDED_SYS_STATE_DATA::ID, 1.0),
    (GLOBAL_POSITION_INT_DATA::ID, 5.0),
    (LOCAL_POSITION_NED_DATA::ID, 5.0),
    (GPS_RAW_INT_DATA::ID, 2.0),
    (ATTITUDE_DATA::ID, 10.0),
    (ATTITUDE_QUATERNION_DATA::ID, 10.0),
    (VFR_HUD_DATA::ID, 4.0),
    (BATTERY_STATUS_DATA::ID, 1.0),
    (HOME_POSITION_DATA::ID, 0.5),
    (ALTITUDE_DATA::ID, 1.0),
    (SYSTEM_TIME_DATA::ID, 1.0),
    (CURRENT_MODE_DATA::ID, 1.0),
    // The set-points flown, echoed (PX4's normal stream set has them too).
    (ATTITUDE_TARGET_DATA::ID, 2.0),
    (POSITION_TARGET_LOCAL_NED_DATA::ID, 1.0),
    // In Orbit only, at PX4's rate of its normal stream set.
    (ORBIT_EXECUTION_STATUS_DATA::ID, 2.0),
    (WIND_COV_DATA::ID, 1.0), // once the vehicle has flown and learned it
    // Once an RC receiver is read (PX4's normal stream set has RC_CHANNELS at 5 Hz).
    (RC_CHANNELS_DATA::ID, 5.0),
    (RADIO_STATUS_DATA::ID, 1.0),
];

/// The same messages at the rates of PX4's `onboard` stream set (`mavlink start -m onboard`, the
/// set PX4's SITL gives MAVSDK's port): status at 5 Hz, the state at tens of Hz. Where PX4
/// streams a message on every new sample (GPS_RAW_INT), at the GPS's usual 5 Hz; CURRENT_MODE
/// and RADIO_STATUS, absent from PX4's table, as in the normal set.
const ONBOARD_STREAMS: [(u32, f64); 20] = [
    (HEARTBEAT_DATA::ID, 1.0),
    (SYS_STATUS_DATA::ID, 5.0),
    (EXTENDED_SYS_STATE_DATA::ID, 5.0),
    (GLOBAL_POSITION_INT_DATA::ID, 50.0),
    (LOCAL_POSITION_NED_DATA::ID, 30.0),
    (GPS_RAW_INT_DATA::ID, 5.0),
    (ATTITUDE_DATA::ID, 100.0),
    (ATTITUDE_QUATERNION_DATA::ID, 50.0),
    (VFR_HUD_DATA::ID, 10.0),
    (BATTERY_STATUS_DATA::ID, 0.5),
    (HOME_POSITION_DATA::ID, 0.5),
    (ALTITUDE_DATA::ID, 10.0),
    (SYSTEM_TIME_DATA::ID, 1.0),
    (CURRENT_MODE_DATA::ID, 1.0),
    (ATTITUDE_TARGET_DATA::ID, 10.0),
    (POSITION_TARGET_LOCAL_NED_DATA::ID, 10.0),
    (ORBIT_EXECUTION_STATUS_DATA::ID, 5.0),
    (WIND_COV_DATA::ID, 10.0),
    (RC_CHANNELS_DATA::ID, 20.0),
    (RADIO_STATUS_DATA::ID, 1.0),
];

/// The stream set a link starts with, as PX4's `mavlink start -m MODE` chooses it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum StreamSet {
    /// PX4's `normal` set: a ground station such as QGroundControl.
    #[default]
    Normal,
    /// PX4's `onboard` set: an API such as MAVSDK on a companion computer.
    Onboard,
}

impl StreamSet {
    /// The set named `name` (`normal`, `onboard`), if there is one.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "normal" => Some(Self::Normal),
            "onboard" => Some(Self::Onboard),
            _ => None,
        }
    }

    /// Each message and its rate (Hz).
    pub(crate) fn rates(self) -> &'static [(u32, f64)] {
        match self {
            Self::Normal => &DEFAULT_STREAMS,
            Self::Onboard => &ONBOARD_STREAMS,
        }
    }
}
