//! The commander: arming, flight modes and what each mode flies (PX4's commander and navigator
//! in one pure state machine of time and the estimate).
//!
//! Commands ([`Commander::arm`], [`Commander::set_mode`], [`Commander::takeoff`], …) are answered
//! at once with `Ok` or a denial that says why; [`Commander::update`] then turns the mode into a
//! set-point for the flight core on every sample: a position set-point, or an attitude and thrust
//! in the stick-to-attitude modes.
//!
//! - *Takeoff*: spool up for `spool_s` after arming, climb on a speed- and acceleration-limited
//!   profile to the take-off altitude above home, then *Loiter* there.
//! - *Loiter* (Hold): brake to a stop and hold that point; armed on the ground it stays there.
//! - *Land*: descend where it is (slower for the last metres), touchdown after standing still for
//!   a second, disarm.
//! - *RTL*: climb to the return altitude (if lower), fly home on a limited profile, land there.
//! - *Posctl*, *Altctl* (manual, sticks from `MANUAL_CONTROL`): velocity or tilt from the sticks,
//!   climb rate from the throttle stick around its centre, hold when centred; take-off by
//!   raising the throttle, touchdown and disarm after holding it low on the ground. Sticks
//!   that stop arriving (`COM_RC_LOSS_T`) switch to Hold.
//! - *Stabilized* and *Manual* (the same on a multicopter, as in PX4): the roll and pitch sticks
//!   tilt the vehicle up to `MPC_MAN_TILT_MAX` in the heading's frame, the yaw stick turns it,
//!   the throttle stick sets the collective thrust (its centre is hover thrust); the vehicle
//!   levels itself when the sticks centre but holds neither altitude nor position. Touchdown
//!   and disarm after the throttle has stayed low with the vehicle still for a second.
//! - *Offboard*: the set-points a companion computer or script streams (position, velocity,
//!   acceleration, yaw or yaw rate, or attitude and thrust), entered only while they arrive;
//!   take-off when they ask to go up, touchdown and disarm when they rest it on the ground. A
//!   stream that stops for `COM_OF_LOSS_T` hands over to `COM_OBL_RC_ACT`'s mode.
//! - *Descend* (failsafe): when the estimate stops being fit to fly on, an armed vehicle on the
//!   ground disarms and one in the air levels and descends on what estimate is left, until
//!   touchdown; it is left only by landing.
//!
//! Failsafes (link, battery, geofence, crash, estimator and sensors) are decided by the
//! [`crate::safety`] state machine on every update and carried out here (Hold, Return, Land,
//! Descend, disarm); arming asks its [`crate::safety::preflight::preflight`] checks.

use crate::control::position::PositionSetpoint;
use crate::control::{AttitudeTarget, Setpoint};
use crate::math::geo::LatLonAlt;
use crate::mission::MissionStatus;
use crate::safety::failsafe::{
    Action, Condition, Safety, SafetyEvent, SafetyInput, SafetyParams, SensorsLost,
};
use crate::safety::preflight::PreflightInput;
use mission::{MissionRun, Stage};
use nalgebra::{UnitQuaternion, Vector2, Vector3};
use std::f64::consts::{PI, TAU};

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

crate::params::param_group! {
    /// What to fly, and the commander's limits. Names and types are PX4's where PX4 has the
    /// parameter (`MIS_TAKEOFF_ALT`, `RTL_RETURN_ALT`, …), so that ground stations and MAVSDK
    /// find them where they look.
    CommanderParams, "commander", COMMANDER_META {
        /// Take-off altitude above home (m).
        takeoff_alt_m: f64 = 2.5, "MIS_TAKEOFF_ALT", "m", [0.5, 100.0], "Take-off altitude above home";
        /// Climb speed of the take-off set-point (m/s).
        takeoff_speed_m_s: f64 = 1.5, "MPC_TKO_SPEED", "m/s", [0.3, 5.0], "Climb speed of the take-off";
        /// Spool-up time on the ground after arming (s).
        spool_s: f64 = 1.0, "COM_SPOOLUP_TIME", "s", [0.0, 30.0], "Time on the ground after arming before a take-off climbs";
        /// Descent speed while landing (m/s).
        land_speed_m_s: f64 = 0.7, "MPC_LAND_SPEED", "m/s", [0.1, 3.0], "Descent speed while landing";
        /// Descent speed for the last part of the landing (m/s), as PX4's two-stage landing.
        final_speed_m_s: f64 = 0.3, "MPC_LAND_CRWL", "m/s", [0.1, 3.0], "Descent speed for the last metres of a landing";
        /// Height above home where the final, slower descent begins (m).
        final_height_m: f64 = 2.0, "MPC_LAND_ALT3", "m", [0.0, 20.0], "Height above home below which a landing descends at MPC_LAND_CRWL";
        /// Return altitude above home (m).
        rtl_return_alt_m: f64 = 30.0, "RTL_RETURN_ALT", "m", [0.0, 500.0], "Return altitude above home (a vehicle higher up returns at its altitude)";
        /// Horizontal cruise speed of automatic flight (m/s).
        cruise_speed_m_s: f64 = 5.0, "MPC_XY_CRUISE", "m/s", [0.5, 20.0], "Horizontal speed of automatic flight";
        /// Acceleration of the automatic set-point profiles (m/s²).
        accel_m_s2: f64 = 1.0, "MPC_ACC_HOR", "m/s^2", [0.2, 15.0], "Acceleration of the automatic set-point profiles";
        /// Deceleration of a failsafe's stop (m/s²).
        failsafe_brake_m_s2: f64 = 2.5, "MPC_ACC_FS_BRK", "m/s^2", [0.5, 15.0], "Deceleration of a failsafe's Hold (a fence breach, a lost link): it holds where the vehicle stops at this rate, not at the gentle MPC_ACC_HOR";
        /// Disarm when armed on the ground this long without taking off (s; 0: never).
        disarm_preflight_s: f64 = 10.0, "COM_DISARM_PRFLT", "s", [0.0, 3600.0], "Disarm when armed on the ground this long without taking off (0: never)";
        /// Largest horizontal speed from the sticks in Posctl (m/s).
        manual_speed_m_s: f64 = 5.0, "MPC_VEL_MANUAL", "m/s", [0.5, 20.0], "Horizontal speed at full stick in position mode";
        /// Largest tilt from the sticks in Altctl (deg).
        manual_tilt_deg: f64 = 35.0, "MPC_MAN_TILT_MAX", "deg", [1.0, 70.0], "Tilt at full stick in altitude, stabilized and manual modes";
        /// Yaw rate at full stick (deg/s).
        manual_yaw_rate_deg_s: f64 = 150.0, "MPC_MAN_Y_MAX", "deg/s", [0.0, 400.0], "Yaw rate at full stick";
        /// Climb rate at full throttle stick (m/s).
        manual_climb_m_s: f64 = 3.0, "MAN_Z_VEL_UP", "m/s", [0.3, 10.0], "Climb rate at full throttle stick in altitude and position modes";
        /// Descent rate at zero throttle stick (m/s).
        manual_sink_m_s: f64 = 1.0, "MAN_Z_VEL_DN", "m/s", [0.3, 10.0], "Descent rate at zero throttle stick in altitude and position modes";
        /// Stick dead zone around the centre (fraction of full travel).
        stick_deadzone: f64 = 0.1, "MPC_HOLD_DZ", "", [0.0, 0.5], "Stick dead zone around the centre, where the vehicle holds";
        /// Manual control older than this is lost (s).
        manual_loss_s: f64 = 0.5, "COM_RC_LOSS_T", "s", [0.1, 35.0], "Manual control lost after this long without MANUAL_CONTROL: manual modes switch to Hold";
        /// Thrust at zero throttle stick in the stick-to-attitude modes (fraction of full thrust).
        manual_thrust_min: f64 = 0.08, "MPC_MANTHR_MIN", "", [0.0, 0.3], "Thrust at zero throttle stick in Stabilized and Manual (fraction of full thrust)";
        /// Offboard set-points older than this are lost (s).
        offboard_loss_s: f64 = 0.5, "COM_OF_LOSS_T", "s", [0.05, 60.0], "Offboard set-points lost after this long without one: COM_OBL_RC_ACT takes over";
        /// What flies when the offboard set-points stop.
        offboard_loss_action: u32 = 0, "COM_OBL_RC_ACT", "", [0.0, 5.0], "Offboard loss: 0 Position, 1 Altitude, 2 Manual (each Hold without a joystick), 3 Return, 4 Land, 5 Hold";
        /// Horizontal acceptance radius of mission waypoints that give none (m).
        acceptance_m: f64 = 2.0, "NAV_ACC_RAD", "m", [0.05, 200.0], "Horizontal acceptance radius of mission waypoints that give none";
        /// Vertical acceptance of mission waypoints (m).
        alt_acceptance_m: f64 = 0.8, "NAV_MC_ALT_RAD", "m", [0.05, 200.0], "Vertical acceptance radius of mission waypoints";
        /// Climb speed of automatic flight (m/s).
        auto_climb_m_s: f64 = 3.0, "MPC_Z_V_AUTO_UP", "m/s", [0.5, 8.0], "Climb speed of missions and repositions";
        /// Descent speed of automatic flight (m/s).
        auto_sink_m_s: f64 = 1.5, "MPC_Z_V_AUTO_DN", "m/s", [0.5, 4.0], "Descent speed of missions and repositions";
        /// Yaw rate of automatic flight (deg/s).
        auto_yaw_rate_deg_s: f64 = 45.0, "MPC_YAWRAUTO_MAX", "deg/s", [5.0, 360.0], "Yaw rate of missions, repositions and CONDITION_YAW";
    }
}

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

