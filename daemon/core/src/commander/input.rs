//! What the commander is given: the estimate and the vehicle's health on every update, the
//! sticks of a joystick and the set-points of an offboard stream between updates.

use crate::control::Setpoint;
use crate::math::geo::LatLonAlt;
use crate::safety::failsafe::SensorsLost;
use nalgebra::Vector3;

/// Stick positions from a ground station's joystick (`MANUAL_CONTROL`), normalised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sticks {
    /// Pitch stick, forward positive, −1 to 1.
    pub forward: f64,
    /// Roll stick, right positive, −1 to 1.
    pub right: f64,
    /// Throttle stick, 0 (low) to 1 (high); 0.5 is the centre of altitude and position modes.
    pub throttle: f64,
    /// Yaw stick, clockwise positive, −1 to 1.
    pub yaw: f64,
}

impl Sticks {
    /// Centred sticks, throttle at its centre.
    pub const CENTRED: Self = Self {
        forward: 0.0,
        right: 0.0,
        throttle: 0.5,
        yaw: 0.0,
    };

    /// The sticks clamped to their ranges (NaN: centred).
    pub fn clamped(self) -> Self {
        let c = |x: f64, lo: f64, hi: f64, centre: f64| {
            if x.is_nan() { centre } else { x.clamp(lo, hi) }
        };
        Self {
            forward: c(self.forward, -1.0, 1.0, 0.0),
            right: c(self.right, -1.0, 1.0, 0.0),
            throttle: c(self.throttle, 0.0, 1.0, 0.5),
            yaw: c(self.yaw, -1.0, 1.0, 0.0),
        }
    }
}

/// The estimate the commander watches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommanderInput {
    /// Time (s).
    pub t_s: f64,
    /// The estimator can be flown on (attitude and position valid).
    pub ready: bool,
    /// The horizontal estimate is valid (GPS fresh): a descent without a full estimate then
    /// brakes to a stop over the ground instead of only levelling.
    pub horizontal_valid: bool,
    /// Estimated position NED (m).
    pub pos_ned_m: Vector3<f64>,
    /// Estimated velocity NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Estimated heading (rad).
    pub yaw_rad: f64,
    /// Thrust that holds the vehicle up, as a fraction of its full thrust (PX4's
    /// `MPC_THR_HOVER`): the centre of the throttle stick in the stick-to-attitude modes.
    pub hover_thrust: f64,
    /// The thrust the rotors were last told, as the same fraction.
    pub thrust: f64,
    /// The IMU alone shows the vehicle still, whatever the estimate (see
    /// [`crate::estimator::attitude::AttitudeEstimate::imu_still`]).
    pub imu_still: bool,
    /// The estimate's local origin (where NED is anchored), once the GPS has set it: what
    /// mission coordinates are resolved against.
    pub origin: Option<LatLonAlt>,
    /// What else the failsafes and arming checks watch.
    pub health: Health,
}

/// The vehicle's health beyond the position estimate: what the failsafes and arming checks
/// watch ([`crate::safety`]). The default is a healthy vehicle that knows nothing of its link
/// or battery.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Health {
    /// Attitude estimate valid.
    pub attitude_valid: bool,
    /// The gyro bias is known well enough to take off.
    pub gyro_bias_settled: bool,
    /// Altitude estimate valid.
    pub altitude_valid: bool,
    /// Wall-clock time since the last ground-station heartbeat (s); `None` before the first.
    pub gcs_link_age_s: Option<f64>,
    /// Battery charge left (fraction), if known.
    pub battery_remaining: Option<f64>,
    /// Outside the geofence.
    pub geofence_breached: bool,
    /// Sensors missing, stale or frozen.
    pub sensors_lost: SensorsLost,
    /// Estimated roll and pitch (rad).
    pub roll_pitch_rad: (f64, f64),
    /// A motor marked failed (1-based), if any.
    pub motor_failed: Option<usize>,
    /// A quad flying on its other three rotors, spinning (the reduced-attitude controller).
    pub spinning: bool,
    /// The magnetometer's calibration and the field it measures.
    pub mag: crate::sensors::mag_check::MagStatus,
}

impl Default for Health {
    fn default() -> Self {
        Self {
            attitude_valid: true,
            gyro_bias_settled: true,
            altitude_valid: true,
            gcs_link_age_s: None,
            battery_remaining: None,
            geofence_breached: false,
            sensors_lost: SensorsLost::default(),
            roll_pitch_rad: (0.0, 0.0),
            motor_failed: None,
            spinning: false,
            mag: crate::sensors::mag_check::MagStatus::default(),
        }
    }
}

/// A set-point streamed in Offboard (`SET_POSITION_TARGET_*`, `SET_ATTITUDE_TARGET`), already in
/// the local NED frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffboardTarget {
    /// What to fly. A position set-point's NaN yaw holds the heading (or turns it at
    /// `yaw_rate_rad_s`); an attitude target's NaN thrust is hover thrust.
    pub setpoint: Setpoint,
    /// Yaw rate (rad/s, clockwise) for a position set-point without a yaw.
    pub yaw_rate_rad_s: Option<f64>,
}
