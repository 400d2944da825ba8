//! The commander's Mission mode (PX4's AUTO.MISSION), and the guided commands that share its
//! machinery: `DO_REPOSITION` (Hold flies to a point), `DO_CHANGE_SPEED`, `CONDITION_YAW`.
//!
//! Each navigation item is a straight leg on the speed- and acceleration-limited profile of
//! [`Line`] (stopping at its end, so that the path between waypoints is the straight line and
//! the vehicle is within the acceptance radius when the profile arrives), then what the item
//! asks at its end (hold, loiter, land). `DO_*` items are done at once, in the same update.

use super::{Commander, FlightMode, LandedState, Line, wrap_pi};
use super::{CommanderInput, Denial};
use crate::control::position::PositionSetpoint;
use crate::mission::{
    MissionItem, MissionPoint, MissionState, MissionStatus, REACHED_KEPT, SpeedChange,
};
use nalgebra::Vector3;

/// Where the current item is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Stage {
    /// Not begun: the next update sets it up.
    Start,
    /// Climbing off the ground before the item (its own climb if it is a take-off).
    Takeoff,
    /// Flying the leg to `target` (NED, m).
    Leg { target: Vector3<f64> },
    /// At `target` until `until_s` (infinite: until told otherwise).
    Hold { target: Vector3<f64>, until_s: f64 },
    /// Descending to touch down.
    Land,
    /// Returning home (the RTL mode's stages).
    Rtl,
}

/// The uploaded mission and how far it has been flown.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct MissionRun {
    items: Vec<MissionItem>,
    current: usize,
    state: MissionState,
    /// Jumps done per item (for `DO_JUMP` repeats).
    jumps: Vec<u32>,
    pub(super) stage: Stage,
    reached_count: u32,
    reached_recent: [u16; REACHED_KEPT],
}

impl MissionRun {
    pub(super) fn new() -> Self {
        Self {
            items: Vec::new(),
            current: 0,
            state: MissionState::NoMission,
            jumps: Vec::new(),
            stage: Stage::Start,
            reached_count: 0,
            reached_recent: [0; REACHED_KEPT],
        }
    }

    fn item(&self) -> Option<MissionItem> {
        self.items.get(self.current).copied()
    }

    /// The current item is done: report it, go to the next.
    fn reached(&mut self) {
        self.reached_recent[self.reached_count as usize % REACHED_KEPT] = self.current as u16;
        self.reached_count += 1;
        self.current += 1;
        self.stage = Stage::Start;
        if self.current >= self.items.len() {
            self.state = MissionState::Complete;
        }
    }

    /// Back to the first item, jump counters cleared.
    fn restart(&mut self) {
        self.current = 0;
        self.jumps.iter_mut().for_each(|j| *j = 0);
        self.stage = Stage::Start;
        self.state = if self.items.is_empty() {
            MissionState::NoMission
        } else {
            MissionState::NotStarted
        };
    }

    pub(super) fn status(&self) -> MissionStatus {
        let total = self.items.len() as u16;
        MissionStatus {
            // Past the last item once complete, as MISSION_CURRENT says it.
            current: if self.state == MissionState::Complete {
                total
            } else {
                (self.current as u16).min(total.saturating_sub(1))
            },
            total,
            state: self.state,
            reached_count: self.reached_count,
            reached_recent: self.reached_recent,
        }
    }

    /// Leaving Mission mode before the end pauses it.
    pub(super) fn left(&mut self) {
        if self.state == MissionState::Active {
            self.state = MissionState::Paused;
        }
        self.stage = Stage::Start;
    }
}

impl Commander {
    /// The mission flown (as last set).
    pub fn mission_items(&self) -> &[MissionItem] {
        &self.mission.items
    }

    /// A new mission (an upload finished): replaces the old one and starts at its first item.
    /// Flying in Mission mode, the vehicle goes on with the new mission's first item; an empty
    /// mission there means Hold.
    pub fn set_mission(&mut self, items: Vec<MissionItem>) {
        self.mission.jumps = vec![0; items.len()];
        self.mission.items = items;
        self.mission.restart();
        if self.mode == FlightMode::Mission {
            if self.mission.items.is_empty() {
                self.enter(FlightMode::Loiter);
            } else {
                self.enter(FlightMode::Mission);
            }
        }
    }

