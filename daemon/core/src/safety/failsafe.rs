//! The failsafe state machine, as PX4's framework. Each [`Condition`] has a rule: its [`FailsafeAction`]
//! (from a parameter), when it clears (when the condition goes away, or only at disarm), and
//! whether the operator may take over with a mode change. Several at once: the most severe
//! action wins. An action the vehicle cannot fly is degraded (Return without a home or a
//! position: Land; Hold or Land without a position: Descend, the level descent on the altitude
//! alone); on the ground, anything that would bring the vehicle down disarms instead. The
//! ground-station link loss holds first for `COM_FAIL_ACT_T` seconds, waiting for the link to
//! return, as PX4 does. A flight termination is latched until the daemon restarts.

use std::fmt;

/// What a failsafe does, in increasing severity (PX4's order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FailsafeAction {
    /// Nothing.
    None,
    /// A warning to the operator, flight unchanged.
    Warn,
    /// Hold (Loiter) where the vehicle is.
    Hold,
    /// Return to launch and land there.
    Return,
    /// Land where the vehicle is.
    Land,
    /// Level descent on the altitude estimate alone, without a position (PX4's Descend).
    Descend,
    /// Motors off.
    Disarm,
    /// Motors off, and no re-arming until the daemon restarts.
    Terminate,
}

impl FailsafeAction {
    /// Its name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Warn => "warning",
            Self::Hold => "Hold",
            Self::Return => "Return",
            Self::Land => "Land",
            Self::Descend => "Descend",
            Self::Disarm => "disarm",
            Self::Terminate => "flight termination",
        }
    }

    /// `NAV_DLL_ACT` (PX4's values): 0 no action (the loss and the return still said, as PX4
    /// does), 1 Hold, 2 Return, 3 Land, 5 terminate, 6 disarm.
    pub fn from_nav_dll_act(v: u32) -> Self {
        match v {
            1 => Self::Hold,
            2 => Self::Return,
            3 => Self::Land,
            5 => Self::Terminate,
            6 => Self::Disarm,
            _ => Self::Warn,
        }
    }

    /// `GF_ACTION` (PX4's values): 0 none, 1 warning, 2 Hold, 3 Return, 4 terminate, 5 Land.
    pub fn from_gf_action(v: u32) -> Self {
        match v {
            1 => Self::Warn,
            2 => Self::Hold,
            3 => Self::Return,
            4 => Self::Terminate,
            5 => Self::Land,
            _ => Self::None,
        }
    }
}

/// What can go wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Condition {
    /// No ground-station heartbeat for `COM_DL_LOSS_T` (after one was seen).
    GcsLinkLost,
    /// Battery below `BAT_LOW_THR`.
    BatteryLow,
    /// Battery below `BAT_CRIT_THR`.
    BatteryCritical,
    /// Battery below `BAT_EMERGEN_THR`.
    BatteryEmergency,
    /// Outside the geofence (a polygon or circle, `GF_MAX_HOR_DIST`, `GF_MAX_VER_DIST`).
    GeofenceBreach,
    /// The attitude estimate is invalid.
    AttitudeInvalid,
    /// The horizontal position estimate is invalid in a mode that needs it.
    PositionInvalid,
    /// The altitude estimate is invalid.
    AltitudeInvalid,
    /// The IMU stopped or froze.
    ImuLost,
    /// The magnetometer stopped or froze.
    MagLost,
    /// The barometer stopped or froze.
    BaroLost,
    /// The GPS stopped or lost its fix.
    GpsLost,
    /// Roll or pitch beyond `FD_FAIL_R`/`FD_FAIL_P` for `FD_FAIL_R_TTRI`: crashed or flipping.
    Crash,
    /// A motor was declared failed.
    MotorFailure,
}