/// The throttle stick at or below this is "low" (arming and touchdown in Stabilized).
const LOW_THROTTLE: f64 = 0.1;

/// A stick value with the dead zone `dz` around zero taken out, rescaled to reach ±1.
fn deadzone(x: f64, dz: f64) -> f64 {
    if x.abs() <= dz {
        0.0
    } else {
        x.signum() * (x.abs() - dz) / (1.0 - dz).max(1e-6)
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

/// Why a command was refused, in words for the operator (`STATUSTEXT`).
pub type Denial = String;

/// The commander's state as telemetry shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommanderStatus {
    /// Motors armed.
    pub armed: bool,
    /// The flight mode.
    pub mode: FlightMode,
    /// On the ground, taking off, flying or landing.
    pub landed: LandedState,
    /// Home position NED (m) and heading (rad), once set.
    pub home: Option<(Vector3<f64>, f64)>,
    /// A failsafe is flying the vehicle.
    pub failsafe: bool,
    /// The failsafe's action and the condition behind it, while one acts (a warning included).
    pub failsafe_action: Option<(Action, Condition)>,
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
    /// The failsafe conditions acting (bit k: `safety::CONDITIONS[k]`).
    pub failsafe_conditions: u32,
    /// Disarmed and every arming check passes (`SYS_STATUS`'s pre-arm bit).
    pub prearm_ok: bool,
    /// The failsafe machine's events, numbered: each to be said once.
    pub safety_log: crate::safety::failsafe::SafetyLog,
}

/// A straight-line set-point profile from `from` to `to`: speed ramps up at `accel`, cruises
/// at `speed`, and slows so that it stops at the end (v ≤ √(2·a·d)).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    from: Vector3<f64>,
    dir: Vector3<f64>,
    length: f64,
    s: f64,
    v: f64,
    speed: f64,
    accel: f64,
    /// Stepped at least once: the first step starts the profile (no time has passed on it).
    started: bool,
}

impl Line {
    fn new(from: Vector3<f64>, to: Vector3<f64>, speed: f64, accel: f64) -> Self {
        let d = to - from;
        let length = d.norm();
        Self {
            from,
            dir: if length > 1e-9 {
                d / length
            } else {
                Vector3::zeros()
            },
            length,
            s: 0.0,
            v: 0.0,
            speed,
            accel,
            started: false,
        }
    }

    /// Advances `dt`; returns the set-point (position, velocity and acceleration feed-forward,
    /// yaw left to the caller) and whether the end is reached.
    fn step(&mut self, dt: f64, yaw_rad: f64) -> (PositionSetpoint, bool) {
        let dt = if self.started { dt } else { 0.0 };
        self.started = true;
        let left = (self.length - self.s).max(0.0);
        // A lower speed (a speed change on the way) is reached at the same deceleration.
        let v = (self.v + self.accel * dt)
            .min(self.speed)
            .max(self.v - self.accel * dt)
            .min(braking_speed(left, self.accel, dt));
        let a = if dt > 0.0 { (v - self.v) / dt } else { 0.0 };
        self.v = v;
        self.s = (self.s + v * dt).min(self.length);
        let arrived = self.s >= self.length;
        let sp = PositionSetpoint {
            pos_ned_m: self.from + self.dir * self.s,
            vel_ned_m_s: if arrived {
                Vector3::zeros()
            } else {
                self.dir * v
            },
            accel_ned_m_s2: self.dir * a,
            yaw_rad,
        };
        (sp, arrived)
    }
}

/// The fastest speed from which a set-point stepping every `dt` still stops within `left` at
/// deceleration `a`: v = √(2·a·d) in the limit, here with the half-step of the discrete motion,
/// √(2·a·d + (a·dt/2)²) − a·dt/2.
fn braking_speed(left: f64, a: f64, dt: f64) -> f64 {
    let h = 0.5 * a * dt;
    (2.0 * a * left + h * h).sqrt() - h
}

