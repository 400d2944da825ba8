//! The RC transmitter flying the vehicle, as PX4's commander takes it: its sticks into the
//! commander (shared with a ground station's joystick by `COM_RC_IN_MODE`), its mode switch
//! entering `COM_FLTMODEn`'s mode when it moves to slot n, its arm switch (or the stick
//! gesture) arming and disarming, and sticks moved beyond `COM_RC_STICK_OV` taking over from
//! an automatic mode into Position (`COM_RC_OVERRIDE`). A receiver in failsafe, or one that
//! stops, is lost sticks: after `COM_RC_LOSS_T` the commander flies `NAV_RCL_ACT`'s mode.

use super::Autopilot;
use crate::commander::rc_input::{Gesture, RcFrame};
use crate::commander::{FlightMode, LandedState, Sticks};

/// Where sticks come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StickSource {
    Rc,
    Joystick,
}

/// The transmitter's state between frames.
#[derive(Debug, Clone, Default)]
pub(super) struct RcState {
    gesture: Gesture,
    /// The mode switch's slot and the arm switch, as last seen.
    slot: Option<usize>,
    arm_switch: Option<bool>,
    /// When each source last gave sticks (s).
    rc_at: Option<f64>,
    joystick_at: Option<f64>,
    /// `COM_RC_IN_MODE` 3: the source that came first, while it lasts.
    owner: Option<StickSource>,
    /// A ground station calibrates the radio: its channels are reported, not flown.
    calibrating: bool,
}

/// The last RC frame and when it came, for the ground stations (`RC_CHANNELS`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RcReport {
    /// The frame.
    pub frame: RcFrame,
    /// When it came (s, sensor time).
    pub t_s: f64,
}

impl Autopilot {
    /// The last step's time (s).
    fn now_s(&self) -> f64 {
        self.last_answer
            .as_ref()
            .map_or(0.0, |a| a.t_usec as f64 * 1e-6)
    }

    fn sticks_fresh(&self, at: Option<f64>, t_s: f64) -> bool {
        at.is_some_and(|a| t_s - a <= self.commander.params().manual_loss_s)
    }

    /// Whether sticks from `source` fly now (`COM_RC_IN_MODE`), noting the owner.
    fn sticks_from(&mut self, source: StickSource, t_s: f64) -> bool {
        let rc_fresh = self.sticks_fresh(self.rc.rc_at, t_s);
        let joystick_fresh = self.sticks_fresh(self.rc.joystick_at, t_s);
        match (self.params.rc.input_mode, source) {
            (0, StickSource::Rc) | (1, StickSource::Joystick) => true,
            (2, StickSource::Rc) => true,
            (2, StickSource::Joystick) => !rc_fresh,
            (3, _) => {
                let owner_fresh = match self.rc.owner {
                    Some(StickSource::Rc) => rc_fresh,
                    Some(StickSource::Joystick) => joystick_fresh,
                    None => false,
                };
                if !owner_fresh {
                    self.rc.owner = Some(source);
                }
                self.rc.owner == Some(source)
            }
            _ => false,
        }
    }

    /// A ground station's joystick (`MANUAL_CONTROL`) at the last step's time.
    pub(super) fn joystick(&mut self, sticks: Sticks) {
        let t_s = self.now_s();
        if self.sticks_from(StickSource::Joystick, t_s) {
            self.commander.manual_control(sticks);
        }
        self.rc.joystick_at = Some(t_s);
    }

    /// The radio calibration starts: RC input off until it ends (refused armed).
    pub(super) fn calibrate_radio(&mut self) -> Result<(), crate::commander::Denial> {
        self.may_calibrate()?;
        self.rc.calibrating = true;
        tracing::info!("radio calibration: RC input off until it ends");
        Ok(())
    }

    /// The radio calibration ends (or none ran).
    pub(super) fn end_radio_calibration(&mut self) {
        if std::mem::take(&mut self.rc.calibrating) {
            tracing::info!("radio calibration over: RC input on");
        }
    }

    /// The radio is being calibrated.
    pub(super) fn calibrating_radio(&self) -> bool {
        self.rc.calibrating
    }

    /// One frame from the RC receiver at `t_s`.
    pub(super) fn rc_frame(&mut self, t_s: f64, frame: &RcFrame) {
        self.published.rc = Some(RcReport { frame: *frame, t_s });
        if self.rc.calibrating || frame.failsafe || !self.sticks_from(StickSource::Rc, t_s) {
            return;
        }
        self.rc.rc_at = Some(t_s);
        let rc = &self.params.rc;
        let demand = rc.demand(frame);
        let slot_mode = demand.mode_slot.and_then(|s| rc.slot_mode(s));
        let gesture_arms = rc.gesture == 1 && rc.map_arm == 0;
        self.commander.manual_control(demand.sticks);
        if demand.mode_slot != self.rc.slot {
            self.rc.slot = demand.mode_slot;
            if let Some(mode) = slot_mode {
                {
                    let r = self.commander.set_mode(mode);
                    self.rc_says("mode switch", r)
                };
            }
        }
        if demand.arm_switch != self.rc.arm_switch {
            let first = self.rc.arm_switch.is_none();
            self.rc.arm_switch = demand.arm_switch;
            // A switch found on at start does not arm: it must be moved there.
            match demand.arm_switch {
                Some(true) if !first => {
                    let r = self.commander.arm(false);
                    self.rc_says("arm switch", r)
                }
                Some(false) if self.commander.landed() != LandedState::InAir => {
                    {
                        let r = self.commander.disarm(false);
                        self.rc_says("arm switch", r)
                    };
                }
                _ => {}
            }
        }
        let gesture = self.rc.gesture.update(t_s, &demand.sticks);
        if gesture_arms {
            match gesture {
                Some(true) => {
                    let r = self.commander.arm(false);
                    self.rc_says("arm gesture", r)
                }
                Some(false) if self.commander.landed() != LandedState::InAir => {
                    {
                        let r = self.commander.disarm(false);
                        self.rc_says("disarm gesture", r)
                    };
                }
                _ => {}
            }
        }
        self.stick_override(&demand.sticks);
    }

    /// Sticks moved beyond `COM_RC_STICK_OV` in an automatic mode: Position takes over.
    fn stick_override(&mut self, s: &Sticks) {
        let (override_modes, override_pct) =
            (self.params.rc.override_modes, self.params.rc.override_pct);
        let mode = self.commander.mode();
        let overridable = match mode {
            FlightMode::Offboard => override_modes & 2 != 0,
            FlightMode::Loiter
            | FlightMode::Mission
            | FlightMode::Rtl
            | FlightMode::Land
            | FlightMode::Takeoff
            | FlightMode::Orbit
            | FlightMode::FollowTarget => override_modes & 1 != 0,
            _ => false,
        };
        let moved = s.forward.abs().max(s.right.abs()).max(s.yaw.abs()) > override_pct / 100.0;
        if overridable && moved && self.commander.landed() == LandedState::InAir {
            {
                let r = self.commander.set_mode(FlightMode::Posctl);
                self.rc_says("stick override", r)
            };
        }
    }

    fn rc_says(&self, what: &str, result: Result<(), crate::commander::Denial>) {
        match result {
            Ok(()) => tracing::info!(mode = self.commander.mode().name(), "RC {what}"),
            Err(e) => tracing::warn!("RC {what}: {e}"),
        }
    }
}
