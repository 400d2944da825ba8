//! The commander's state as the rest of the vehicle sees it: the flight modes (PX4's), where
//! the vehicle is relative to the ground, and the status telemetry shows.

use super::{GroundContact, OrbitStatus, TargetEstimate};
use crate::mission::MissionStatus;
use crate::safety::failsafe::{Condition, FailsafeAction};
use nalgebra::Vector3;

/// The flight modes, in PX4's terms (the MAVLink layer maps them to PX4's `custom_mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FlightMode {
    /// PX4's Manual: on a multicopter the same as Stabilized.
    Manual,
    /// Sticks to attitude (self-levelling) and throttle to thrust; no altitude or position hold.
    Stabilized,
    /// Altitude hold: the throttle stick sets the climb rate (centre holds), the roll and pitch
    /// sticks tilt the vehicle, the yaw stick turns it.
    Altctl,
    /// Position hold: the sticks set horizontal velocity in the heading's frame, climb rate and
    /// yaw rate; centred sticks hold the position.
    Posctl,
    /// Climb to the take-off altitude, then Loiter.
    Takeoff,
    /// Hold position (PX4's AUTO.LOITER, "Hold").
    Loiter,
    /// Fly the uploaded mission (PX4's AUTO.MISSION).
    Mission,
    /// Return to home and land.
    Rtl,
    /// Land where it is.
    Land,
    /// Follow set-points streamed by a companion computer or script.
    Offboard,
    /// Circle a point (PX4's Orbit, `MAV_CMD_DO_ORBIT`).
    Orbit,
    /// Follow a target that reports its place (PX4's Follow Me, `FOLLOW_TARGET`).
    FollowTarget,
    /// Failsafe: level and descend on what estimate is left.
    Descend,
}

impl FlightMode {
    /// Whether the mode flies on the horizontal position estimate.
    pub fn needs_position(self) -> bool {
        !matches!(
            self,
            Self::Manual | Self::Stabilized | Self::Altctl | Self::Descend
        )
    }

    /// The mode's name as PX4 reports it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Manual => "MANUAL",
            Self::Stabilized => "STABILIZED",
            Self::Altctl => "ALTCTL",
            Self::Posctl => "POSCTL",
            Self::Takeoff => "TAKEOFF",
            Self::Loiter => "LOITER",
            Self::Mission => "MISSION",
            Self::Rtl => "RTL",
            Self::Land => "LAND",
            Self::Offboard => "OFFBOARD",
            Self::Orbit => "ORBIT",
            Self::FollowTarget => "FOLLOW_TARGET",
            Self::Descend => "DESCEND",
        }
    }
}

/// Where the vehicle is relative to the ground (MAVLink's `MAV_LANDED_STATE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LandedState {
    /// On the ground (armed or not).
    OnGround,
    /// Climbing away from the ground.
    Takeoff,
    /// Flying.
    InAir,
    /// Descending to land.
    Landing,
}

impl LandedState {
    /// Its name as the flight-data CSV writes it.
    pub fn name(self) -> &'static str {
        match self {
            LandedState::OnGround => "OnGround",
            LandedState::Takeoff => "Takeoff",
            LandedState::InAir => "InAir",
            LandedState::Landing => "Landing",
        }
    }
}

/// The commander's state as telemetry shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommanderStatus {
    /// Motors armed.
    pub armed: bool,
    /// The flight mode.
    pub mode: FlightMode,
    /// On the ground, taking off, flying or landing.
    pub landed: LandedState,
    /// How far a landing has come on the ground.
    pub ground_contact: GroundContact,
    /// Home position NED (m) and heading (rad), once set.
    pub home: Option<(Vector3<f64>, f64)>,
    /// A failsafe is flying the vehicle.
    pub failsafe: bool,
    /// The failsafe's action and the condition behind it, while one acts (a warning included).
    pub failsafe_action: Option<(FailsafeAction, Condition)>,
    /// The estimator can be flown on.
    pub ready: bool,
    /// Time in the current mode (s).
    pub in_mode_s: f64,
    /// How often manual control was lost in a manual mode (Hold took over).
    pub manual_losses: u32,
    /// Manual control: never seen (`None`), arriving (`Some(true)`) or stale (`Some(false)`).
    pub manual_control: Option<bool>,
    /// How often the offboard set-points were lost in Offboard (and `COM_OBL_RC_ACT` took over).
    pub offboard_losses: u32,
    /// The mission's progress.
    pub mission: MissionStatus,
    /// A motor declared failed (1-based), if any.
    pub motor_failed: Option<usize>,
    /// A quad flying on its other three rotors, spinning.
    pub spinning: bool,
    /// The failsafe conditions acting (bit k: `safety::CONDITIONS[k]`).
    pub failsafe_conditions: u32,
    /// Disarmed and every arming check passes (`SYS_STATUS`'s pre-arm bit).
    pub prearm_ok: bool,
    /// The failsafe machine's events, numbered: each to be said once.
    pub safety_log: crate::safety::failsafe::SafetyLog,
    /// The orbit flown, in Orbit.
    pub orbit: Option<OrbitStatus>,
    /// The follow target as filtered, in Follow Target once there has been a fix.
    pub follow: Option<TargetEstimate>,
}