/// The stages of a return.
#[derive(Debug, Clone, Copy, PartialEq)]
enum RtlStage {
    Climb,
    Return,
    Land,
}

/// The commander.
#[derive(Debug, Clone, PartialEq)]
pub struct Commander {
    params: CommanderParams,
    armed: bool,
    mode: FlightMode,
    landed: LandedState,
    since_s: f64,
    armed_at_s: f64,
    home: Option<(Vector3<f64>, f64)>,
    /// Home was set by a command: arming keeps it.
    home_commanded: bool,
    /// The take-off altitude of the current take-off (m above home).
    takeoff_alt_m: f64,
    line: Option<Line>,
    hold: Option<(Vector3<f64>, f64)>,
    land_sp_down: Option<f64>,
    land_xy: Option<(f64, f64)>,
    rtl: RtlStage,
    still_since_s: Option<f64>,
    last: Option<CommanderInput>,
    /// The mode changed since the caller last asked (heartbeat "right after a mode change").
    changed: bool,
    /// The last sticks and the time they arrived (s, the commander's clock).
    sticks: Option<(Sticks, f64)>,
    /// The heading the yaw stick steers (rad).
    manual_yaw: Option<f64>,
    /// How often manual control was lost in a manual mode (and Hold took over).
    manual_losses: u32,
    /// The last offboard set-point and the time it arrived (s, the commander's clock).
    offboard: Option<(OffboardTarget, f64)>,
    /// The heading Offboard holds or turns when its set-points give none (rad).
    offboard_yaw: Option<f64>,
    /// How often the offboard set-points were lost in Offboard.
    offboard_losses: u32,
    /// The uploaded mission and its progress.
    mission: MissionRun,
    /// The horizontal speed of automatic flight `DO_CHANGE_SPEED` set (m/s).
    speed_override: Option<f64>,
    /// The heading automatic flight turns (rad): set by missions and repositions, held by the
    /// other automatic modes; cleared at arming (home's heading then).
    auto_yaw: Option<f64>,
    /// A `CONDITION_YAW` heading (rad) and rate (rad/s), until the mode or item changes.
    yaw_goal: Option<(f64, Option<f64>)>,
    /// The failsafe state machine.
    safety: Safety,
    /// Its last decision's action and cause.
    failsafe: (Action, Option<Condition>),
    /// Every arming check passed at the last update (checked there once, not per status read).
    prearm_ok: bool,
    /// What it said since the caller last asked.
    safety_events: Vec<SafetyEvent>,
    /// What it said, numbered, for readers of [`Commander::status`].
    safety_log: crate::safety::failsafe::SafetyLog,
}

impl Commander {
    /// A disarmed commander in Loiter (Hold), PX4's default.
    pub fn new(params: CommanderParams) -> Self {
        Self {
            params,
            armed: false,
            mode: FlightMode::Loiter,
            landed: LandedState::OnGround,
            since_s: 0.0,
            armed_at_s: 0.0,
            home: None,
            home_commanded: false,
            takeoff_alt_m: params.takeoff_alt_m,
            line: None,
            hold: None,
            land_sp_down: None,
            land_xy: None,
            rtl: RtlStage::Climb,
            still_since_s: None,
            last: None,
            changed: false,
            sticks: None,
            manual_yaw: None,
            manual_losses: 0,
            offboard: None,
            offboard_yaw: None,
            offboard_losses: 0,
            mission: MissionRun::new(),
            speed_override: None,
            auto_yaw: None,
            yaw_goal: None,
            safety: Safety::new(SafetyParams::default()),
            failsafe: (Action::None, None),
            prearm_ok: false,
            safety_events: Vec::new(),
            safety_log: crate::safety::failsafe::SafetyLog::default(),
        }
    }

    /// New failsafe and arming-check parameters.
    pub fn set_safety_params(&mut self, params: SafetyParams) {
        self.safety.set_params(params);
    }

    /// What the failsafes said since the last call (for `STATUSTEXT`), oldest first.
    pub fn take_safety_events(&mut self) -> Vec<SafetyEvent> {
        std::mem::take(&mut self.safety_events)
    }

    /// A new offboard set-point, at the time of the last update.
    pub fn offboard_setpoint(&mut self, target: OffboardTarget) {
        self.offboard = Some((target, self.now()));
    }

    /// The offboard set-point, if it arrived within `COM_OF_LOSS_T`.
    fn fresh_offboard(&self) -> Option<OffboardTarget> {
        self.offboard
            .filter(|&(_, t)| self.now() - t <= self.params.offboard_loss_s)
            .map(|(s, _)| s)
    }

    /// New stick positions (`MANUAL_CONTROL`), at the time of the last update.
    pub fn manual_control(&mut self, sticks: Sticks) {
        self.sticks = Some((sticks.clamped(), self.now()));
    }

    /// The sticks, if they arrived within `COM_RC_LOSS_T`.
    fn fresh_sticks(&self) -> Option<Sticks> {
        self.sticks
            .filter(|&(_, t)| self.now() - t <= self.params.manual_loss_s)
            .map(|(s, _)| s)
    }

    /// The parameters.
    pub fn params(&self) -> &CommanderParams {
        &self.params
    }

    /// Changes the parameters (a parameter set from a ground station); the flight in progress
    /// uses the new values from its next stage.
    pub fn set_params(&mut self, params: CommanderParams) {
        self.params = params;
    }

    /// The state as telemetry shows it.
    pub fn status(&self) -> CommanderStatus {
        CommanderStatus {
            armed: self.armed,
            mode: self.mode,
            landed: self.landed,
            home: self.home,
            failsafe: self.mode == FlightMode::Descend || self.failsafe.0 > Action::Warn,
            failsafe_action: match self.failsafe {
                (a, Some(c)) if a > Action::None => Some((a, c)),
                _ => None,
            },
            ready: self.last.is_some_and(|i| i.ready),
            in_mode_s: self.last.map_or(0.0, |i| (i.t_s - self.since_s).max(0.0)),
            manual_losses: self.manual_losses,
            manual_control: self.sticks.map(|_| self.fresh_sticks().is_some()),
            offboard_losses: self.offboard_losses,
            mission: self.mission.status(),
            motor_failed: self.last.and_then(|i| i.health.motor_failed),
            failsafe_conditions: self.safety.active_mask(),
            prearm_ok: !self.armed && self.prearm_ok,
            safety_log: self.safety_log,
        }
    }

    /// Motors armed.
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// The flight mode.
    pub fn mode(&self) -> FlightMode {
        self.mode
    }

    /// On the ground, taking off, flying or landing.
    pub fn landed(&self) -> LandedState {
        self.landed
    }

    /// Home position NED (m), once set: where the position first became valid on the ground,
    /// then where it armed (unless [`Commander::set_home`] set it).
    pub fn home(&self) -> Option<Vector3<f64>> {
        self.home.map(|h| h.0)
    }