/// Every condition, in order.
pub const CONDITIONS: [Condition; 14] = [
    Condition::GcsLinkLost,
    Condition::BatteryLow,
    Condition::BatteryCritical,
    Condition::BatteryEmergency,
    Condition::GeofenceBreach,
    Condition::AttitudeInvalid,
    Condition::PositionInvalid,
    Condition::AltitudeInvalid,
    Condition::ImuLost,
    Condition::MagLost,
    Condition::BaroLost,
    Condition::GpsLost,
    Condition::Crash,
    Condition::MotorFailure,
];

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::GcsLinkLost => "ground-station link lost",
            Self::BatteryLow => "battery low",
            Self::BatteryCritical => "battery critical",
            Self::BatteryEmergency => "battery emergency",
            Self::GeofenceBreach => "geofence breached",
            Self::AttitudeInvalid => "attitude estimate invalid",
            Self::PositionInvalid => "position estimate invalid",
            Self::AltitudeInvalid => "altitude estimate invalid",
            Self::ImuLost => "IMU lost",
            Self::MagLost => "magnetometer lost",
            Self::BaroLost => "barometer lost",
            Self::GpsLost => "GPS lost",
            Self::Crash => "attitude failure (crash or flip)",
            Self::MotorFailure => "motor failure",
        })
    }
}

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

/// Which sensors are missing, stale or frozen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SensorsLost {
    /// Gyroscope and accelerometer.
    pub imu: bool,
    /// Magnetometer.
    pub mag: bool,
    /// Barometer.
    pub baro: bool,
    /// GPS (no solution, or no 3D fix).
    pub gps: bool,
}

/// What the failsafe state machine watches, each step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyInput {
    /// Time (s; the flight's clock).
    pub t_s: f64,
    /// Motors armed.
    pub armed: bool,
    /// Flying (not on the ground).
    pub in_air: bool,
    /// The current mode flies on the position estimate.
    pub mode_needs_position: bool,
    /// Wall-clock time since the last ground-station heartbeat (s); `None` before the first.
    pub gcs_link_age_s: Option<f64>,
    /// Battery charge left (fraction), if known.
    pub battery_remaining: Option<f64>,
    /// Outside the geofence.
    pub geofence_breached: bool,
    /// Attitude estimate valid.
    pub attitude_valid: bool,
    /// Horizontal position estimate valid.
    pub position_valid: bool,
    /// Altitude estimate valid.
    pub altitude_valid: bool,
    /// Sensors lost.
    pub sensors_lost: SensorsLost,
    /// Roll and pitch (rad).
    pub roll_pitch_rad: (f64, f64),
    /// A home position is set (Return can fly).
    pub home_set: bool,
    /// A motor was declared failed.
    pub motor_failed: bool,
    /// A quad flies on its other three rotors, spinning: at least Land.
    pub spinning: bool,
}

/// A change the operator should hear of (`STATUSTEXT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SafetyEvent {
    /// The condition began, acting with this action (after degradation).
    Triggered(Condition, FailsafeAction),
    /// The condition is over.
    Cleared(Condition),
    /// A delayed action's hold is over: the action begins.
    Escalated(Condition, FailsafeAction),
}

impl fmt::Display for SafetyEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Triggered(c, FailsafeAction::Warn | FailsafeAction::None) => write!(f, "{c}"),
            Self::Triggered(c, a) => write!(f, "failsafe: {c}: {}", a.name()),
            Self::Cleared(Condition::GcsLinkLost) => write!(f, "ground-station link regained"),
            Self::Cleared(c) => write!(f, "failsafe over: {c}"),
            Self::Escalated(c, a) => write!(f, "failsafe: {c}: {} now", a.name()),
        }
    }
}

/// The last [`SafetyLog::LEN`] safety events, numbered. A reader of status snapshots taken
/// now and then (a ground-station link) says each once, however short-lived its condition: a
/// crash disarms within a step, and a snapshot of the acting failsafe would never show it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SafetyLog {
    /// Events ever logged.
    pub count: u64,
    recent: [Option<SafetyEvent>; SafetyLog::LEN],
}

impl SafetyLog {
    /// Events kept.
    pub const LEN: usize = 16;

    /// Logs `e` as number `count`.
    pub fn push(&mut self, e: SafetyEvent) {
        self.recent[(self.count % Self::LEN as u64) as usize] = Some(e);
        self.count += 1;
    }

    /// The events from number `seen` on, oldest first, and how many of those are no longer
    /// kept. A `seen` beyond `count` (a log started anew) reads from the start.
    pub fn since(&self, seen: u64) -> (u64, impl Iterator<Item = SafetyEvent> + '_) {
        let seen = if seen > self.count { 0 } else { seen };
        let first = seen.max(self.count.saturating_sub(Self::LEN as u64));
        let kept = (first..self.count).filter_map(|n| self.recent[(n % Self::LEN as u64) as usize]);
        (first - seen, kept)
    }
}