    /// `MISSION_SET_CURRENT` / `DO_SET_MISSION_CURRENT`: go on at item `seq` (in Mission mode at
    /// once, else when Mission is entered). Jump counters start again.
    pub fn set_mission_current(&mut self, seq: u16) -> Result<(), Denial> {
        let n = self.mission.items.len();
        if seq as usize >= n {
            return Err(format!("mission item {seq} does not exist ({n} items)"));
        }
        self.mission.restart();
        self.mission.current = seq as usize;
        if self.mode == FlightMode::Mission {
            self.enter(FlightMode::Mission);
        }
        Ok(())
    }

    /// `MAV_CMD_MISSION_START`: Mission mode from item `first` (or where it stands).
    pub fn start_mission(&mut self, first: Option<u16>) -> Result<(), Denial> {
        if let Some(seq) = first {
            self.set_mission_current(seq)?;
        }
        self.set_mode(FlightMode::Mission)
    }

    /// The mission's progress.
    pub fn mission_status(&self) -> MissionStatus {
        self.mission.status()
    }

    /// Whether Mission mode may be entered now, and the mission set up to start or resume.
    pub(super) fn mission_entry(&mut self) -> Result<(), Denial> {
        if self.mission.items.is_empty() {
            return Err("MISSION refused: no mission uploaded".into());
        }
        if self.last.and_then(|i| i.origin).is_none() {
            return Err("MISSION refused: no global position yet".into());
        }
        if self.mission.state == MissionState::Complete {
            self.mission.restart();
        }
        Ok(())
    }

    /// `DO_CHANGE_SPEED`: the horizontal speed of automatic flight from now on (the leg in
    /// progress too).
    pub fn change_speed(&mut self, change: SpeedChange) -> Result<(), Denial> {
        let speed_m_s = match change {
            SpeedChange::To(s) if s.is_finite() && s > 0.0 => Some(s),
            SpeedChange::To(s) => return Err(format!("speed {s} m/s refused")),
            SpeedChange::Default => None,
            SpeedChange::Unchanged => return Ok(()),
        };
        self.speed_override = speed_m_s.map(|s| s.min(20.0));
        // The horizontal leg in progress too (not a take-off's or a landing's climb).
        if let Some(line) = self.line.filter(|l| l.dir.xy().norm() > 0.5) {
            let speed = self
                .leg(line.from, line.from + line.dir * line.length)
                .speed;
            if let Some(l) = self.line.as_mut() {
                l.speed = speed;
            }
        }
        Ok(())
    }

    /// `CONDITION_YAW`: turn to `yaw_rad` at `rate_rad_s` (or `MPC_YAWRAUTO_MAX`), in Hold and
    /// Mission while flying (in Mission until the next item).
    pub fn condition_yaw(&mut self, yaw_rad: f64, rate_rad_s: Option<f64>) -> Result<(), Denial> {
        if !matches!(self.mode, FlightMode::Loiter | FlightMode::Mission)
            || self.landed != LandedState::InAir
        {
            return Err("yaw command refused: flying in Hold or Mission only".into());
        }
        if !yaw_rad.is_finite() {
            return Err("yaw command refused: angle not finite".into());
        }
        let rate = rate_rad_s.filter(|r| r.is_finite() && *r > 0.0);
        self.yaw_goal = Some((wrap_pi(yaw_rad), rate));
        Ok(())
    }

