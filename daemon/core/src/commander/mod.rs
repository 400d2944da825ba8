//! The commander: arming, flight modes and what each mode flies (PX4's commander and navigator
//! in one pure state machine of time and the estimate).
//!
//! Commands ([`Commander::arm`], [`Commander::set_mode`], [`Commander::takeoff`], …) are answered
//! at once with `Ok` or a denial that says why; [`Commander::update`] then turns the mode into a
//! set-point for the flight core on every sample: a position set-point, or an attitude and thrust
//! in the stick-to-attitude modes.
//!
//! The commander only chooses the mode and switches; each mode is flown by a flight task of
//! its own (`task.rs`: `activate`, `update`, `is_finished`, as PX4's `FlightTask`), in one file
//! per mode: `takeoff.rs`, `hold.rs` (Loiter), `land.rs`, `rtl.rs`, `mission.rs`,
//! `manual_position.rs` (Posctl, Altctl), `stabilized.rs` (Stabilized, Manual), `offboard.rs`,
//! `orbit.rs`, `follow_target.rs` and `descend.rs` (a failsafe, left only by landing). What outlives a mode — armed, landed,
//! home, the uploaded mission, the heading and speed of automatic flight — is `flight.rs`.
//! A finished take-off hands over to Hold; a touchdown disarms; a stick or offboard stream
//! that stops (`COM_RC_LOSS_T`, `COM_OF_LOSS_T`) switches to Hold or `COM_OBL_RC_ACT`'s mode.
//!
//! Failsafes (link, battery, geofence, crash, estimator and sensors) are decided by the
//! [`crate::safety`] state machine on every update and carried out here (Hold, Return, Land,
//! Descend, disarm); arming asks its [`crate::safety::preflight::preflight`] checks.

pub use denial::{ArmingDenial, Denial};
pub use follow_target::{STALE_S as FOLLOW_STALE_S, TargetEstimate, TargetFilter, TargetFix};
pub use input::{CommanderInput, Health, OffboardTarget, Sticks};
pub use orbit::{
    OrbitRequest, OrbitStatus, OrbitYaw, SPEED_MAX_M_S as ORBIT_SPEED_MAX_M_S, speed_bound_m_s,
};
pub use params::{COMMANDER_META, CommanderParams};
pub use status::{CommanderStatus, FlightMode, LandedState};

use crate::control::position::PositionSetpoint;
use crate::control::{GroundContact, Setpoint};
use crate::safety::failsafe::{
    Condition, FailsafeAction, Safety, SafetyEvent, SafetyLog, SafetyParams,
};
use crate::safety::targets::TargetLimits;
use flight::{Flight, Tick, brake_point, hold_setpoint, spooled};
use nalgebra::Vector3;
use task::Task;

/// The commander.
#[derive(Debug, Clone, PartialEq)]
pub struct Commander {
    /// What outlives a mode: armed, landed, home, the mission, automatic flight's heading.
    flight: Flight,
    mode: FlightMode,
    /// The task flying `mode`.
    task: Task,
    /// When the mode was entered (s).
    since_s: f64,
    armed_at_s: f64,
    last: Option<CommanderInput>,
    /// The mode changed since the caller last asked (heartbeat "right after a mode change").
    changed: bool,
    /// The last sticks and the time they arrived (s, the commander's clock).
    sticks: Option<(Sticks, f64)>,
    /// How often manual control was lost in a manual mode (and Hold took over).
    manual_losses: u32,
    /// The last offboard set-point and the time it arrived (s, the commander's clock).
    offboard: Option<(OffboardTarget, f64)>,
    /// How often the offboard set-points were lost in Offboard.
    offboard_losses: u32,
    /// The failsafe state machine.
    safety: Safety,
    /// Its last decision's action and cause.
    failsafe: (FailsafeAction, Option<Condition>),
    /// Every arming check passed at the last update (checked there once, not per status read).
    prearm_ok: bool,
    /// What it said since the caller last asked.
    safety_events: Vec<SafetyEvent>,
    /// What it said, numbered, for readers of [`Commander::status`].
    safety_log: SafetyLog,
    /// The follow target's fixes, filtered.
    target: TargetFilter,
}