    /// Whether the armed state or the mode changed since the last call (and clears it).
    pub fn take_changed(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    fn now(&self) -> f64 {
        self.last.map_or(0.0, |i| i.t_s)
    }

    fn ready(&self) -> bool {
        self.last.is_some_and(|i| i.ready)
    }

    fn enter(&mut self, mode: FlightMode) {
        if mode != self.mode {
            self.changed = true;
        }
        if self.mode == FlightMode::Mission {
            self.mission.left();
        }
        self.mission.stage = Stage::Start;
        self.yaw_goal = None;
        self.mode = mode;
        self.since_s = self.now();
        self.line = None;
        self.hold = None;
        self.land_sp_down = None;
        self.land_xy = None;
        self.rtl = RtlStage::Climb;
        self.still_since_s = None;
        self.manual_yaw = None;
        self.offboard_yaw = None;
    }

    /// Arms the motors. Refused while the estimator is not ready (unless `force`), in modes
    /// that cannot start on the ground (Land, RTL, Descend), and in modes not flown yet.
    pub fn arm(&mut self, force: bool) -> Result<(), Denial> {
        if self.armed {
            return Ok(());
        }
        match self.mode {
            FlightMode::Takeoff | FlightMode::Loiter => {}
            FlightMode::Mission => self
                .mission_entry()
                .map_err(|e| format!("arming refused: {e}"))?,
            FlightMode::Posctl | FlightMode::Altctl => {
                let Some(s) = self.fresh_sticks() else {
                    return Err(format!(
                        "arming refused: {} needs manual control (MANUAL_CONTROL)",
                        self.mode.name()
                    ));
                };
                if s.throttle > 0.5 + self.params.stick_deadzone && !force {
                    return Err("arming refused: throttle stick above centre".into());
                }
            }
            FlightMode::Manual | FlightMode::Stabilized => {
                let Some(s) = self.fresh_sticks() else {
                    return Err(format!(
                        "arming refused: {} needs manual control (MANUAL_CONTROL)",
                        self.mode.name()
                    ));
                };
                // The throttle is the thrust here: arming with it up would leap.
                if s.throttle > LOW_THROTTLE && !force {
                    return Err("arming refused: throttle stick not low".into());
                }
            }
            FlightMode::Offboard => {
                if self.fresh_offboard().is_none() {
                    return Err("arming refused: no offboard set-points".into());
                }
            }
            FlightMode::Land | FlightMode::Rtl | FlightMode::Descend => {
                return Err(format!(
                    "arming refused: not in a mode to start in ({})",
                    self.mode.name()
                ));
            }
        }
        let Some(i) = self.last else {
            return Err("arming refused: no sensor data yet".into());
        };
        let mut failures = self.preflight_failures(&i);
        failures.retain(|f| !(force && f.skippable));
        if let Some(first) = failures.first() {
            let more = match failures.len() {
                1 => String::new(),
                n => format!(" (and {} more)", n - 1),
            };
            return Err(format!("arming refused: {}{more}", first.text));
        }
        self.armed = true;
        self.changed = true;
        self.armed_at_s = i.t_s;
        self.since_s = i.t_s;
        self.landed = LandedState::OnGround;
        if !self.home_commanded {
            self.home = Some((i.pos_ned_m, i.yaw_rad));
        }
        self.hold = None;
        self.line = None;
        self.auto_yaw = None;
        self.mission.stage = Stage::Start;
        Ok(())
    }

    /// The arming checks that fail now (whatever the mode asks for besides).
    fn preflight_failures(
        &self,
        i: &CommanderInput,
    ) -> Vec<crate::safety::preflight::PreflightFailure> {
        let h = i.health;
        let mut failures = crate::safety::preflight::preflight(
            &PreflightInput {
                attitude_valid: h.attitude_valid,
                gyro_bias_settled: h.gyro_bias_settled,
                position_valid: i.horizontal_valid,
                altitude_valid: h.altitude_valid,
                mode_needs_position: self.mode.needs_position(),
                sensors_lost: h.sensors_lost,
                mag: h.mag,
                battery_remaining: h.battery_remaining,
                params_invalid: self.safety.params().inconsistencies().first().cloned(),
                roll_pitch_rad: h.roll_pitch_rad,
                geofence_breached: h.geofence_breached,
                motor_failed: h.motor_failed,
                terminated: self.safety.terminated(),
            },
            self.safety.params(),
        );
        if !i.ready && self.mode.needs_position() && failures.is_empty() {
            // The caller's verdict on the estimate, when its parts are not known here.
            failures.push(crate::safety::preflight::PreflightFailure {
                text: "estimator not ready (attitude or position invalid)".into(),
                skippable: true,
            });
        }
        failures
    }

    /// Disarms. Refused in the air unless `force` (which stops the motors wherever it is).
    pub fn disarm(&mut self, force: bool) -> Result<(), Denial> {
        if !self.armed {
            return Ok(());
        }
        if self.landed != LandedState::OnGround && !force {
            return Err("disarming refused: in the air (land first, or force)".into());
        }
        self.disarmed();
        Ok(())
    }

    /// The motors stopped (a forced disarm, the end of a failsafe): on the ground from now on,
    /// in Loiter unless the mode needs no flight (a failsafe's Descend ends here).
    pub fn disarmed(&mut self) {
        if self.armed {
            self.changed = true;
            self.mission_landed();
        }
        self.armed = false;
        self.landed = LandedState::OnGround;
        if matches!(
            self.mode,
            FlightMode::Land | FlightMode::Rtl | FlightMode::Descend | FlightMode::Takeoff
        ) {
            self.enter(FlightMode::Loiter);
        }
    }

    /// Switches mode. Refused for modes not flown yet, for RTL without a home, and out of a
    /// failsafe's Descend while it flies.
    pub fn set_mode(&mut self, mode: FlightMode) -> Result<(), Denial> {
        if mode == self.mode {
            return Ok(());
        }
        if self.mode == FlightMode::Descend && self.armed {
            return Err("mode change refused: failsafe descent in progress".into());
        }
        if self.armed && self.failsafe.0 > Action::Warn {
            // The operator takes over (refused while a failsafe allows none).
            self.safety.take_over()?;
            self.failsafe = (Action::None, None);
        }
        match mode {
            FlightMode::Takeoff | FlightMode::Loiter | FlightMode::Land => {}
            FlightMode::Rtl => {
                if self.home.is_none() {
                    return Err("RTL refused: no home position".into());
                }
            }
            FlightMode::Posctl
            | FlightMode::Altctl
            | FlightMode::Manual
            | FlightMode::Stabilized => {
                if self.fresh_sticks().is_none() {
                    return Err(format!(
                        "{} refused: no manual control (MANUAL_CONTROL)",
                        mode.name()
                    ));
                }
            }
            FlightMode::Offboard => {
                if self.fresh_offboard().is_none() {
                    return Err(format!(
                        "OFFBOARD refused: no set-point stream in the last {} s (COM_OF_LOSS_T)",
                        self.params.offboard_loss_s
                    ));
                }
            }
            FlightMode::Mission => self.mission_entry()?,
            FlightMode::Descend => return Err("DESCEND is a failsafe, not a mode to select".into()),
        }
        if mode == FlightMode::Takeoff && self.armed && !self.ready() {
            return Err("take-off refused: estimator not ready".into());
        }
        if mode == FlightMode::Takeoff && self.mode != FlightMode::Takeoff {
            // The mode selected by itself climbs to today's MIS_TAKEOFF_ALT.
            self.takeoff_alt_m = self.params.takeoff_alt_m;
        }
        self.enter(mode);
        Ok(())
    }

    /// Take-off to `alt_above_home_m` (the parameter's altitude if `None`): switches to
    /// Takeoff; a disarmed vehicle climbs once armed.
    pub fn takeoff(&mut self, alt_above_home_m: Option<f64>) -> Result<(), Denial> {
        let alt = alt_above_home_m.unwrap_or(self.params.takeoff_alt_m);
        if !(alt.is_finite() && alt > 0.0) {
            return Err(format!(
                "take-off refused: altitude {alt} m is not above home"
            ));
        }
        if self.mode == FlightMode::Takeoff {
            // A repeated command (a retransmission) keeps the climb in progress.
            self.takeoff_alt_m = alt;
            return Ok(());
        }
        self.set_mode(FlightMode::Takeoff)?;
        self.takeoff_alt_m = alt;
        Ok(())
    }

    /// Sets home to `pos_ned_m` (or to the current position if `None`).
    pub fn set_home(&mut self, pos_ned_m: Option<Vector3<f64>>) -> Result<(), Denial> {
        let Some(i) = self.last else {
            return Err("home refused: no position estimate yet".into());
        };
        let pos = match pos_ned_m {
            Some(p) => p,
            None if i.ready => i.pos_ned_m,
            None => return Err("home refused: position estimate not valid".into()),
        };
        if !pos.iter().all(|x| x.is_finite()) {
            return Err("home refused: position not finite".into());
        }
        let yaw = self.home.map_or(i.yaw_rad, |h| h.1);
        self.home = Some((pos, yaw));
        self.home_commanded = true;
        Ok(())
    }

    /// The estimate is lost (sensors stopped, or it is unfit to fly on): on the ground the motors
    /// stop; in the air the vehicle descends (what flies it until they return is the caller's:
    /// see [`crate::safety::blind_descent::BlindDescent`]). Returns whether it is in the air.
    pub fn sensors_stopped(&mut self) -> bool {
        if !self.armed {
            return false;
        }
        if self.landed == LandedState::OnGround {
            self.disarmed();
            return false;
        }
        if self.mode != FlightMode::Descend {
            self.enter(FlightMode::Descend);
            self.landed = LandedState::Landing;
        }
        true
    }

    /// Touchdown when the vehicle has been `stopped` for a second: disarm.
    fn touchdown_check(&mut self, stopped: bool, t: f64) {
        match (stopped, self.still_since_s) {
            (true, None) => self.still_since_s = Some(t),
            (true, Some(s)) if t - s >= 1.0 => self.disarmed(),
            (false, _) => self.still_since_s = None,
            _ => {}
        }
    }

    /// The landing descent at `xy`: the set-point goes down steadily (slower near the ground);
    /// touchdown when the vehicle has stopped moving down for a second while the set-point is
    /// well below it (it cannot go lower).
    fn land_at(&mut self, i: &CommanderInput, dt: f64, yaw: f64) -> PositionSetpoint {
        let p = self.params;
        self.landed = LandedState::Landing;
        let (x, y) = *self.land_xy.get_or_insert((i.pos_ned_m.x, i.pos_ned_m.y));
        let ground = self.home.map_or(i.pos_ned_m.z, |h| h.0.z);
        let height = ground - i.pos_ned_m.z;
        let speed = if height > p.final_height_m {
            p.land_speed_m_s
        } else {
            p.final_speed_m_s
        };
        let down = self.land_sp_down.get_or_insert(i.pos_ned_m.z);
        *down = (*down + speed * dt).min(i.pos_ned_m.z + 1.0);
        let down = *down;
        let stopped = i.vel_ned_m_s.z.abs() < 0.15 && down - i.pos_ned_m.z > 0.5;
        self.touchdown_check(stopped, i.t_s);
        PositionSetpoint {
            pos_ned_m: Vector3::new(x, y, down),
            vel_ned_m_s: Vector3::new(0.0, 0.0, speed),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        }
    }

    /// One step of the failsafe state machine, its decision carried out when it changes.
    fn failsafes(&mut self, i: &CommanderInput) {
        let h = i.health;
        // GF_MAX_HOR_DIST and GF_MAX_VER_DIST from home (0: no limit), with the caller's
        // polygons and circles.
        let limits = *self.safety.params();
        let breached = self.home.is_some_and(|(home, _)| {
            let off = i.pos_ned_m - home;
            let beyond = |x: f64, limit: f64| limit > 0.0 && x > limit;
            beyond(off.xy().norm(), limits.fence_max_horizontal_m)
                || beyond(-off.z, limits.fence_max_vertical_m)
        });
        let d = self.safety.update(&SafetyInput {
            t_s: i.t_s,
            armed: self.armed,
            in_air: self.landed != LandedState::OnGround,
            mode_needs_position: self.mode.needs_position(),
            gcs_link_age_s: h.gcs_link_age_s,
            battery_remaining: h.battery_remaining,
            geofence_breached: h.geofence_breached || (breached && i.horizontal_valid),
            attitude_valid: h.attitude_valid,
            position_valid: i.horizontal_valid,
            altitude_valid: h.altitude_valid,
            sensors_lost: h.sensors_lost,
            roll_pitch_rad: h.roll_pitch_rad,
            home_set: self.home.is_some(),
            motor_failed: h.motor_failed.is_some(),
        });
        self.safety_events.extend(d.events.iter().copied());
        for &e in &d.events {
            self.safety_log.push(e);
        }
        // Kept for a caller that drains them; bounded for one that does not.
        let excess = self.safety_events.len().saturating_sub(64);
        self.safety_events.drain(..excess);
        let changed = d.action != self.failsafe.0;
        self.failsafe = (d.action, d.cause);
        if !changed || !self.armed {
            return;
        }
        match d.action {
            Action::None | Action::Warn => {}
            Action::Hold => {
                self.enter(FlightMode::Loiter);
                if self.landed == LandedState::InAir {
                    // Stop firmly: a braking profile at MPC_ACC_FS_BRK from the present speed
                    // (its velocity and deceleration fed forward), then hold where it ends.
                    let v = Vector3::new(i.vel_ned_m_s.x, i.vel_ned_m_s.y, 0.0);
                    let speed = v.norm();
                    let a = self.params.failsafe_brake_m_s2.max(0.1);
                    let stop = i.pos_ned_m + v * speed / (2.0 * a);
                    if speed > 0.1 {
                        let mut line = Line::new(i.pos_ned_m, stop, speed, a);
                        line.v = speed;
                        self.line = Some(line);
                    }
                    self.hold = Some((stop, self.auto_yaw.unwrap_or(i.yaw_rad)));
                }
            }
            Action::Return => self.enter(FlightMode::Rtl),
            Action::Land => self.enter(FlightMode::Land),
            Action::Descend => {
                self.sensors_stopped();
            }
            Action::Disarm | Action::Terminate => self.disarmed(),
        }
    }

    /// Advances; returns the set-point and whether the motors are armed.
    pub fn update(&mut self, i: &CommanderInput) -> (Setpoint, bool) {
        let p = self.params;
        let t = i.t_s;
        let dt = self.last.map_or(0.0, |l| (t - l.t_s).max(0.0));
        self.last = Some(*i);
        self.failsafes(i);
        self.prearm_ok = !self.armed && self.preflight_failures(i).is_empty();
        if !i.ready {
            // The same reaction as to silent sensors, at this update's time.
            self.sensors_stopped();
        }
        let yaw = self
            .auto_yaw
            .unwrap_or_else(|| self.home.map_or(i.yaw_rad, |h| h.1));
        let hold = |pos: Vector3<f64>| PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        };
        if !self.armed {
            if self.home.is_none() && i.ready {
                // As PX4: home as soon as the position is valid on the ground (ground stations
                // and MAVSDK's health wait for it), then again at arming.
                self.home = Some((i.pos_ned_m, i.yaw_rad));
            }
            return (Setpoint::Position(hold(i.pos_ned_m)), false);
        }
        let home = self.home.map_or(i.pos_ned_m, |h| h.0);
        // Spool-up: a set-point just below the ground keeps thrust low until take-off.
        let on_ground = hold(home + Vector3::new(0.0, 0.0, 0.5));
        let since_arming = t - self.armed_at_s;
        if self.landed == LandedState::OnGround
            && self.mode != FlightMode::Takeoff
            && p.disarm_preflight_s > 0.0
            && since_arming >= p.disarm_preflight_s
        {
            // PX4's COM_DISARM_PRFLT: armed and left on the ground.
            self.disarmed();
            return (Setpoint::Position(hold(i.pos_ned_m)), false);
        }
        let sp = match self.mode {
            FlightMode::Takeoff => {
                if self.landed == LandedState::OnGround && since_arming < p.spool_s {
                    return (Setpoint::Position(on_ground), true);
                }
                let target_down = home.z - self.takeoff_alt_m;
                if self.line.is_none() {
                    if i.pos_ned_m.z <= target_down && self.landed != LandedState::OnGround {
                        // Already above the take-off altitude: hold here.
                        self.enter(FlightMode::Loiter);
                        return (Setpoint::Position(self.loiter(i, yaw)), true);
                    }
                    // From the ground the climb starts at the ground, not at the estimate's
                    // noise around it.
                    let from = if self.landed == LandedState::OnGround {
                        Vector3::new(i.pos_ned_m.x, i.pos_ned_m.y, home.z)
                    } else {
                        i.pos_ned_m
                    };
                    self.line = Some(Line::new(
                        from,
                        Vector3::new(from.x, from.y, target_down),
                        p.takeoff_speed_m_s,
                        p.accel_m_s2,
                    ));
                    self.landed = LandedState::Takeoff;
                }
                let Some(line) = self.line.as_mut() else {
                    return (Setpoint::Position(on_ground), true);
                };
                let (sp, arrived) = line.step(dt, yaw);
                let goal = line.from.z - line.length;
                if arrived && i.pos_ned_m.z - home.z <= 0.95 * (goal - home.z) {
                    self.landed = LandedState::InAir;
                    self.enter(FlightMode::Loiter);
                    self.hold = Some((sp.pos_ned_m, yaw));
                }
                sp
            }
            FlightMode::Loiter => {
                if self.landed == LandedState::OnGround {
                    return (Setpoint::Position(on_ground), true);
                }
                self.landed = LandedState::InAir;
                // A CONDITION_YAW turns the held heading; a reposition flies its leg first.
                let yaw = if self.yaw_goal.is_some() {
                    self.slew_yaw(None, i, dt)
                } else {
                    self.hold.map_or(yaw, |h| h.1)
                };
                if let Some(h) = self.hold.as_mut() {
                    h.1 = yaw;
                }
                match self.line.as_mut() {
                    Some(line) => {
                        let (sp, arrived) = line.step(dt, yaw);
                        if arrived {
                            self.line = None;
                        }
                        sp
                    }
                    None => self.loiter(i, yaw),
                }
            }
            FlightMode::Land => self.land_at(i, dt, yaw),
            FlightMode::Mission => self.mission_flight(i, dt, home),
            FlightMode::Rtl => {
                if self.landed == LandedState::OnGround {
                    return (Setpoint::Position(on_ground), true);
                }
                self.rtl(i, dt, yaw, home)
            }
            FlightMode::Descend => {
                // Braking to zero ground speed while the horizontal estimate holds, else level
                // (horizontal velocity uncontrolled); touchdown when the vertical speed has
                // stayed near zero for a second.
                self.landed = LandedState::Landing;
                let stopped = t - self.since_s > 1.0 && i.vel_ned_m_s.z.abs() < 0.15;
                self.touchdown_check(stopped, t);
                let h = if i.horizontal_valid { 0.0 } else { f64::NAN };
                PositionSetpoint {
                    pos_ned_m: Vector3::repeat(f64::NAN),
                    vel_ned_m_s: Vector3::new(h, h, p.land_speed_m_s),
                    accel_ned_m_s2: Vector3::zeros(),
                    yaw_rad: yaw,
                }
            }
            FlightMode::Posctl | FlightMode::Altctl => match self.fresh_sticks() {
                Some(sticks) => match self.manual(i, dt, sticks, home) {
                    Some(sp) => sp,
                    None => return (Setpoint::Position(on_ground), true),
                },
                None => self.manual_lost(i, yaw),
            },
            FlightMode::Offboard => match self.fresh_offboard() {
                Some(target) => return (self.offboard_flight(i, dt, target, home), self.armed),
                None => self.offboard_lost(i, yaw),
            },
            FlightMode::Manual | FlightMode::Stabilized => match self.fresh_sticks() {
                Some(sticks) => {
                    let target = self.stabilized(i, sticks, home);
                    return (Setpoint::Attitude(target), self.armed);
                }
                None => self.manual_lost(i, yaw),
            },
        };
        (Setpoint::Position(sp), self.armed)
    }