    /// `DO_REPOSITION`: in the air, switch to Hold (when `change_mode`, or in Hold already) and
    /// fly to `target` (NED, m; a NaN part keeps the current one) at `speed_m_s` (or the cruise
    /// speed), turning to `yaw_rad` if given; then hold there.
    pub fn reposition(
        &mut self,
        target: Vector3<f64>,
        speed_m_s: Option<f64>,
        yaw_rad: Option<f64>,
        change_mode: bool,
    ) -> Result<(), Denial> {
        let Some(i) = self.last else {
            return Err("reposition refused: no position estimate yet".into());
        };
        if !self.armed || self.landed != LandedState::InAir {
            return Err("reposition refused: not flying".into());
        }
        if !(change_mode || self.mode == FlightMode::Loiter) {
            return Err("reposition refused: not in Hold (and no mode change asked)".into());
        }
        if self.mode == FlightMode::Descend {
            return Err("reposition refused: failsafe descent in progress".into());
        }
        let mut to = self.hold.map_or(i.pos_ned_m, |h| h.0);
        for k in 0..3 {
            if target[k].is_finite() {
                to[k] = target[k];
            }
        }
        if let Some(s) = speed_m_s.filter(|s| s.is_finite() && *s > 0.0) {
            self.speed_override = Some(s.min(20.0));
        }
        self.enter(FlightMode::Loiter);
        let from = self.leg_start(&i);
        self.line = Some(self.leg(from, to));
        let yaw = self.auto_yaw.unwrap_or(i.yaw_rad);
        self.hold = Some((to, yaw));
        if let Some(y) = yaw_rad.filter(|y| y.is_finite()) {
            self.yaw_goal = Some((wrap_pi(y), None));
        }
        Ok(())
    }

    /// The horizontal speed of automatic flight.
    pub(super) fn cruise_speed(&self) -> f64 {
        self.speed_override.unwrap_or(self.params.cruise_speed_m_s)
    }

    /// A leg from `from` to `to` at the cruise speed, its vertical part no faster than
    /// `MPC_Z_V_AUTO_UP` / `MPC_Z_V_AUTO_DN`.
    pub(super) fn leg(&self, from: Vector3<f64>, to: Vector3<f64>) -> Line {
        let p = self.params;
        let d = to - from;
        let n = d.norm().max(1e-9);
        let (h, v) = (d.xy().norm() / n, d.z / n);
        let mut speed = if h > 1e-6 {
            self.cruise_speed() / h
        } else {
            f64::INFINITY
        };
        if v < -1e-6 {
            speed = speed.min(p.auto_climb_m_s / -v);
        } else if v > 1e-6 {
            speed = speed.min(p.auto_sink_m_s / v);
        }
        if !speed.is_finite() {
            speed = self.cruise_speed();
        }
        Line::new(from, to, speed, p.accel_m_s2)
    }

    /// Where a new leg starts: the set-point flown so far when the vehicle is near it (so that
    /// consecutive legs join), else the vehicle's position.
    fn leg_start(&self, i: &CommanderInput) -> Vector3<f64> {
        match self.hold {
            Some((p, _)) if (p - i.pos_ned_m).norm() < 2.0 => p,
            _ => i.pos_ned_m,
        }
    }

    /// The heading of automatic flight, turned towards `goal` (or the `CONDITION_YAW` goal) at
    /// most at `MPC_YAWRAUTO_MAX` (or the command's rate).
    pub(super) fn slew_yaw(&mut self, goal: Option<f64>, i: &CommanderInput, dt: f64) -> f64 {
        let (goal, rate) = match (self.yaw_goal, goal) {
            (Some((g, r)), _) => (Some(g), r),
            (None, g) => (g, None),
        };
        let rate = rate.unwrap_or(self.params.auto_yaw_rate_deg_s.to_radians());
        let yaw = self.auto_yaw.unwrap_or(i.yaw_rad);
        let yaw = match goal {
            Some(g) => wrap_pi(yaw + wrap_pi(g - yaw).clamp(-rate * dt, rate * dt)),
            None => yaw,
        };
        self.auto_yaw = Some(yaw);
        yaw
    }

