//! Mission mode (PX4's AUTO.MISSION): each navigation item is a straight leg on the speed- and
//! acceleration-limited profile of [`Line`] (so that the path between waypoints is the straight
//! line), then what the item asks at its end (hold, loiter, land, return). A waypoint with no
//! hold and no heading of its own that another waypoint follows is flown through on the arc of
//! a [`Corner`]: its leg ends where the arc begins, at the arc's speed, and the next leg starts
//! where it ends. Every other leg stops at its end, with the vehicle within the acceptance radius. `DO_*`
//! items are done at once, in the same update. After the last item it holds (or stays on the
//! ground).

use super::LandedState;
use super::corner::Corner;
use super::flight::{Flight, Tick, hold_setpoint, loiter, spooled};
use super::land::Landing;
use super::line::Line;
use super::mission_run::MissionRun;
use super::rtl::Rtl;
use super::task::FlightTask;
use crate::commander::CommanderInput;
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use crate::mission::{MissionItem, MissionPoint, MissionState};
use nalgebra::Vector3;

/// Where the current item is.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
enum Stage {
    /// Not begun: the next update sets it up.
    #[default]
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

/// Flying the mission.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct MissionFlight {
    stage: Stage,
    line: Option<Line>,
    /// The set-point flown last (where a new leg joins), then held after the last item.
    hold: Option<(Vector3<f64>, f64)>,
    landing: Landing,
    rtl: Rtl,
    /// The corner flown at the start of the current leg (handed on by the last one).
    arc: Option<Corner>,
    /// The corner at the end of the current leg, flown through rather than stopped at.
    corner: Option<Corner>,
}

impl MissionFlight {
    /// The leg being flown, if any.
    pub(super) fn line_mut(&mut self) -> Option<&mut Line> {
        match self.stage {
            Stage::Rtl => self.rtl.line_mut(),
            _ => self.line.as_mut(),
        }
    }

    /// The set-point flown last.
    pub(super) fn held(&self) -> Option<(Vector3<f64>, f64)> {
        self.hold
    }

    /// The motors stopped (a touchdown, or a disarm) during a Land or RTL item: that item is
    /// done.
    pub(super) fn motors_stopped(&mut self, run: &mut MissionRun) {
        if matches!(self.stage, Stage::Land | Stage::Rtl) {
            self.reached(run);
        }
    }

    /// The current item is done: on to the next.
    fn reached(&mut self, run: &mut MissionRun) {
        run.reached();
        self.stage = Stage::Start;
        self.line = None;
    }

    /// Where a new leg starts: the set-point flown so far when the vehicle is near it (so that
    /// consecutive legs join), else the vehicle's position.
    fn leg_start(&self, i: &CommanderInput) -> Vector3<f64> {
        match self.hold {
            Some((p, _)) if (p - i.pos_ned_m).norm() < 2.0 => p,
            _ => i.pos_ned_m,
        }
    }