    /// Armed on the ground: a set-point just below home keeps the thrust low (spooled up).
    fn spooled(&self, i: &CommanderInput, yaw: f64) -> PositionSetpoint {
        let home = self.home.map_or(i.pos_ned_m, |h| h.0);
        PositionSetpoint {
            pos_ned_m: home + Vector3::new(0.0, 0.0, 0.5),
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        }
    }

    /// PX4's manual-control-loss failsafe: hold where it is (on the ground: stay there).
    fn manual_lost(&mut self, i: &CommanderInput, yaw: f64) -> PositionSetpoint {
        self.manual_losses += 1;
        self.enter(FlightMode::Loiter);
        if self.landed == LandedState::OnGround {
            return self.spooled(i, yaw);
        }
        self.loiter(i, yaw)
    }

    /// Offboard: the streamed set-point, with the landed state it implies (take-off when it
    /// asks to go up; touchdown when it does not, below a metre, still for a second: disarm).
    fn offboard_flight(
        &mut self,
        i: &CommanderInput,
        dt: f64,
        target: OffboardTarget,
        home: Vector3<f64>,
    ) -> Setpoint {
        let hover = i.hover_thrust.clamp(0.05, 0.95);
        let up_asked = match &target.setpoint {
            Setpoint::Position(p) => {
                p.pos_ned_m.z < home.z - 0.3
                    || p.vel_ned_m_s.z < -0.1
                    || (p.pos_ned_m.z.is_nan()
                        && p.vel_ned_m_s.z.is_nan()
                        && p.accel_ned_m_s2.z < -0.1)
            }
            Setpoint::Attitude(a) => a.thrust > hover,
        };
        let height = home.z - i.pos_ned_m.z;
        match self.landed {
            LandedState::OnGround => {
                self.still_since_s = None;
                if !up_asked {
                    // Kept on the ground until the set-points ask to leave it.
                    return Setpoint::Position(self.spooled(i, i.yaw_rad));
                }
                self.landed = LandedState::Takeoff;
            }
            LandedState::Takeoff if height > 1.0 => self.landed = LandedState::InAir,
            _ => {
                let still = !up_asked && height < 1.0 && i.vel_ned_m_s.norm() < 0.3;
                self.touchdown_check(still, i.t_s);
            }
        }
        match target.setpoint {
            Setpoint::Position(mut p) => {
                if !p.yaw_rad.is_finite() {
                    // No yaw: hold the heading, or turn it at the yaw rate given.
                    let yaw = self.offboard_yaw.get_or_insert(i.yaw_rad);
                    if let Some(rate) = target.yaw_rate_rad_s.filter(|r| r.is_finite()) {
                        *yaw = (*yaw + rate * dt + PI).rem_euclid(TAU) - PI;
                    }
                    p.yaw_rad = *yaw;
                } else {
                    self.offboard_yaw = Some(p.yaw_rad);
                }
                Setpoint::Position(p)
            }
            Setpoint::Attitude(mut a) => {
                if !a.thrust.is_finite() {
                    a.thrust = hover;
                }
                self.offboard_yaw = None;
                Setpoint::Attitude(a)
            }
        }
    }