impl Commander {
    /// A disarmed commander in Loiter (Hold), PX4's default.
    pub fn new(params: CommanderParams) -> Self {
        Self {
            flight: Flight::new(params),
            mode: FlightMode::Loiter,
            task: Task::of(FlightMode::Loiter),
            since_s: 0.0,
            armed_at_s: 0.0,
            last: None,
            changed: false,
            sticks: None,
            manual_losses: 0,
            offboard: None,
            offboard_losses: 0,
            safety: Safety::new(SafetyParams::default()),
            failsafe: (FailsafeAction::None, None),
            prearm_ok: false,
            safety_events: Vec::new(),
            safety_log: SafetyLog::default(),
            target: TargetFilter::default(),
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
            .filter(|&(_, t)| self.now() - t <= self.flight.params.offboard_loss_s)
            .map(|(s, _)| s)
    }

    /// New stick positions (`MANUAL_CONTROL`), at the time of the last update.
    pub fn manual_control(&mut self, sticks: Sticks) {
        self.sticks = Some((sticks.clamped(), self.now()));
    }

    /// The sticks, if they arrived within `COM_RC_LOSS_T`.
    fn fresh_sticks(&self) -> Option<Sticks> {
        self.sticks
            .filter(|&(_, t)| self.now() - t <= self.flight.params.manual_loss_s)
            .map(|(s, _)| s)
    }

    /// The parameters.
    pub fn params(&self) -> &CommanderParams {
        &self.flight.params
    }

    /// Changes the parameters (a parameter set from a ground station); the flight in progress
    /// uses the new values from its next stage.
    pub fn set_params(&mut self, params: CommanderParams) {
        self.flight.params = params;
    }

    /// A new fence, judged at once against the last estimate: the arming check reads it
    /// before the next update.
    pub fn note_geofence_breached(&mut self, breached: bool) {
        if let Some(i) = self.last.as_mut() {
            i.health.geofence_breached = breached;
        }
    }

    /// The state as telemetry shows it.
    pub fn status(&self) -> CommanderStatus {
        let f = &self.flight;
        CommanderStatus {
            armed: f.armed,
            mode: self.mode,
            landed: f.land.state(),
            ground_contact: f.ground_contact,
            home: f.home,
            failsafe: self.mode == FlightMode::Descend || self.failsafe.0 > FailsafeAction::Warn,
            failsafe_action: match self.failsafe {
                (a, Some(c)) if a > FailsafeAction::None => Some((a, c)),
                _ => None,
            },
            ready: self.ready(),
            in_mode_s: self.last.map_or(0.0, |i| (i.t_s - self.since_s).max(0.0)),
            manual_losses: self.manual_losses,
            manual_control: self.sticks.map(|_| self.fresh_sticks().is_some()),
            offboard_losses: self.offboard_losses,
            mission: f.mission.status(),
            motor_failed: self.last.and_then(|i| i.health.motor_failed),
            spinning: self.last.is_some_and(|i| i.health.spinning),
            failsafe_conditions: self.safety.active_mask(),
            prearm_ok: !f.armed && self.prearm_ok,
            safety_log: self.safety_log,
            orbit: match &self.task {
                Task::Orbit(o) => Some(o.status()),
                _ => None,
            },
            follow: match self.mode {
                FlightMode::FollowTarget => self.follow_target(),
                _ => None,
            },
        }
    }

    /// Motors armed.
    pub fn armed(&self) -> bool {
        self.flight.armed
    }

    /// The flight mode.
    pub fn mode(&self) -> FlightMode {
        self.mode
    }

    /// On the ground, taking off, flying or landing.
    pub fn landed(&self) -> LandedState {
        self.flight.land.state()
    }

    /// Home position NED (m), once set: where the position first became valid on the ground,
    /// then where it armed (unless [`Commander::set_home`] set it).
    pub fn home(&self) -> Option<Vector3<f64>> {
        self.flight.home.map(|h| h.0)
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

    /// Enters `mode` with a fresh task.
    fn enter(&mut self, mode: FlightMode) {
        self.enter_with(mode, Task::of(mode));
    }

    /// Enters `mode`, flown by `task` from now on.
    fn enter_with(&mut self, mode: FlightMode, task: Task) {
        if mode != self.mode {
            self.changed = true;
        }
        if self.mode == FlightMode::Mission {
            self.flight.mission.left();
        }
        self.flight.yaw_goal = None;
        self.mode = mode;
        self.since_s = self.now();
        self.task = task;
        self.task.flight_task().activate(self.since_s);
    }

    /// Disarms. Refused in the air unless `force` (which stops the motors wherever it is).
    pub fn disarm(&mut self, force: bool) -> Result<(), Denial> {
        if !self.flight.armed {
            return Ok(());
        }
        if self.flight.land.state() != LandedState::OnGround && !force {
            return Err(Denial::InAir);
        }
        self.disarmed();
        Ok(())
    }

    /// The motors stopped (a touchdown, a forced disarm, the end of a failsafe): on the ground
    /// from now on, in Loiter unless the mode needs no flight (a failsafe's Descend ends here).
    pub fn disarmed(&mut self) {
        if self.flight.armed {
            self.changed = true;
            if let Task::Mission(m) = &mut self.task {
                m.motors_stopped(&mut self.flight.mission);
            }
        }
        self.flight.armed = false;
        self.flight.land.on_ground();
        if matches!(
            self.mode,
            FlightMode::Land
                | FlightMode::Rtl
                | FlightMode::Descend
                | FlightMode::Takeoff
                | FlightMode::Orbit
                | FlightMode::FollowTarget
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
        if self.mode == FlightMode::Descend && self.flight.armed {
            return Err(Denial::FailsafeDescent {
                command: "mode change",
            });
        }
        self.operator_takes_over()?;
        match mode {
            FlightMode::Takeoff | FlightMode::Loiter | FlightMode::Land => {}
            FlightMode::Rtl => {
                if self.flight.home.is_none() {
                    return Err(Denial::NoHome);
                }
            }
            FlightMode::Posctl
            | FlightMode::Altctl
            | FlightMode::Manual
            | FlightMode::Stabilized => {
                if self.fresh_sticks().is_none() {
                    return Err(Denial::NoManualControl(mode.name()));
                }
            }
            FlightMode::Offboard => {
                if self.fresh_offboard().is_none() {
                    let loss_s = self.flight.params.offboard_loss_s;
                    return Err(Denial::NoOffboardStream(loss_s));
                }
            }
            FlightMode::Mission => self.mission_entry()?,
            // Chosen without a command: about where it is, with the defaults.
            FlightMode::Orbit => return self.orbit(OrbitRequest::default()),
            FlightMode::FollowTarget => self.follow_entry()?,
            FlightMode::Descend => return Err(Denial::FailsafeMode),
        }
        if mode == FlightMode::Takeoff && self.flight.armed && !self.ready() {
            return Err(Denial::NotReady {
                command: "take-off",
            });
        }
        if mode == FlightMode::Takeoff && self.mode != FlightMode::Takeoff {
            // The mode selected by itself climbs to today's MIS_TAKEOFF_ALT.
            self.flight.takeoff_alt_m = self.flight.params.takeoff_alt_m;
        }
        self.enter(mode);
        Ok(())
    }

    /// A command of the operator's changes what the vehicle flies: a failsafe acting ends,
    /// unless it allows no take-over (then the command is refused).
    fn operator_takes_over(&mut self) -> Result<(), Denial> {
        if self.flight.armed && self.failsafe.0 > FailsafeAction::Warn {
            self.safety.take_over().map_err(Denial::FailsafeActing)?;
            self.failsafe = (FailsafeAction::None, None);
        }
        Ok(())
    }

    /// Take-off to `alt_above_home_m` (the parameter's altitude if `None`): switches to
    /// Takeoff; a disarmed vehicle climbs once armed.
    pub fn takeoff(&mut self, alt_above_home_m: Option<f64>) -> Result<(), Denial> {
        let alt = alt_above_home_m.unwrap_or(self.flight.params.takeoff_alt_m);
        self.target_limits()
            .check_height(alt)
            .map_err(|why| Denial::Target {
                command: "take-off",
                why,
            })?;
        if self.mode != FlightMode::Takeoff {
            self.set_mode(FlightMode::Takeoff)?;
        }
        // A repeated command (a retransmission) keeps the climb in progress.
        self.flight.takeoff_alt_m = alt;
        Ok(())
    }

    /// The limits on where a command or mission item may send the vehicle.
    pub fn target_limits(&self) -> TargetLimits {
        TargetLimits::new(self.safety.params())
    }

    /// Sets home to `pos_ned_m` (or to the current position if `None`): near the vehicle.
    pub fn set_home(&mut self, pos_ned_m: Option<Vector3<f64>>) -> Result<(), Denial> {
        let Some(i) = self.last else {
            return Err(Denial::NoPositionEstimate { command: "home" });
        };
        if let Some(p) = pos_ned_m {
            let current = self.flight.home.map_or(i.pos_ned_m, |h| h.0);
            self.target_limits()
                .check_home(&p, &i.pos_ned_m, &current)
                .map_err(|why| Denial::Target {
                    command: "home",
                    why,
                })?;
        }
        self.flight.set_home(pos_ned_m, &i)
    }

    /// The estimate is lost (sensors stopped, or it is unfit to fly on): on the ground the motors
    /// stop; in the air the vehicle descends (what flies it until they return is the caller's:
    /// see [`crate::safety::blind_descent::BlindDescent`]). Returns whether it is in the air.
    pub fn sensors_stopped(&mut self) -> bool {
        if !self.flight.armed {
            return false;
        }
        if self.flight.land.state() == LandedState::OnGround {
            self.disarmed();
            return false;
        }
        if self.mode != FlightMode::Descend {
            self.enter(FlightMode::Descend);
            self.flight.land.landing();
        }
        true
    }

    /// Advances; returns the set-point and whether the motors are armed.
    pub fn update(&mut self, i: &CommanderInput) -> (Setpoint, bool) {
        let p = self.flight.params;
        let dt = self.last.map_or(0.0, |l| (i.t_s - l.t_s).max(0.0));
        self.last = Some(*i);
        self.failsafes(i);
        self.prearm_ok = !self.flight.armed && self.preflight_failures(i).is_empty();
        if !i.ready {
            // The same reaction as to silent sensors, at this update's time.
            self.sensors_stopped();
        }
        let f = &mut self.flight;
        let yaw = f
            .auto_yaw
            .unwrap_or_else(|| f.home.map_or(i.yaw_rad, |h| h.1));
        if !f.armed {
            if f.home.is_none() && i.ready {
                // As PX4: home as soon as the position is valid on the ground (ground stations
                // and MAVSDK's health wait for it), then again at arming.
                f.home = Some((i.pos_ned_m, i.yaw_rad));
            }
            return (Setpoint::Position(hold_setpoint(i.pos_ned_m, yaw)), false);
        }
        let since_arming_s = i.t_s - self.armed_at_s;
        if f.land.state() == LandedState::OnGround
            && self.mode != FlightMode::Takeoff
            && p.disarm_preflight_s > 0.0
            && since_arming_s >= p.disarm_preflight_s
        {
            // PX4's COM_DISARM_PRFLT: armed and left on the ground.
            self.disarmed();
            return (Setpoint::Position(hold_setpoint(i.pos_ned_m, yaw)), false);
        }
        let tick = Tick {
            i,
            dt,
            home: f.home.map_or(i.pos_ned_m, |h| h.0),
            yaw,
            since_arming_s,
            sticks: self.fresh_sticks(),
            offboard: self.fresh_offboard(),
            target: self.follow_target(),
        };
        if let Some(sp) = self.stream_lost(&tick) {
            return (Setpoint::Position(sp), self.flight.armed);
        }
        self.flight.ground_contact = GroundContact::None;
        let sp = self.task.flight_task().update(&mut self.flight, &tick);
        if std::mem::take(&mut self.flight.touched_down) {
            self.disarmed();
        } else if self.task.flight_task().is_finished() {
            // A take-off done: Hold where it ended.
            let hold = self.task.held().map_or_else(
                || Task::of(FlightMode::Loiter),
                |at| Task::Hold(hold::Hold::at(at)),
            );
            self.enter_with(FlightMode::Loiter, hold);
        }
        (sp, self.flight.armed)
    }

    /// The stream a mode flies on has stopped: the sticks (PX4's manual-control-loss
    /// failsafe: `NAV_RCL_ACT`'s mode) or the offboard set-points (`COM_OBL_RC_ACT`'s mode, a stick mode only
    /// with a joystick, else Hold). This update holds where braking stops the vehicle (on the
    /// ground: stays there, in Hold). `None`: the stream is there, or the mode needs none.
    fn stream_lost(&mut self, t: &Tick) -> Option<PositionSetpoint> {
        let next = match self.mode {
            FlightMode::Posctl
            | FlightMode::Altctl
            | FlightMode::Manual
            | FlightMode::Stabilized
                if t.sticks.is_none() =>
            {
                self.manual_losses += 1;
                match self.flight.params.manual_loss_action {
                    2 if self.flight.home.is_some() => FlightMode::Rtl,
                    3 => FlightMode::Land,
                    _ => FlightMode::Loiter,
                }
            }
            FlightMode::Offboard if t.offboard.is_none() => {
                self.offboard_losses += 1;
                let sticks = t.sticks.is_some();
                match self.flight.params.offboard_loss_action {
                    0 if sticks => FlightMode::Posctl,
                    1 if sticks => FlightMode::Altctl,
                    2 if sticks => FlightMode::Stabilized,
                    3 if self.flight.home.is_some() => FlightMode::Rtl,
                    4 => FlightMode::Land,
                    _ => FlightMode::Loiter,
                }
            }
            _ => return None,
        };
        if self.flight.land.state() == LandedState::OnGround {
            self.enter(FlightMode::Loiter);
            return Some(spooled(t.home, t.yaw));
        }
        self.enter(next);
        let at = brake_point(t.i, self.flight.params.accel_m_s2, t.yaw);
        self.task.hold_at(at);
        Some(hold_setpoint(at.0, at.1))
    }
}

mod arming;
mod corner;
mod denial;
mod descend;
mod failsafes;
mod flight;
mod follow_target;
mod guided;
mod hold;
mod input;
mod land;
mod land_detector;
mod line;
mod manual_position;
mod mission;
mod mission_run;
mod offboard;
mod orbit;
mod params;
pub mod rc_input;
mod rtl;
mod stabilized;
mod status;
mod takeoff;
mod task;
#[cfg(test)]
mod tests;