    /// One item: its set-point, or `None` when it is done.
    fn item(&mut self, f: &mut Flight, t: &Tick, item: MissionItem) -> Option<PositionSetpoint> {
        let (i, dt, home) = (t.i, t.dt, t.home);
        let origin = i.origin?;
        let resolve = |m: &MissionPoint| m.to_ned(&origin, &home, &i.pos_ned_m);
        // Done at once.
        match item {
            MissionItem::ChangeSpeed(change) => {
                // Checked at upload: a speed the command would refuse cannot be here.
                let _ = f.change_speed(change, self.line_mut());
                return None;
            }
            MissionItem::SetHome { at } => {
                // A home the estimate cannot give yet is skipped: the ground station sees home
                // unchanged (HOME_POSITION).
                let _ = f.set_home(at.map(|a| resolve(&a)), i);
                return None;
            }
            _ => {}
        }
        if self.stage == Stage::Start {
            f.yaw_goal = None;
            self.stage = self.begin(f, t, item, &resolve)?;
        }
        let item_yaw = match item {
            MissionItem::Waypoint { yaw_rad, .. }
            | MissionItem::Takeoff { yaw_rad, .. }
            | MissionItem::Land { yaw_rad, .. } => yaw_rad,
            _ => None,
        };
        match self.stage {
            Stage::Start => None,
            Stage::Takeoff => {
                let yaw = f.auto_yaw.unwrap_or(i.yaw_rad);
                let line = self.line.as_mut()?;
                let goal = line.from.z - line.length;
                let (sp, arrived) = line.step(dt, yaw);
                f.land.climbing();
                if arrived && i.pos_ned_m.z - home.z <= 0.95 * (goal - home.z) {
                    f.land.airborne();
                    self.line = None;
                    // A take-off item is done when its altitude is; any other item starts now.
                    if let MissionItem::Takeoff { at, .. } = item
                        && (sp.pos_ned_m.xy() - resolve(&at).xy()).norm() <= acceptance(f, &item)
                    {
                        return None;
                    }
                    self.stage = Stage::Start;
                }
                Some(sp)
            }
            Stage::Leg { target } => self.leg(f, t, item, item_yaw, target),
            Stage::Hold { target, until_s } => {
                if i.t_s >= until_s {
                    return None;
                }
                f.land.airborne();
                let yaw = f.slew_yaw(item_yaw, i, dt);
                Some(hold_setpoint(target, yaw))
            }
            Stage::Land => {
                let yaw = f.slew_yaw(item_yaw, i, dt);
                Some(self.landing.step(f, i, dt, yaw))
            }
            Stage::Rtl => {
                let yaw = f.auto_yaw.unwrap_or(i.yaw_rad);
                Some(self.rtl.fly(f, i, dt, yaw, home))
            }
        }
    }

    /// A leg to `target`: along its line (or through a corner's arc), then what the item does
    /// there (hold, loiter, land), or `None` when it is done.
    fn leg(
        &mut self,
        f: &mut Flight,
        t: &Tick,
        item: MissionItem,
        item_yaw: Option<f64>,
        target: Vector3<f64>,
    ) -> Option<PositionSetpoint> {
        let (p, i, dt) = (f.params, t.i, t.dt);
        f.land.airborne();
        if let Some(arc) = self.arc.as_mut() {
            let yaw = f.slew_yaw(item_yaw, i, dt);
            let (sp, done) = arc.step(dt, yaw);
            if done {
                self.arc = None;
            }
            return Some(sp);
        }
        let line = self.line.as_mut()?;
        let along = (line.dir.xy().norm() > 0.5 && line.length - line.s > 1.0)
            .then(|| line.dir.y.atan2(line.dir.x));
        let yaw = f.slew_yaw(item_yaw.or(along), i, dt);
        let (sp, arrived) = self.line.as_mut()?.step(dt, yaw);
        let off = i.pos_ned_m - target;
        let within = off.xy().norm() <= acceptance(f, &item) && off.z.abs() <= p.alt_acceptance_m;
        if let Some(corner) = self.corner.filter(|_| arrived) {
            // Through the corner: reached as the arc begins, the vehicle about the
            // waypoint (within the acceptance radius of it or of the arc's start).
            let near = (i.pos_ned_m - corner.start).xy().norm() <= acceptance(f, &item);
            if within || near {
                self.line = None;
                self.corner = None;
                self.arc = Some(corner);
                return None;
            }
        }
        if !(arrived && within) {
            return Some(sp);
        }
        self.line = None;
        self.stage = match item {
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
                self.landing = Landing::over((target.x, target.y));
                Stage::Land
            }
            _ => return None,
        };
        Some(sp)
    }

    /// Sets up an item: its first stage (`None`: nothing to do, it is done).
    fn begin(
        &mut self,
        f: &mut Flight,
        t: &Tick,
        item: MissionItem,
        resolve: &dyn Fn(&MissionPoint) -> Vector3<f64>,
    ) -> Option<Stage> {
        let (p, i, home) = (f.params, t.i, t.home);
        if !matches!(item, MissionItem::Waypoint { .. }) {
            self.arc = None; // a corner leads only onto a waypoint's leg
        }
        if f.land.state() == LandedState::OnGround {
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
            self.line = Some(f.climb(from, down));
            f.land.climbing();
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
                self.rtl = Rtl::default();
                self.line = None;
                return Some(Stage::Rtl);
            }
            _ => return None,
        };
        // A corner handed on by the last leg starts this one (only a waypoint's: cleared above
        // for any other item); the leg starts where the arc ends.
        let arc = self.arc;
        let from = arc.map_or_else(|| self.leg_start(i), |c| c.end);
        let mut leg = f.leg(from, target);
        let plain =
            matches!(item, MissionItem::Waypoint { hold_s, yaw_rad: None, .. } if hold_s <= 0.0);
        self.corner = self
            .next_waypoint(f, resolve)
            .filter(|_| plain)
            .and_then(|next| {
                let touch = acceptance(f, &item);
                Corner::new(from, target, next, touch, p.accel_m_s2, leg.speed)
            });
        if let Some(c) = &self.corner {
            leg = f.leg(from, c.start).passing_at(c.speed);
        }
        if let Some(c) = &arc {
            leg = leg.starting_at(c.speed);
        }
        self.line = Some(leg);
        Some(Stage::Leg { target })
    }

    /// Where the next navigation item after the current one goes, when it is a waypoint flown
    /// straight on to (past speed changes; not past a jump, whose target may be anything).
    fn next_waypoint(
        &self,
        f: &Flight,
        resolve: &dyn Fn(&MissionPoint) -> Vector3<f64>,
    ) -> Option<Vector3<f64>> {
        let run = &f.mission;
        for item in run.items.iter().skip(run.current + 1) {
            match item {
                MissionItem::ChangeSpeed(_) => continue,
                MissionItem::Waypoint { at, .. } => return Some(resolve(at)),
                _ => return None,
            }
        }
        None
    }
}

