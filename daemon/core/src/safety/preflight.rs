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

/// One reason not to arm.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PreflightFailure {
    /// For the operator (`STATUSTEXT`, `COMMAND_ACK`).
    pub text: String,
    /// A forced arm may skip it.
    pub skippable: bool,
}

/// Every reason not to arm, in order of importance. A forced arm may skip the estimator's
/// convergence, the magnetometer's state, the battery above its emergency level and the
/// geofence; never a missing IMU, a failed motor, a tilt beyond `COM_ARM_TILT`, an
/// emergency-level battery or a terminated flight.
pub fn preflight(i: &PreflightInput, p: &SafetyParams) -> Vec<PreflightFailure> {
    let mut v = Vec::new();
    let mut fail = |text: String, skippable: bool| v.push(PreflightFailure { text, skippable });
    if i.terminated {
        fail("flight terminated: restart the autopilot".into(), false);
    }
    if i.sensors_lost.imu {
        fail("IMU missing or frozen".into(), false);
    }
    if let Some(m) = i.motor_failed {
        fail(format!("motor {m} failed"), false);
    }
    let (roll, pitch) = i.roll_pitch_rad;
    let tilt = (roll.cos() * pitch.cos()).clamp(-1.0, 1.0).acos();
    if i.attitude_valid && tilt > p.arm_tilt_deg.to_radians() {
        fail(
            format!(
                "tilted {:.0}° (COM_ARM_TILT {:.0}°)",
                tilt.to_degrees(),
                p.arm_tilt_deg
            ),
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
            fail(
                format!("battery at emergency level ({:.0} %)", r * 100.0),
                false,
            );
        } else if r < min {
            fail(format!("battery low ({:.0} %)", r * 100.0), true);
        }
    }
    if let Some(why) = &i.params_invalid {
        fail(format!("parameters invalid: {why}"), false);
    }
    if !i.attitude_valid {
        fail("attitude estimate not converged".into(), true);
    } else if !i.gyro_bias_settled {
        fail(
            "gyro bias not settled: keep the vehicle still for 2 s".into(),
            true,
        );
    }
    if i.mode_needs_position && !i.position_valid {
        fail(
            "position estimate not valid (the mode needs it)".into(),
            true,
        );
    }
    if !i.altitude_valid {
        fail("altitude estimate not valid".into(), true);
    }
    for (lost, name) in [
        (i.sensors_lost.mag, "magnetometer"),
        (i.sensors_lost.baro, "barometer"),
        (i.sensors_lost.gps && i.mode_needs_position, "GPS"),
    ] {
        if lost {
            fail(format!("{name} silent or frozen"), true);
        }
    }
    if !i.mag.calibrated {
        fail("magnetometer not calibrated".into(), true);
    }
    if let Some(m) = i.mag.measured.filter(|_| !i.sensors_lost.mag) {
        let e = i.mag.expected;
        // EKF2_MAG_CHK_STR and EKF2_MAG_CHK_INC (0: off).
        let checks = [
            (
                m.strength_gauss,
                e.strength_gauss,
                p.mag_strength_tolerance_gauss,
                "field",
                " G",
                2,
            ),
            (
                m.inclination_deg,
                e.inclination_deg,
                p.mag_inclination_tolerance_deg,
                "inclination",
                "°",
                0,
            ),
        ];
        for (got, want, tol, what, unit, digits) in checks {
            if tol > 0.0 && (got - want).abs() > tol {
                fail(
                    format!("mag {what} {got:.digits$}{unit}, expected {want:.digits$}{unit}"),
                    true,
                );
            }
        }
    }
    if i.geofence_breached {
        fail("outside the geofence".into(), true);
    }
    v
}
