//! The arming checks: every reason not to arm, each marked whether a forced arm
//! (`MAV_CMD_COMPONENT_ARM_DISARM` param2 = 21196) may skip it.

use super::failsafe::{SafetyParams, SensorsLost};
use crate::sensors::mag_check::MagStatus;

/// What the arming checks look at.
#[derive(Debug, Clone, PartialEq)]
pub struct PreflightInput {
    /// Attitude estimate valid (converged).
    pub attitude_valid: bool,
    /// The gyro bias is known well enough to take off.
    pub gyro_bias_settled: bool,
    /// Horizontal position estimate valid.
    pub position_valid: bool,
    /// Altitude estimate valid.
    pub altitude_valid: bool,
    /// The mode to arm in flies on the position estimate.
    pub mode_needs_position: bool,
    /// Sensors missing, stale or frozen.
    pub sensors_lost: SensorsLost,
    /// The magnetometer's calibration and the field it measures at rest.
    pub mag: MagStatus,
    /// Battery charge left (fraction), if known.
    pub battery_remaining: Option<f64>,
    /// What is wrong with the parameters, if anything.
    pub params_invalid: Option<String>,
    /// Roll and pitch (rad).
    pub roll_pitch_rad: (f64, f64),
    /// Outside the geofence.
    pub geofence_breached: bool,
    /// A motor marked failed (1-based), if any.
    pub motor_failed: Option<usize>,
    /// A flight termination happened.
    pub terminated: bool,
}

/// One arming check that fails; `Display` gives its words for the operator.
#[derive(Debug, Clone, PartialEq)]
pub enum PreflightCheck {
    /// A flight termination happened.
    Terminated,
    /// The IMU is missing or frozen.
    ImuLost,
    /// A motor (1-based) is marked failed.
    MotorFailed(usize),
    /// Tilted beyond `COM_ARM_TILT`.
    Tilted {
        /// The tilt (deg).
        tilt_deg: f64,
        /// `COM_ARM_TILT` (deg).
        limit_deg: f64,
    },
    /// The battery is at its emergency level (charge left, fraction).
    BatteryEmergency(f64),
    /// The battery is below the level to arm at (charge left, fraction).
    BatteryLow(f64),
    /// The parameters contradict each other.
    ParamsInvalid(String),
    /// The attitude estimate has not converged.
    AttitudeNotConverged,
    /// The gyro bias is not known well enough yet.
    GyroBiasUnsettled,
    /// The mode flies on a position estimate that is not valid.
    PositionInvalid,
    /// The altitude estimate is not valid.
    AltitudeInvalid,
    /// The magnetometer is silent or frozen.
    MagLost,
    /// The barometer is silent or frozen.
    BaroLost,
    /// The GPS is silent or frozen (and the mode needs it).
    GpsLost,
    /// The magnetometer was never calibrated.
    MagUncalibrated,
    /// The field measured at rest is unlike the expected one.
    MagField(MagFieldCheck),
    /// Outside the geofence.
    Geofence,
    /// The estimate cannot be flown on, its parts unknown to the commander.
    EstimatorNotReady,
}

/// Which property of the field at rest is off, and by how much.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MagFieldCheck {
    /// Its strength (gauss) against `EKF2_MAG_CHK_STR`.
    Strength {
        /// Measured (G).
        got: f64,
        /// Expected (G).
        want: f64,
    },
    /// Its inclination (deg) against `EKF2_MAG_CHK_INC`.
    Inclination {
        /// Measured (deg).
        got: f64,
        /// Expected (deg).
        want: f64,
    },
}

impl std::fmt::Display for PreflightCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Terminated => write!(f, "flight terminated: restart the autopilot"),
            Self::ImuLost => write!(f, "IMU missing or frozen"),
            Self::MotorFailed(m) => write!(f, "motor {m} failed"),
            Self::Tilted {
                tilt_deg,
                limit_deg,
            } => write!(f, "tilted {tilt_deg:.0}° (COM_ARM_TILT {limit_deg:.0}°)"),
            Self::BatteryEmergency(r) => {
                write!(f, "battery at emergency level ({:.0} %)", r * 100.0)
            }
            Self::BatteryLow(r) => write!(f, "battery low ({:.0} %)", r * 100.0),
            Self::ParamsInvalid(why) => write!(f, "parameters invalid: {why}"),
            Self::AttitudeNotConverged => write!(f, "attitude estimate not converged"),
            Self::GyroBiasUnsettled => {
                write!(f, "gyro bias not settled: keep the vehicle still for 2 s")
            }
            Self::PositionInvalid => write!(f, "position estimate not valid (the mode needs it)"),
            Self::AltitudeInvalid => write!(f, "altitude estimate not valid"),
            Self::MagLost => write!(f, "magnetometer silent or frozen"),
            Self::BaroLost => write!(f, "barometer silent or frozen"),
            Self::GpsLost => write!(f, "GPS silent or frozen"),
            Self::MagUncalibrated => write!(f, "magnetometer not calibrated"),
            Self::MagField(MagFieldCheck::Strength { got, want }) => {
                write!(f, "mag field {got:.2} G, expected {want:.2} G")
            }
            Self::MagField(MagFieldCheck::Inclination { got, want }) => {
                write!(f, "mag inclination {got:.0}°, expected {want:.0}°")
            }
            Self::Geofence => write!(f, "outside the geofence"),
            Self::EstimatorNotReady => {
                write!(f, "estimator not ready (attitude or position invalid)")
            }
        }
    }
}

