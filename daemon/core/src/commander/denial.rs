//! Why a command was refused: one variant per reason. `Display` gives the operator's words
//! (`STATUSTEXT`, the shell's answer); a ground station tells the reasons apart by variant.

use crate::safety::failsafe::Condition;
use crate::safety::failure_injection::Refusal;
use crate::safety::preflight::PreflightCheck;
use crate::safety::targets::TargetError;
use std::mem::{Discriminant, discriminant};

/// Why a command was refused. `command` names what was asked in the operator's words
/// ("orbit", "take-off", "MISSION" …).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Denial {
    /// Arming (or a command that arms) refused.
    #[error("arming refused: {0}")]
    Arming(ArmingDenial),
    /// The command names a place on the Earth and the vehicle has no global position.
    #[error("{command} refused: no global position yet")]
    NoGlobalPosition {
        /// What was asked.
        command: &'static str,
    },
    /// The command needs a position estimate and none has been seen.
    #[error("{command} refused: no position estimate yet")]
    NoPositionEstimate {
        /// What was asked.
        command: &'static str,
    },
    /// The command needs a valid position estimate.
    #[error("{command} refused: position estimate not valid")]
    PositionNotValid {
        /// What was asked.
        command: &'static str,
    },
    /// The estimator cannot be flown on yet.
    #[error("{command} refused: estimator not ready")]
    NotReady {
        /// What was asked.
        command: &'static str,
    },
    /// The command is for a vehicle in the air.
    #[error("{command} refused: not flying")]
    NotFlying {
        /// What was asked.
        command: &'static str,
    },
    /// A failsafe's Descend flies the vehicle until it lands.
    #[error("{command} refused: failsafe descent in progress")]
    FailsafeDescent {
        /// What was asked.
        command: &'static str,
    },
    /// A failsafe that allows no take-over acts.
    #[error("mode change refused: failsafe in progress ({0})")]
    FailsafeActing(Condition),
    /// The command's target is out of range or not a place.
    #[error("{command} refused: {why}")]
    Target {
        /// What was asked.
        command: &'static str,
        /// What is wrong with the target.
        why: TargetError,
    },
    /// A number of the command is not finite.
    #[error("{command} refused: {what}")]
    NotFinite {
        /// What was asked.
        command: &'static str,
        /// Which number, in the operator's words.
        what: &'static str,
    },
    /// An orbit's radius outside `RADIUS_MIN_M` to `MC_ORBIT_RAD_MAX`.
    #[error("orbit refused: radius {radius_m} m outside {min_m}..{max_m} m (MC_ORBIT_RAD_MAX)")]
    OrbitRadius {
        /// The radius asked (m, signed).
        radius_m: f64,
        /// The least radius (m).
        min_m: f64,
        /// `MC_ORBIT_RAD_MAX` (m).
        max_m: f64,
    },
    /// An orbit's speed not above zero or above the largest.
    #[error("orbit refused: speed {speed_m_s} m/s outside 0..{max_m_s} m/s")]
    OrbitSpeed {
        /// The speed asked (m/s).
        speed_m_s: f64,
        /// The largest (m/s).
        max_m_s: f64,
    },
    /// A follow target's fix too far from the vehicle.
    #[error("follow target refused: {away_m:.0} m away (at most {max_m:.0} m)")]
    TargetTooFar {
        /// Its distance (m).
        away_m: f64,
        /// The farthest (m).
        max_m: f64,
    },
    /// A mission item the mission checks refuse.
    #[error("MISSION refused: item {item}: {why}")]
    MissionItem {
        /// The item's index.
        item: usize,
        /// What is wrong with it.
        why: TargetError,
    },
    /// Mission mode without a mission.
    #[error("MISSION refused: no mission uploaded")]
    NoMission,
    /// A mission item asked for that the mission does not have.
    #[error("mission item {seq} does not exist ({count} items)")]
    NoMissionItem {
        /// The item asked for.
        seq: u16,
        /// How many there are.
        count: usize,
    },
    /// A speed of automatic flight not above zero.
    #[error("speed {0} m/s refused")]
    Speed(f64),
    /// The command is flown only in some modes.
    #[error("{command} refused: {needs}")]
    WrongMode {
        /// What was asked.
        command: &'static str,
        /// Where it is flown, in the operator's words.
        needs: &'static str,
    },
    /// A stick mode without a stick stream (the mode's name).
    #[error("{0} refused: no manual control (MANUAL_CONTROL)")]
    NoManualControl(&'static str),
    /// Offboard without a set-point stream within `COM_OF_LOSS_T` (s).
    #[error("OFFBOARD refused: no set-point stream in the last {0} s (COM_OF_LOSS_T)")]
    NoOffboardStream(f64),
    /// Return without a home.
    #[error("RTL refused: no home position")]
    NoHome,
    /// A failsafe's mode asked for as a mode.
    #[error("DESCEND is a failsafe, not a mode to select")]
    FailsafeMode,
    /// Disarming in the air without force.
    #[error("disarming refused: in the air (land first, or force)")]
    InAir,
    /// A calibration asked for while armed.
    #[error("calibration refused: disarm first")]
    CalibrationArmed,
    /// A calibration asked for while another runs (its sensor).
    #[error("calibration refused: the {0} calibration is running")]
    CalibrationRunning(&'static str),
    /// A failure injection refused.
    #[error(transparent)]
    Injection(#[from] Refusal),
    /// The vehicle's request queue was full.
    #[error("vehicle busy: try again")]
    Busy,
    /// The vehicle did not answer (its loop has stopped).
    #[error("the control loop did not answer")]
    NoAnswer,
}

/// Why arming was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArmingDenial {
    /// An arming check failed: the first, and how many more did.
    #[error("{check}{}", more_said(*.more))]
    Check {
        /// The first that failed.
        check: PreflightCheck,
        /// How many more failed.
        more: usize,
    },
    /// A stick mode without a stick stream (the mode's name).
    #[error("{0} needs manual control (MANUAL_CONTROL)")]
    NeedsSticks(&'static str),
    /// Position and Altitude arm with the throttle at or below centre.
    #[error("throttle stick above centre")]
    ThrottleAboveCentre,
    /// The stick-to-thrust modes arm with the throttle low.
    #[error("throttle stick not low")]
    ThrottleNotLow,
    /// Offboard arms on a set-point stream.
    #[error("no offboard set-points")]
    NoOffboard,
    /// The mode cannot start on the ground (its name).
    #[error("not in a mode to start in ({0})")]
    ModeCannotStart(&'static str),
    /// No sample has reached the commander.
    #[error("no sensor data yet")]
    NoSensorData,
    /// A calibration runs (its sensor).
    #[error("calibrating the {0}")]
    Calibrating(&'static str),
    /// Mission mode may not be entered.
    #[error("{0}")]
    Mission(Box<Denial>),
}

/// " (and N more)" for `more` further failures.
fn more_said(more: usize) -> String {
    match more {
        0 => String::new(),
        n => format!(" (and {n} more)"),
    }
}

/// What tells two denials' reasons apart, their numbers aside.
type ReasonKey = (
    Discriminant<Denial>,
    Option<&'static str>,
    Option<&'static str>,
    Option<Discriminant<TargetError>>,
);

impl Denial {
    /// The same reason as `other`, its numbers aside (a stream's refusals said once per
    /// reason, not at every fix).
    pub fn same_reason(&self, other: &Self) -> bool {
        self.reason_key() == other.reason_key()
    }

    /// The variant, the words it names and the kind of target error, without the numbers.
    fn reason_key(&self) -> ReasonKey {
        let (command, detail, target) = match self {
            Self::NoGlobalPosition { command }
            | Self::NoPositionEstimate { command }
            | Self::PositionNotValid { command }
            | Self::NotReady { command }
            | Self::NotFlying { command }
            | Self::FailsafeDescent { command } => (Some(*command), None, None),
            Self::NotFinite { command, what: d } | Self::WrongMode { command, needs: d } => {
                (Some(*command), Some(*d), None)
            }
            Self::Target { command, why } => (Some(*command), None, Some(discriminant(why))),
            Self::MissionItem { why, .. } => (None, None, Some(discriminant(why))),
            Self::NoManualControl(d) | Self::CalibrationRunning(d) => (None, Some(*d), None),
            _ => (None, None, None),
        };
        (discriminant(self), command, detail, target)
    }
}

impl From<ArmingDenial> for Denial {
    fn from(d: ArmingDenial) -> Self {
        Self::Arming(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_reason_says_the_operators_words() {
        let far = TargetError::TooFar {
            distance_m: 1234.5,
            from: "home",
            limit_m: 1000.0,
            by: "GF_MAX_HOR_DIST",
        };
        let table: [(Denial, &str); 8] = [
            (
                ArmingDenial::Check {
                    check: PreflightCheck::BatteryLow(0.12),
                    more: 2,
                }
                .into(),
                "arming refused: battery low (12 %) (and 2 more)",
            ),
            (
                ArmingDenial::Mission(Box::new(Denial::NoMission)).into(),
                "arming refused: MISSION refused: no mission uploaded",
            ),
            (
                Denial::NoGlobalPosition { command: "orbit" },
                "orbit refused: no global position yet",
            ),
            (
                Denial::OrbitRadius {
                    radius_m: -0.5,
                    min_m: 1.0,
                    max_m: 100.0,
                },
                "orbit refused: radius -0.5 m outside 1..100 m (MC_ORBIT_RAD_MAX)",
            ),
            (
                Denial::Target {
                    command: "reposition",
                    why: far,
                },
                &format!("reposition refused: {far}"),
            ),
            (
                Denial::FailsafeActing(Condition::BatteryCritical),
                &format!(
                    "mode change refused: failsafe in progress ({})",
                    Condition::BatteryCritical
                ),
            ),
            (
                Denial::NoOffboardStream(0.5),
                "OFFBOARD refused: no set-point stream in the last 0.5 s (COM_OF_LOSS_T)",
            ),
            (Denial::Busy, "vehicle busy: try again"),
        ];
        for (d, words) in table {
            assert_eq!(d.to_string(), words);
        }
    }

    #[test]
    fn reasons_are_the_same_with_other_numbers_only() {
        let far = |away_m| Denial::TargetTooFar {
            away_m,
            max_m: 1000.0,
        };
        assert!(far(1200.0).same_reason(&far(1500.0)));
        let not_flying = |command| Denial::NotFlying { command };
        assert!(!not_flying("orbit").same_reason(&not_flying("reposition")));
        assert!(!far(1200.0).same_reason(&not_flying("orbit")));
    }
}
