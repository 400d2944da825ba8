//! How each failsafe condition is handled: its rule (action, when it clears, whether the
//! operator may take over, whether it waits first) from the failsafe parameters, PX4's names
//! and values.

use super::{Condition, FailsafeAction};

/// When a triggered condition stops acting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clear {
    /// As soon as the condition goes away (the vehicle stays in the mode it was put in).
    WhenConditionClears,
    /// At disarm only (a battery level, once reached, is not un-reached).
    OnDisarm,
}

/// How one condition is handled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rule {
    /// What it does.
    pub action: FailsafeAction,
    /// When it stops.
    pub clear: Clear,
    /// The operator may take over with a mode change (which silences it until it clears).
    pub takeover: bool,
    /// Hold first for `COM_FAIL_ACT_T` before the action (waiting for the condition to clear).
    pub delayed: bool,
}

crate::params::param_group! {
    /// Failsafe and arming-check parameters, PX4's names and values.
    SafetyParams, "safety", SAFETY_META {
        /// Ground-station link loss time (s).
        gcs_loss_s: f64 = 5.0, "COM_DL_LOSS_T", "s", [1.0, 300.0], "Ground-station link lost after this long without its heartbeat (wall-clock time)";
        /// Ground-station link loss action.
        gcs_loss_action: u32 = 0, "NAV_DLL_ACT", "", [0.0, 6.0], "Ground-station link loss: 0 warn only, 1 Hold, 2 Return, 3 Land, 5 terminate, 6 disarm";
        /// Hold before a delayed failsafe action (s).
        action_delay_s: f64 = 5.0, "COM_FAIL_ACT_T", "s", [0.0, 25.0], "Hold this long before a link-loss action, waiting for the link";
        /// Battery failsafe action.
        low_battery_action: u32 = 3, "COM_LOW_BAT_ACT", "", [0.0, 4.0], "Battery: 0 warn, 2 Land at critical, 3 Return at critical and Land at emergency, 4 Return at critical and terminate at emergency";
        /// Low battery level (fraction).
        battery_low: f64 = 0.15, "BAT_LOW_THR", "", [0.12, 0.5], "Battery level that warns (fraction of capacity)";
        /// Critical battery level (fraction).
        battery_critical: f64 = 0.07, "BAT_CRIT_THR", "", [0.05, 0.5], "Battery level of the critical action (fraction of capacity)";
        /// Emergency battery level (fraction).
        battery_emergency: f64 = 0.05, "BAT_EMERGEN_THR", "", [0.03, 0.5], "Battery level of the emergency action (fraction of capacity)";
        /// Lowest battery level to arm (fraction).
        arm_battery_min: f64 = 0.0, "COM_ARM_BAT_MIN", "", [0.0, 0.9], "Arming refused below this battery level (fraction; 0: the low level)";
        /// Geofence action.
        geofence_action: u32 = 2, "GF_ACTION", "", [0.0, 5.0], "Geofence breach: 0 none, 1 warning, 2 Hold, 3 Return, 4 terminate, 5 Land";
        /// Largest horizontal distance from home (m; 0: no limit).
        fence_max_horizontal_m: f64 = 0.0, "GF_MAX_HOR_DIST", "m", [0.0, 10000.0], "Largest horizontal distance from home (0: no limit)";
        /// Largest height above home (m; 0: no limit).
        fence_max_vertical_m: f64 = 0.0, "GF_MAX_VER_DIST", "m", [0.0, 10000.0], "Largest height above home (0: no limit)";
        /// Highest target above home (m; 0 or negative: only the geofence and the hard ceiling).
        max_altitude_m: f64 = 500.0, "LNDMC_ALT_MAX", "m", [-1.0, 10000.0], "Highest altitude above home a command or mission may send the vehicle to (0 or negative: only GF_MAX_VER_DIST and 10 km; manual modes are not limited)";
        /// Roll beyond which the vehicle has failed (deg; 0: off).
        fail_roll_deg: f64 = 60.0, "FD_FAIL_R", "deg", [0.0, 180.0], "Roll beyond which the vehicle has crashed or is flipping: disarm (0: off)";
        /// Pitch beyond which the vehicle has failed (deg; 0: off).
        fail_pitch_deg: f64 = 60.0, "FD_FAIL_P", "deg", [0.0, 180.0], "Pitch beyond which the vehicle has crashed or is flipping: disarm (0: off)";
        /// How long beyond the limit before the failure (s).
        fail_time_s: f64 = 0.3, "FD_FAIL_R_TTRI", "s", [0.02, 5.0], "Time beyond FD_FAIL_R or FD_FAIL_P before the failure is declared";
        /// Magnetometer strength tolerance at arming (gauss; 0: off).
        mag_strength_tolerance_gauss: f64 = 0.2, "EKF2_MAG_CHK_STR", "gauss", [0.0, 1.0], "Arming refused when the field measured at rest differs more from ATT_MAG_STR (0: off)";
        /// Magnetometer inclination tolerance at arming (deg; 0: off).
        mag_inclination_tolerance_deg: f64 = 20.0, "EKF2_MAG_CHK_INC", "deg", [0.0, 90.0], "Arming refused when the field's inclination at rest differs more from ATT_MAG_INC (0: off)";
        /// Largest tilt to arm (deg).
        arm_tilt_deg: f64 = 20.0, "COM_ARM_TILT", "deg", [5.0, 90.0], "Arming refused beyond this tilt";
        /// Motor-failure detection on (1) or off (0).
        motor_failure_detection: u32 = 1, "FD_ACT_EN", "", [0.0, 1.0], "Motor-failure detection (rotor speed and thrust imbalance): 1 on, 0 off";
        /// Time a motor must look failed before it is declared (ms).
        motor_failure_timeout_ms: u32 = 100, "FD_ACT_MOT_TOUT", "ms", [10.0, 2000.0], "A motor must look failed this long before the failure is declared (sooner: its own low speed on two ESC readings; a quad's stopping rotor held 8 ms, about 0.04 s after it stops)";
        /// Re-allocation on a motor failure.
        motor_failure_mode: u32 = 1, "CA_FAILURE_MODE", "", [0.0, 1.0], "On a motor failure: 1 fly on without the failed rotor (re-allocated, yaw given up first when needed; a quad spins on its other three under reduced-attitude control and lands), 0 keep the allocation";
        /// Motor-failure action.
        motor_failure_action: u32 = 0, "COM_ACT_FAIL_ACT", "", [0.0, 4.0], "Motor failure: 0 warn and continue, 1 Hold, 2 Land, 3 Return, 4 terminate (a quad spinning on three rotors lands at least)";
        /// Failure injection allowed.
        failure_injection: u32 = 0, "SYS_FAILURE_EN", "", [0.0, 1.0], "Allow MAV_CMD_INJECT_FAILURE (simulation and bench tests): 1 allowed, 0 refused";
    }
}