/// An item's horizontal acceptance radius (m).
fn acceptance(f: &Flight, item: &MissionItem) -> f64 {
    match item {
        MissionItem::Waypoint {
            acceptance_m: Some(r),
            ..
        } => *r,
        _ => f.params.acceptance_m,
    }
}

impl FlightTask for MissionFlight {
    /// The current item; done items hand over to the next in the same update (`DO_*` items
    /// take no time). After the last item: hold (or stay on the ground).
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        let i = t.i;
        // Every item at most once per update: a `DO_JUMP` loop without a navigation item
        // between cannot spin here.
        for _ in 0..=f.mission.items.len() {
            let Some(item) = f.mission.item() else {
                break;
            };
            f.mission.state = MissionState::Active;
            if let MissionItem::Jump { to, repeat } = item {
                // Reported as reached, then continued at its target (or after it, once the
                // repeats are done).
                let run = &mut f.mission;
                let done = &mut run.jumps[run.current];
                let jump = repeat.is_none_or(|r| *done < r);
                if jump {
                    *done += 1;
                }
                run.reached();
                self.stage = Stage::Start;
                if jump {
                    run.current = to as usize;
                    run.state = MissionState::Active;
                }
                continue;
            }
            match self.item(f, t, item) {
                Some(sp) => {
                    self.hold = Some((sp.pos_ned_m, sp.yaw_rad));
                    return Setpoint::Position(sp);
                }
                None => {
                    self.reached(&mut f.mission);
                    f.yaw_goal = None;
                }
            }
        }
        if f.mission.item().is_some() {
            // A loop of `DO_*` items only: hold where it is.
            let yaw = f.auto_yaw.unwrap_or(i.yaw_rad);
            return Setpoint::Position(loiter(&mut self.hold, f, i, yaw));
        }
        f.mission.state = MissionState::Complete;
        if f.land.state() == LandedState::OnGround {
            // Home as it stands now (a `DO_SET_HOME` item may have moved it in this update).
            let home = f.home.map_or(i.pos_ned_m, |h| h.0);
            return Setpoint::Position(spooled(home, i.yaw_rad));
        }
        let yaw = f.slew_yaw(None, i, t.dt);
        Setpoint::Position(loiter(&mut self.hold, f, i, yaw))
    }
}