    /// Mission mode: fly the current item; done items hand over to the next in the same update
    /// (`DO_*` items take no time). After the last item: hold (or stay on the ground).
    pub(super) fn mission_flight(
        &mut self,
        i: &CommanderInput,
        dt: f64,
        home: Vector3<f64>,
    ) -> PositionSetpoint {
        // Every item at most once per update: a `DO_JUMP` loop without a navigation item
        // between cannot spin here.
        for _ in 0..=self.mission.items.len() {
            let Some(item) = self.mission.item() else {
                break;
            };
            self.mission.state = MissionState::Active;
            if let MissionItem::Jump { to, repeat } = item {
                // Reported as reached, then continued at its target (or after it, once the
                // repeats are done).
                let done = &mut self.mission.jumps[self.mission.current];
                let jump = repeat.is_none_or(|r| *done < r);
                if jump {
                    *done += 1;
                }
                self.mission.reached();
                if jump {
                    self.mission.current = to as usize;
                    self.mission.state = MissionState::Active;
                }
                continue;
            }
            match self.mission_item(item, i, dt, home) {
                Some(sp) => {
                    self.hold = Some((sp.pos_ned_m, sp.yaw_rad));
                    return sp;
                }
                None => {
                    self.mission.reached();
                    self.line = None;
                    self.yaw_goal = None;
                }
            }
        }
        if self.mission.item().is_some() {
            // A loop of `DO_*` items only: hold where it is.
            return self.loiter(i, self.auto_yaw.unwrap_or(i.yaw_rad));
        }
        self.mission.state = MissionState::Complete;
        if self.landed == LandedState::OnGround {
            return self.spooled(i, i.yaw_rad);
        }
        let yaw = self.slew_yaw(None, i, dt);
        self.loiter(i, yaw)
    }

    /// One item: its set-point, or `None` when it is done.
    fn mission_item(
        &mut self,
        item: MissionItem,
        i: &CommanderInput,
        dt: f64,
        home: Vector3<f64>,
    ) -> Option<PositionSetpoint> {
        let p = self.params;
        let origin = i.origin?;
        let resolve = |m: &MissionPoint| m.to_ned(&origin, &home, &i.pos_ned_m);
        // Done at once.
        match item {
            MissionItem::ChangeSpeed(change) => {
                // Checked at upload: a speed the command would refuse cannot be here.
                let _ = self.change_speed(change);
                return None;
            }
            MissionItem::SetHome { at } => {
                // A home the estimate cannot give yet is skipped: the ground station sees home
                // unchanged (HOME_POSITION).
                let _ = self.set_home(at.map(|a| resolve(&a)));
                return None;
            }
            _ => {}
        }
        if self.mission.stage == Stage::Start {
            self.yaw_goal = None;
            self.mission.stage = self.begin_item(item, i, home, &resolve)?;
        }
        let item_yaw = match item {
            MissionItem::Waypoint { yaw_rad, .. }
            | MissionItem::Takeoff { yaw_rad, .. }
            | MissionItem::Land { yaw_rad, .. } => yaw_rad,
            _ => None,
        };
        match self.mission.stage {
            Stage::Start => None,
            Stage::Takeoff => {
                let yaw = self.auto_yaw.unwrap_or(i.yaw_rad);
                let line = self.line.as_mut()?;
                let goal = line.from.z - line.length;
                let (sp, arrived) = line.step(dt, yaw);
                self.landed = LandedState::Takeoff;
                if arrived && i.pos_ned_m.z - home.z <= 0.95 * (goal - home.z) {
                    self.landed = LandedState::InAir;
                    self.line = None;
                    // A take-off item is done when its altitude is; any other item starts now.
                    if let MissionItem::Takeoff { at, .. } = item
                        && (sp.pos_ned_m.xy() - resolve(&at).xy()).norm() <= self.acceptance(&item)
                    {
                        return None;
                    }
                    self.mission.stage = Stage::Start;
                }
                Some(sp)
            }
            Stage::Leg { target } => {
                self.landed = LandedState::InAir;
                let line = self.line.as_mut()?;
                let along = (line.dir.xy().norm() > 0.5 && line.length - line.s > 1.0)
                    .then(|| line.dir.y.atan2(line.dir.x));
                let yaw = self.slew_yaw(item_yaw.or(along), i, dt);
                let (sp, arrived) = self.line.as_mut()?.step(dt, yaw);
                let off = i.pos_ned_m - target;
                let within =
                    off.xy().norm() <= self.acceptance(&item) && off.z.abs() <= p.alt_acceptance_m;
                if !(arrived && within) {
                    return Some(sp);
                }
                self.line = None;
                self.mission.stage = match item {
                    MissionItem::Waypoint { hold_s, .. } if hold_s > 0.0 => Stage::Hold {
                        target,
                        until_s: i.t_s + hold_s,
                    },
                    MissionItem::LoiterTime { time_s, .. } => Stage::Hold {
                        target,
                        until_s: i.t_s + time_s,
                    },
                    MissionItem::LoiterUnlimited { .. } => Stage::Hold {
                        target,
                        until_s: f64::INFINITY,
                    },
                    MissionItem::Land { .. } => {
                        self.land_xy = Some((target.x, target.y));
                        self.land_sp_down = None;
                        Stage::Land
                    }
                    _ => return None,
                };
                Some(sp)
            }
            Stage::Hold { target, until_s } => {
                if i.t_s >= until_s {
                    return None;
                }
                self.landed = LandedState::InAir;
                let yaw = self.slew_yaw(item_yaw, i, dt);
                Some(PositionSetpoint {
                    pos_ned_m: target,
                    vel_ned_m_s: Vector3::zeros(),
                    accel_ned_m_s2: Vector3::zeros(),
                    yaw_rad: yaw,
                })
            }
            Stage::Land => {
                let yaw = self.slew_yaw(item_yaw, i, dt);
                Some(self.land_at(i, dt, yaw))
            }
            Stage::Rtl => {
                let yaw = self.auto_yaw.unwrap_or(i.yaw_rad);
                Some(self.rtl(i, dt, yaw, home))
            }
        }
    }

