//! Recovery of the tilt from any error: when the accelerometer's direction can be trusted, the
//! tilt is taken from it at once, not crept towards.
//!
//! The tilt/heading filter turns the specific force, low-passed over `tau_acc` (3 s) in the gyro
//! frame, to the vertical. That rejects a manoeuvre's acceleration, but an error made in one
//! step (a gyro that saturated in a tumble, a bump on landing, a glitch) fades only with the same
//! 3 s: 20° takes 7 s to come within 2°, and a vehicle that hops meanwhile never gets there.
//!
//! Here the same vector is low-passed over 0.2 s beside it, and the vehicle's known
//! acceleration with it. When that fast vector has held its direction in the gyro frame (within
//! 1°) for 0.4 s, its length is gravity's (within 5 %), and it points away from the vertical by
//! more than the limit, the slow low-passes are reset to it: the tilt is the accelerometer's at
//! the next correction. Disarmed, the vehicle's acceleration is taken as zero (it stands or is
//! held; the steadiness rejects a hand's motion). The limit is 2° disarmed and still (the gyro, low-passed the same way, below 1°/s
//! for the last 0.4 s); 5° disarmed when not (a vehicle on its feet rocking in a gusty wind, whose
//! accelerometer is off the vertical by 2–3° as it rocks); 10° armed, where gusts and the
//! velocity's lag make the accelerometer less exact. A steady vector in the gyro frame means no rotation the gyro missed and no
//! acceleration the position estimate did not know: a vehicle at rest, a steady hover, a steady
//! climb.

use super::lowpass::LowPass;
use crate::GRAVITY_M_S2;
use nalgebra::{UnitQuaternion, Vector3};

/// Time constant of the fast low-passes (s).
const FAST_TAU_S: f64 = 0.1;
/// How long the fast vector must hold its direction (s).
const STEADY_S: f64 = 0.4;
/// How far it may turn meanwhile (rad).
const MAX_TURN_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;
/// How far its length may be from gravity's (fraction).
const GRAVITY_TOLERANCE: f64 = 0.05;
/// The tilt error that is reset: disarmed and still, disarmed, armed (rad).
const RESET_STILL_RAD: f64 = 2.0 * std::f64::consts::PI / 180.0;
const RESET_DISARMED_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;
const RESET_ARMED_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;
/// Still: the low-passed rate below this (rad/s).
const STILL_RAD_S: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// A reset the recovery asks for: the values the slow low-passes take.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltReset {
    /// The specific force in the gyro frame (m/s²).
    pub specific_force: Vector3<f64>,
    /// The vehicle's NED acceleration (m/s²; zero when unknown).
    pub accel_ned: Vector3<f64>,
    /// How far the tilt was from it (rad).
    pub error_rad: f64,
}

/// The fast low-passes and the steadiness of the accelerometer's direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltRecovery {
    specific_force: LowPass,
    accel_ned: LowPass,
    rate: LowPass,
    age_s: f64,
    /// The fast vector when the steadiness began, and how long it has held.
    anchor: Vector3<f64>,
    steady_s: f64,
    /// How long the low-passed rate has been below [`STILL_RAD_S`] (s).
    still_s: f64,
}

impl Default for TiltRecovery {
    fn default() -> Self {
        Self {
            specific_force: LowPass::new(FAST_TAU_S),
            accel_ned: LowPass::new(FAST_TAU_S),
            rate: LowPass::new(FAST_TAU_S),
            age_s: 0.0,
            anchor: Vector3::zeros(),
            steady_s: 0.0,
            still_s: 0.0,
        }
    }
}

impl TiltRecovery {
    /// Forgets everything (the filter started again).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// One sample: the specific force in the gyro frame, the vehicle's NED acceleration
    /// (`None` when unknown) and the body rate (bias taken off).
    pub fn update(
        &mut self,
        f_gyro_frame: &Vector3<f64>,
        accel_ned: Option<&Vector3<f64>>,
        rate: &Vector3<f64>,
        dt: f64,
    ) {
        let f = self.specific_force.update(f_gyro_frame, dt);
        let rate = self.rate.update(rate, dt).norm();
        self.still_s = if rate < STILL_RAD_S {
            self.still_s + dt
        } else {
            0.0
        };
        match accel_ned {
            Some(a) => {
                self.accel_ned.update(a, dt);
            }
            None => self.accel_ned.reset_to(Vector3::zeros()),
        }
        self.age_s += dt;
        if self.age_s < 2.0 * FAST_TAU_S {
            return;
        }
        if self.steady_s > 0.0 && f.angle(&self.anchor) <= MAX_TURN_RAD {
            self.steady_s += dt;
        } else {
            self.anchor = f;
            self.steady_s = dt;
        }
    }

    /// The IMU alone shows the vehicle still, whatever the estimate: the rate below 1°/s and the
    /// specific force steady (its direction within 1°) at gravity's length (within 5 %) for the
    /// last 0.4 s. A vehicle on the ground; also a calm hover (thrust tells them apart).
    pub fn still(&self) -> bool {
        let length = self.specific_force.value().norm();
        self.still_s >= STEADY_S
            && self.steady_s >= STEADY_S
            && (length - GRAVITY_M_S2).abs() <= GRAVITY_TOLERANCE * GRAVITY_M_S2
    }

    /// The reset to make now, if any: the tilt `q_tilt` (gyro frame → level) and the heading
    /// `heading` (level → NED) turn the fast vector away from the vertical by more than the
    /// limit for `armed`, and it is steady and gravity's length.
    pub fn check(
        &self,
        q_tilt: &UnitQuaternion<f64>,
        heading: &UnitQuaternion<f64>,
        armed: bool,
    ) -> Option<TiltReset> {
        if self.steady_s < STEADY_S {
            return None;
        }
        let f = self.specific_force.value();
        let still = self.still_s >= STEADY_S;
        // Disarmed, the vehicle stands or is held: the known acceleration, differences of a
        // GPS-corrected velocity, is only the corrections' noise there (a 0.2 m/s GPS makes
        // 2–3° of it through the fast low-pass), and a steady accelerometer is gravity.
        let a = if armed {
            self.accel_ned.value()
        } else {
            Vector3::zeros()
        };
        let v = q_tilt * f - heading.inverse() * a;
        if (v.norm() - GRAVITY_M_S2).abs() > GRAVITY_TOLERANCE * GRAVITY_M_S2 {
            return None;
        }
        let error = v.angle(&Vector3::new(0.0, 0.0, -1.0));
        let limit = if armed {
            RESET_ARMED_RAD
        } else if still {
            RESET_STILL_RAD
        } else {
            RESET_DISARMED_RAD
        };
        (error > limit).then_some(TiltReset {
            specific_force: f,
            accel_ned: a,
            error_rad: error,
        })
    }
}