/// One reason not to arm.
#[derive(Debug, Clone, PartialEq)]
pub struct PreflightFailure {
    /// The check (its words for the operator: `STATUSTEXT`, `COMMAND_ACK`).
    pub check: PreflightCheck,
    /// A forced arm may skip it.
    pub skippable: bool,
}

/// Every reason not to arm, in order of importance. A forced arm may skip the estimator's
/// convergence, the magnetometer's state, the battery above its emergency level and the
/// geofence; never a missing IMU, a failed motor, a tilt beyond `COM_ARM_TILT`, an
/// emergency-level battery or a terminated flight.
pub fn preflight(i: &PreflightInput, p: &SafetyParams) -> Vec<PreflightFailure> {
    use PreflightCheck as C;
    let mut v = Vec::new();
    let mut fail = |check: PreflightCheck, skippable: bool| {
        v.push(PreflightFailure { check, skippable });
    };
    if i.terminated {
        fail(C::Terminated, false);
    }
    if i.sensors_lost.imu {
        fail(C::ImuLost, false);
    }
    if let Some(m) = i.motor_failed {
        fail(C::MotorFailed(m), false);
    }
    let (roll, pitch) = i.roll_pitch_rad;
    let tilt = (roll.cos() * pitch.cos()).clamp(-1.0, 1.0).acos();
    if i.attitude_valid && tilt > p.arm_tilt_deg.to_radians() {
        let (tilt_deg, limit_deg) = (tilt.to_degrees(), p.arm_tilt_deg);
        fail(
            C::Tilted {
                tilt_deg,
                limit_deg,
            },
            false,
        );
    }
    if let Some(r) = i.battery_remaining {
        let min = if p.arm_battery_min > 0.0 {
            p.arm_battery_min
        } else {
            p.battery_low
        };
        if r < p.battery_emergency {
            fail(C::BatteryEmergency(r), false);
        } else if r < min {
            fail(C::BatteryLow(r), true);
        }
    }
    if let Some(why) = &i.params_invalid {
        fail(C::ParamsInvalid(why.clone()), false);
    }
    if !i.attitude_valid {
        fail(C::AttitudeNotConverged, true);
    } else if !i.gyro_bias_settled {
        fail(C::GyroBiasUnsettled, true);
    }
    if i.mode_needs_position && !i.position_valid {
        fail(C::PositionInvalid, true);
    }
    if !i.altitude_valid {
        fail(C::AltitudeInvalid, true);
    }
    for (lost, check) in [
        (i.sensors_lost.mag, C::MagLost),
        (i.sensors_lost.baro, C::BaroLost),
        (i.sensors_lost.gps && i.mode_needs_position, C::GpsLost),
    ] {
        if lost {
            fail(check, true);
        }
    }
    if !i.mag.calibrated {
        fail(C::MagUncalibrated, true);
    }
    if let Some(m) = i.mag.measured.filter(|_| !i.sensors_lost.mag) {
        let e = i.mag.expected;
        // EKF2_MAG_CHK_STR and EKF2_MAG_CHK_INC (0: off).
        let checks = [
            (
                MagFieldCheck::Strength {
                    got: m.strength_gauss,
                    want: e.strength_gauss,
                },
                m.strength_gauss - e.strength_gauss,
                p.mag_strength_tolerance_gauss,
            ),
            (
                MagFieldCheck::Inclination {
                    got: m.inclination_deg,
                    want: e.inclination_deg,
                },
                m.inclination_deg - e.inclination_deg,
                p.mag_inclination_tolerance_deg,
            ),
        ];
        for (check, off, tol) in checks {
            if tol > 0.0 && off.abs() > tol {
                fail(C::MagField(check), true);
            }
        }
    }
    if i.geofence_breached {
        fail(C::Geofence, true);
    }
    v
}