/// What the machine decided this step.
#[derive(Debug, Clone, PartialEq)]
pub struct SafetyDecision {
    /// What the vehicle must do now (`FailsafeAction::None`: fly as the operator asked).
    pub action: FailsafeAction,
    /// The condition behind it.
    pub cause: Option<Condition>,
    /// What changed, for the operator.
    pub events: Vec<SafetyEvent>,
}

/// One condition's state.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Tracked {
    /// Triggered at this time (s), and acting.
    since_s: Option<f64>,
    /// The operator took over: silent until it clears.
    overridden: bool,
    /// A delayed action's hold is over.
    escalated: bool,
}

/// The failsafe state machine.
#[derive(Debug, Clone, PartialEq)]
pub struct Safety {
    params: SafetyParams,
    tracked: [Tracked; CONDITIONS.len()],
    /// When the attitude went beyond the failure limit (s).
    tilted_since_s: Option<f64>,
    /// A flight termination happened: no arming until restart.
    terminated: bool,
    /// The last update's quad was spinning on three rotors.
    spinning: bool,
}

impl Safety {
    /// A machine with nothing triggered.
    pub fn new(params: SafetyParams) -> Self {
        Self {
            params,
            tracked: [Tracked::default(); CONDITIONS.len()],
            tilted_since_s: None,
            terminated: false,
            spinning: false,
        }
    }

    /// New parameters (the triggered conditions stay).
    pub fn set_params(&mut self, params: SafetyParams) {
        self.params = params;
    }

    /// The parameters.
    pub fn params(&self) -> &SafetyParams {
        &self.params
    }

    /// A flight termination happened (arming refused until restart).
    pub fn terminated(&self) -> bool {
        self.terminated
    }

    /// The conditions acting now (triggered, not overridden).
    pub fn active(&self) -> Vec<Condition> {
        let mask = self.active_mask();
        CONDITIONS
            .iter()
            .enumerate()
            .filter(|(k, _)| mask & 1 << k != 0)
            .map(|(_, c)| *c)
            .collect()
    }

    /// [`Safety::active`] as a bit mask (bit k: `CONDITIONS[k]`), without allocating.
    pub fn active_mask(&self) -> u32 {
        CONDITIONS
            .iter()
            .zip(&self.tracked)
            .enumerate()
            .filter(|(_, (_, t))| t.since_s.is_some() && !t.overridden)
            .fold(0, |m, (k, _)| m | 1 << k)
    }

    /// The operator asks for a mode change while failsafes act. Refused (with the reason) while
    /// a condition that allows no take-over acts; otherwise the acting conditions are overridden
    /// (silent until they clear and trigger anew). The refusal names the condition.
    pub fn take_over(&mut self) -> Result<(), Condition> {
        if let Some(c) = self.active().into_iter().find(|&c| {
            let rule = self.params.rule(c, self.spinning);
            !rule.takeover && rule.action > FailsafeAction::Warn
        }) {
            return Err(c);
        }
        for t in self.tracked.iter_mut().filter(|t| t.since_s.is_some()) {
            t.overridden = true;
        }
        Ok(())
    }

