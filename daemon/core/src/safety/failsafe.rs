//! The failsafe state machine, as PX4's framework. Each [`Condition`] has a rule: its [`FailsafeAction`]
//! (from a parameter), when it clears (when the condition goes away, or only at disarm), and
//! whether the operator may take over with a mode change. Several at once: the most severe
//! action wins. An action the vehicle cannot fly is degraded (Return without a home or a
//! position: Land; Hold or Land without a position: Descend, the level descent on the altitude
//! alone); on the ground, anything that would bring the vehicle down disarms instead. The
//! ground-station link loss holds first for `COM_FAIL_ACT_T` seconds, waiting for the link to
//! return, as PX4 does. A flight termination is latched until the daemon restarts.

use std::fmt;

mod rules;
pub use rules::{Clear, Rule, SAFETY_META, SafetyParams};

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
