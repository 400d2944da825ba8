//! The tilt/heading filter's settings, from the attitude parameters.

use crate::estimator::bias::BiasSettings;
use crate::estimator::hard_iron::HardIronSettings;
use crate::estimator::heading::HeadingSettings;

/// Settings of the tilt/heading filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltHeadingSettings {
    /// Time constant of the accelerometer's low-pass in the gyro frame (s).
    pub tau_acc_s: f64,
    /// Heading settings.
    pub heading: HeadingSettings,
    /// Time constant of bias learning at rest (s).
    pub bias_tau_rest_s: f64,
    /// Time constant of bias learning in motion, from the corrections (s); 0 switches it off.
    pub bias_tau_motion_s: f64,
    /// Largest bias estimate (rad/s).
    pub bias_limit_rad_s: f64,
    /// Largest body rate at which the bias is learned in motion (rad/s): faster, gyro scale and
    /// axis errors drift the attitude as much as a bias would (PX4's attitude estimator keeps
    /// the same limit).
    pub bias_max_rate_rad_s: f64,
    /// Whether the body-fixed field is learned online.
    pub learn_hard_iron: bool,
    /// Online hard-iron settings.
    pub hard_iron: HardIronSettings,
    /// The field's expected inclination (rad, positive down), until one is learned: it only
    /// chooses between two headings an in-flight alignment finds (`realign.rs`).
    pub mag_inclination_rad: f64,
}

impl Default for TiltHeadingSettings {
    fn default() -> Self {
        Self {
            tau_acc_s: 3.0,
            heading: HeadingSettings::default(),
            bias_tau_rest_s: 3.0,
            bias_tau_motion_s: 10.0,
            bias_limit_rad_s: 0.1,
            bias_max_rate_rad_s: 20f64.to_radians(),
            learn_hard_iron: false,
            hard_iron: HardIronSettings::default(),
            mag_inclination_rad: 63.3f64.to_radians(),
        }
    }
}

impl TiltHeadingSettings {
    /// The bias filter's settings.
    pub fn bias_settings(&self) -> BiasSettings {
        BiasSettings {
            tau_rest_s: self.bias_tau_rest_s,
            tau_motion_s: self.bias_tau_motion_s,
            limit_rad_s: self.bias_limit_rad_s,
            tau_acc_s: self.tau_acc_s,
        }
    }
}