    /// Which conditions hold now.
    fn conditions_now(&mut self, i: &SafetyInput) -> [bool; CONDITIONS.len()] {
        let p = &self.params;
        let battery = |level: f64| i.battery_remaining.is_some_and(|r| r < level);
        let (roll, pitch) = i.roll_pitch_rad;
        let beyond =
            |angle: f64, limit_deg: f64| limit_deg > 0.0 && angle.abs() > limit_deg.to_radians();
        let tilted = i.armed && (beyond(roll, p.fail_roll_deg) || beyond(pitch, p.fail_pitch_deg));
        if !tilted {
            self.tilted_since_s = None;
        } else if self.tilted_since_s.is_none() {
            self.tilted_since_s = Some(i.t_s);
        }
        let crashed = self
            .tilted_since_s
            .is_some_and(|s| i.t_s - s >= p.fail_time_s);
        let mut now = [false; CONDITIONS.len()];
        for (k, c) in CONDITIONS.iter().enumerate() {
            now[k] = match c {
                Condition::GcsLinkLost => i.gcs_link_age_s.is_some_and(|a| a > p.gcs_loss_s),
                Condition::BatteryLow => battery(p.battery_low),
                Condition::BatteryCritical => battery(p.battery_critical),
                Condition::BatteryEmergency => battery(p.battery_emergency),
                Condition::GeofenceBreach => i.geofence_breached,
                Condition::AttitudeInvalid => !i.attitude_valid,
                Condition::PositionInvalid => i.mode_needs_position && !i.position_valid,
                Condition::AltitudeInvalid => !i.altitude_valid,
                Condition::ImuLost => i.sensors_lost.imu,
                Condition::MagLost => i.sensors_lost.mag,
                Condition::BaroLost => i.sensors_lost.baro,
                Condition::GpsLost => i.sensors_lost.gps,
                Condition::Crash => crashed,
                Condition::MotorFailure => i.motor_failed,
            };
        }
        now
    }

    /// What the vehicle can fly instead of `a` with what it knows now.
    fn degrade(a: FailsafeAction, i: &SafetyInput) -> FailsafeAction {
        let mut a = a;
        if a == FailsafeAction::Return && !(i.home_set && i.position_valid && i.altitude_valid) {
            a = FailsafeAction::Land;
        }
        if matches!(a, FailsafeAction::Hold | FailsafeAction::Land)
            && !(i.position_valid && i.altitude_valid)
        {
            a = FailsafeAction::Descend;
        }
        if !i.in_air
            && matches!(
                a,
                FailsafeAction::Return | FailsafeAction::Land | FailsafeAction::Descend
            )
        {
            // On the ground already: stop the motors.
            a = FailsafeAction::Disarm;
        }
        a
    }

    /// One step: conditions tracked, the action decided.
    pub fn update(&mut self, i: &SafetyInput) -> SafetyDecision {
        self.spinning = i.spinning;
        let now = self.conditions_now(i);
        let mut events = Vec::new();
        let (mut action, mut cause) = (FailsafeAction::None, None);
        for (k, &c) in CONDITIONS.iter().enumerate() {
            let rule = self.params.rule(c, i.spinning);
            let t = &mut self.tracked[k];
            // Clearing.
            if t.since_s.is_some() {
                let clears = match rule.clear {
                    Clear::WhenConditionClears => !now[k],
                    Clear::OnDisarm => !i.armed && !now[k],
                };
                if clears {
                    *t = Tracked::default();
                    events.push(SafetyEvent::Cleared(c));
                    continue;
                }
            }
            if !now[k] && t.since_s.is_none() {
                continue;
            }
            // Triggering: only armed, except the warnings (a low battery on the ground is news).
            if t.since_s.is_none() {
                if rule.action == FailsafeAction::None
                    || (!i.armed && rule.action > FailsafeAction::Warn)
                {
                    continue;
                }
                t.since_s = Some(i.t_s);
                let first = if rule.delayed && self.params.action_delay_s > 0.0 {
                    FailsafeAction::Hold.min(rule.action)
                } else {
                    rule.action
                };
                events.push(SafetyEvent::Triggered(c, Self::degrade(first, i)));
            }
            if t.overridden {
                continue;
            }
            let since = t.since_s.unwrap_or(i.t_s);
            let mut a = rule.action;
            if rule.delayed && i.t_s - since < self.params.action_delay_s {
                a = a.min(FailsafeAction::Hold);
            } else if rule.delayed && a > FailsafeAction::Hold && !t.escalated {
                t.escalated = true;
                if self.params.action_delay_s > 0.0 {
                    events.push(SafetyEvent::Escalated(c, Self::degrade(a, i)));
                }
            }
            if a > action {
                action = a;
                cause = Some(c);
            }
        }
        let action = if action > FailsafeAction::Warn && i.armed {
            Self::degrade(action, i)
        } else {
            action.min(FailsafeAction::Warn)
        };
        if action == FailsafeAction::Terminate {
            self.terminated = true;
        }
        SafetyDecision {
            action,
            cause,
            events,
        }
    }
}