    /// Sets up an item: its first stage (`None`: nothing to do, it is done).
    fn begin_item(
        &mut self,
        item: MissionItem,
        i: &CommanderInput,
        home: Vector3<f64>,
        resolve: &dyn Fn(&MissionPoint) -> Vector3<f64>,
    ) -> Option<Stage> {
        let p = self.params;
        if self.landed == LandedState::OnGround {
            if matches!(item, MissionItem::Land { .. } | MissionItem::ReturnToLaunch) {
                return None; // already down
            }
            // Every other item starts with a take-off: to a take-off item's altitude, else to
            // MIS_TAKEOFF_ALT.
            let down = match item {
                MissionItem::Takeoff { at, .. } => resolve(&at).z.min(home.z - 0.5),
                _ => home.z - p.takeoff_alt_m,
            };
            let from = Vector3::new(i.pos_ned_m.x, i.pos_ned_m.y, home.z);
            self.line = Some(Line::new(
                from,
                Vector3::new(from.x, from.y, down),
                p.takeoff_speed_m_s,
                p.accel_m_s2,
            ));
            self.landed = LandedState::Takeoff;
            return Some(Stage::Takeoff);
        }
        let target = match item {
            MissionItem::Waypoint { at, .. }
            | MissionItem::Takeoff { at, .. }
            | MissionItem::LoiterTime { at, .. }
            | MissionItem::LoiterUnlimited { at } => resolve(&at),
            MissionItem::Land { at, .. } => {
                // Over the point at the altitude it is flying, then down.
                let mut t = resolve(&at);
                t.z = i.pos_ned_m.z;
                t
            }
            MissionItem::Delay { delay_s } => {
                return Some(Stage::Hold {
                    target: self.leg_start(i),
                    until_s: i.t_s + delay_s,
                });
            }
            MissionItem::ReturnToLaunch => {
                self.rtl = super::RtlStage::Climb;
                self.line = None;
                self.land_xy = None;
                self.land_sp_down = None;
                return Some(Stage::Rtl);
            }
            _ => return None,
        };
        let from = self.leg_start(i);
        self.line = Some(self.leg(from, target));
        Some(Stage::Leg { target })
    }

    /// An item's horizontal acceptance radius (m).
    fn acceptance(&self, item: &MissionItem) -> f64 {
        match item {
            MissionItem::Waypoint {
                acceptance_m: Some(r),
                ..
            } => *r,
            _ => self.params.acceptance_m,
        }
    }

    /// The touchdown at the end of a Land or RTL item of the mission: that item is done.
    pub(super) fn mission_landed(&mut self) {
        if self.mode == FlightMode::Mission
            && matches!(self.mission.stage, Stage::Land | Stage::Rtl)
        {
            self.mission.reached();
            self.line = None;
        }
    }
}