    /// The offboard set-points stopped: `COM_OBL_RC_ACT`'s mode takes over (a stick mode only
    /// with a joystick, else Hold); this step holds.
    fn offboard_lost(&mut self, i: &CommanderInput, yaw: f64) -> PositionSetpoint {
        self.offboard_losses += 1;
        let sticks = self.fresh_sticks().is_some();
        let next = match self.params.offboard_loss_action {
            0 if sticks => FlightMode::Posctl,
            1 if sticks => FlightMode::Altctl,
            2 if sticks => FlightMode::Stabilized,
            3 if self.home.is_some() => FlightMode::Rtl,
            4 => FlightMode::Land,
            _ => FlightMode::Loiter,
        };
        if self.landed == LandedState::OnGround {
            self.enter(FlightMode::Loiter);
            return self.spooled(i, yaw);
        }
        self.enter(next);
        self.loiter(i, yaw)
    }

    /// Stabilized (and Manual): the sticks as an attitude and a thrust, as PX4's
    /// `ManualControl` → attitude set-point for multicopters.
    fn stabilized(&mut self, i: &CommanderInput, s: Sticks, home: Vector3<f64>) -> AttitudeTarget {
        let p = self.params;
        // Throttle curve (PX4's MPC_THR_CURVE 0): zero → MPC_MANTHR_MIN, centre → hover
        // thrust, full → full thrust, linear in between.
        let hover = i.hover_thrust.clamp(0.05, 0.95);
        let min = p.manual_thrust_min.min(hover);
        let thrust = if s.throttle <= 0.5 {
            min + (hover - min) * s.throttle / 0.5
        } else {
            hover + (1.0 - hover) * (s.throttle - 0.5) / 0.5
        };
        let height = home.z - i.pos_ned_m.z;
        match self.landed {
            LandedState::OnGround => {
                // Lifting off: thrust above hover, or the vehicle has risen.
                if thrust > hover || height > 0.5 {
                    self.landed = LandedState::Takeoff;
                }
                self.still_since_s = None;
            }
            LandedState::Takeoff if height > 1.0 => self.landed = LandedState::InAir,
            _ => {
                // Touchdown: throttle held low and the vehicle still for a second.
                let still = s.throttle <= LOW_THROTTLE && i.vel_ned_m_s.norm() < 0.3;
                self.touchdown_check(still, i.t_s);
            }
        }
        // The yaw stick commands a turn rate, the heading following the vehicle meanwhile (as
        // PX4's StickYaw: a set-point integrated ahead of a vehicle whose turn rate is limited
        // by MC_YAWRATE_MAX would run away from it); centred, the heading of that moment is
        // held. On the ground the heading follows the vehicle.
        let yaw_rate = deadzone(s.yaw, p.stick_deadzone) * p.manual_yaw_rate_deg_s.to_radians();
        let yaw = match self.manual_yaw {
            Some(y) if yaw_rate == 0.0 && self.landed != LandedState::OnGround => y,
            _ => i.yaw_rad,
        };
        let yaw = (yaw + PI).rem_euclid(TAU) - PI;
        self.manual_yaw = (yaw_rate == 0.0).then_some(yaw);
        // Roll and pitch sticks: a tilt vector in the heading's frame (right stick: roll right;
        // forward stick: nose down), its length limited to the largest tilt.
        let max_tilt = p.manual_tilt_deg.to_radians();
        let mut tilt = Vector2::new(s.right, -s.forward) * max_tilt;
        if tilt.norm() > max_tilt {
            tilt *= max_tilt / tilt.norm();
        }
        let q_d = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
            * UnitQuaternion::from_scaled_axis(Vector3::new(tilt.x, tilt.y, 0.0));
        // Ω_d: the heading's turn, seen in the desired body frame.
        let rate = q_d.inverse() * Vector3::new(0.0, 0.0, yaw_rate);
        AttitudeTarget {
            q_d: Some(q_d),
            rate_frd_rad_s: if self.landed == LandedState::OnGround {
                Vector3::zeros()
            } else {
                rate
            },
            thrust,
        }
    }