impl SafetyParams {
    /// The rule of `c` under these parameters, for a quad `spinning` on three rotors or not.
    pub fn rule(&self, c: Condition, spinning: bool) -> Rule {
        use Condition as C;
        let (action, clear, takeover, delayed) = match c {
            C::GcsLinkLost => (
                FailsafeAction::from_nav_dll_act(self.gcs_loss_action),
                Clear::WhenConditionClears,
                true,
                true,
            ),
            C::BatteryLow => (FailsafeAction::Warn, Clear::OnDisarm, true, false),
            C::BatteryCritical => {
                let a = match self.low_battery_action {
                    2 => FailsafeAction::Land,
                    3 | 4 => FailsafeAction::Return,
                    _ => FailsafeAction::Warn,
                };
                (a, Clear::OnDisarm, true, false)
            }
            C::BatteryEmergency => {
                let a = match self.low_battery_action {
                    2 | 3 => FailsafeAction::Land,
                    4 => FailsafeAction::Terminate,
                    _ => FailsafeAction::Warn,
                };
                (a, Clear::OnDisarm, false, false)
            }
            C::GeofenceBreach => (
                FailsafeAction::from_gf_action(self.geofence_action),
                Clear::WhenConditionClears,
                true,
                false,
            ),
            C::AttitudeInvalid | C::AltitudeInvalid => {
                (FailsafeAction::Descend, Clear::OnDisarm, false, false)
            }
            // Without a position the vehicle descends; a mode that needs none (the sticks
            // flying attitude or altitude) is the operator's way out.
            C::PositionInvalid => (
                FailsafeAction::Descend,
                Clear::WhenConditionClears,
                true,
                false,
            ),
            // What a lost sensor costs shows in the estimate's validity; the loss itself warns.
            C::ImuLost | C::MagLost | C::BaroLost | C::GpsLost => (
                FailsafeAction::Warn,
                Clear::WhenConditionClears,
                true,
                false,
            ),
            C::Crash => (FailsafeAction::Disarm, Clear::OnDisarm, false, false),
            C::MotorFailure => {
                let a = match self.motor_failure_action {
                    1 => FailsafeAction::Hold,
                    2 => FailsafeAction::Land,
                    3 => FailsafeAction::Return,
                    4 => FailsafeAction::Terminate,
                    _ => FailsafeAction::Warn,
                };
                // A quad spinning on three rotors flies on no margin: it lands (or returns, if
                // asked), whatever the action for other airframes.
                let a = if spinning && a < FailsafeAction::Return {
                    FailsafeAction::Land
                } else {
                    a
                };
                (a, Clear::OnDisarm, true, false)
            }
        };
        Rule {
            action,
            clear,
            takeover,
            delayed,
        }
    }

    /// Values that make no sense together (the levels out of order).
    pub fn inconsistencies(&self) -> Vec<String> {
        let mut v = Vec::new();
        if !(self.battery_low > self.battery_critical
            && self.battery_critical > self.battery_emergency)
        {
            v.push(format!(
                "BAT_LOW_THR {} > BAT_CRIT_THR {} > BAT_EMERGEN_THR {} is required",
                self.battery_low, self.battery_critical, self.battery_emergency
            ));
        }
        v
    }
}