    /// Position and altitude modes from the sticks; `None`: on the ground, stay there.
    fn manual(
        &mut self,
        i: &CommanderInput,
        dt: f64,
        s: Sticks,
        home: Vector3<f64>,
    ) -> Option<PositionSetpoint> {
        let p = self.params;
        let dz = p.stick_deadzone;
        // Throttle around its centre: climb (up to MAN_Z_VEL_UP) or sink (MAN_Z_VEL_DN).
        let climb = deadzone(2.0 * s.throttle - 1.0, dz);
        let vz = if climb > 0.0 {
            -climb * p.manual_climb_m_s
        } else {
            -climb * p.manual_sink_m_s
        };
        if self.landed == LandedState::OnGround {
            if climb <= 0.0 {
                self.still_since_s = None;
                return None;
            }
            self.landed = LandedState::Takeoff;
        }
        let yaw = *self.manual_yaw.get_or_insert(i.yaw_rad);
        let turned = yaw + deadzone(s.yaw, dz) * p.manual_yaw_rate_deg_s.to_radians() * dt;
        let yaw = (turned + PI).rem_euclid(TAU) - PI;
        self.manual_yaw = Some(yaw);
        let height = home.z - i.pos_ned_m.z;
        if self.landed == LandedState::Takeoff && height > 1.0 {
            self.landed = LandedState::InAir;
        }
        // Touchdown: sinking commanded, and no longer moving down for a second.
        let stopped = climb < 0.0 && i.vel_ned_m_s.z.abs() < 0.15 && height < 1.0;
        self.touchdown_check(stopped, i.t_s);
        if !self.armed {
            return None;
        }
        // The held point, per axis: forgotten (NaN) while its stick moves; when the stick
        // centres the vehicle brakes (velocity zero) and the point is locked where it has
        // slowed down, as PX4 does, rather than where the stick was let go (which it would
        // overshoot and fly back to).
        let hold = &mut self.hold.get_or_insert((i.pos_ned_m, yaw)).0;
        let (fwd, right) = (deadzone(s.forward, dz), deadzone(s.right, dz));
        let moving_h = self.mode == FlightMode::Posctl && (fwd != 0.0 || right != 0.0);
        if vz != 0.0 {
            hold.z = f64::NAN;
        } else if hold.z.is_nan() && i.vel_ned_m_s.z.abs() < 0.2 {
            hold.z = i.pos_ned_m.z;
        }
        if moving_h {
            hold.x = f64::NAN;
            hold.y = f64::NAN;
        } else if hold.x.is_nan() && i.vel_ned_m_s.xy().norm() < 0.3 {
            hold.x = i.pos_ned_m.x;
            hold.y = i.pos_ned_m.y;
        }
        let hold_pos = *hold;
        let mut pos = Vector3::repeat(f64::NAN);
        let mut vel = Vector3::repeat(f64::NAN);
        let mut accel = Vector3::zeros();
        if vz != 0.0 {
            vel.z = vz;
        } else if hold_pos.z.is_nan() {
            vel.z = 0.0; // braking
        } else {
            pos.z = hold_pos.z;
        }
        // The stick in the frame of the vehicle's heading, to NED (as PX4).
        let (c, sn) = (i.yaw_rad.cos(), i.yaw_rad.sin());
        let north = fwd * c - right * sn;
        let east = fwd * sn + right * c;
        if self.mode == FlightMode::Posctl {
            if moving_h {
                vel.x = north * p.manual_speed_m_s;
                vel.y = east * p.manual_speed_m_s;
            } else if hold_pos.x.is_nan() {
                vel.x = 0.0; // braking
                vel.y = 0.0;
            } else {
                pos.x = hold_pos.x;
                pos.y = hold_pos.y;
            }
        } else {
            // Altitude mode: the stick tilts the vehicle (its horizontal acceleration).
            let a = crate::GRAVITY_M_S2 * p.manual_tilt_deg.to_radians().tan();
            accel.x = north * a;
            accel.y = east * a;
        }
        Some(PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: vel,
            accel_ned_m_s2: accel,
            yaw_rad: yaw,
        })
    }

    /// Hold: the point where braking at the profile's acceleration stops the vehicle.
    fn loiter(&mut self, i: &CommanderInput, yaw: f64) -> PositionSetpoint {
        let a = self.params.accel_m_s2.max(0.1);
        let (pos, yaw) = *self.hold.get_or_insert_with(|| {
            let v = i.vel_ned_m_s;
            (i.pos_ned_m + v * v.norm() / (2.0 * a), yaw)
        });
        PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        }
    }

    /// Return: climb to the return altitude, fly home level, land there.
    fn rtl(
        &mut self,
        i: &CommanderInput,
        dt: f64,
        yaw: f64,
        home: Vector3<f64>,
    ) -> PositionSetpoint {
        let p = self.params;
        self.landed = LandedState::InAir;
        loop {
            match self.rtl {
                RtlStage::Climb => {
                    let up_to = (home.z - p.rtl_return_alt_m).min(i.pos_ned_m.z);
                    let line = self.line.get_or_insert_with(|| {
                        let to = Vector3::new(i.pos_ned_m.x, i.pos_ned_m.y, up_to);
                        Line::new(i.pos_ned_m, to, p.takeoff_speed_m_s, p.accel_m_s2)
                    });
                    let (sp, arrived) = line.step(dt, yaw);
                    if !arrived {
                        return sp;
                    }
                    self.rtl = RtlStage::Return;
                    self.line = None;
                }
                RtlStage::Return => {
                    let line = self.line.get_or_insert_with(|| {
                        let from = Vector3::new(i.pos_ned_m.x, i.pos_ned_m.y, i.pos_ned_m.z);
                        let to = Vector3::new(home.x, home.y, from.z);
                        Line::new(from, to, p.cruise_speed_m_s, p.accel_m_s2)
                    });
                    let to = line.from + line.dir * line.length;
                    let (sp, arrived) = line.step(dt, yaw);
                    if !(arrived && (i.pos_ned_m.xy() - to.xy()).norm() < 1.0) {
                        return sp;
                    }
                    self.rtl = RtlStage::Land;
                    self.land_xy = Some((home.x, home.y));
                }
                RtlStage::Land => return self.land_at(i, dt, yaw),
            }
        }
    }
}

/// An angle wrapped to [−π, π).
fn wrap_pi(a: f64) -> f64 {
    (a + PI).rem_euclid(TAU) - PI
}

mod mission;
#[cfg(test)]
mod tests;
