//! The commands that change what automatic flight does without a mode of their own: the
//! mission (upload, current item, start), `DO_REPOSITION` (Hold flies to a point),
//! `DO_CHANGE_SPEED` and `CONDITION_YAW`.

use super::flight::wrap_pi;
use super::hold::Hold;
use super::task::Task;
use super::{Commander, Denial, FlightMode, LandedState};
use crate::mission::{MissionItem, MissionState, MissionStatus, SpeedChange};
use crate::safety::targets::check_mission;
use nalgebra::Vector3;

impl Commander {
    /// The mission flown (as last set).
    pub fn mission_items(&self) -> &[MissionItem] {
        &self.flight.mission.items
    }

    /// A new mission (an upload finished): replaces the old one and starts at its first item.
    /// Flying in Mission mode, the vehicle goes on with the new mission's first item; an empty
    /// mission there means Hold.
    pub fn set_mission(&mut self, items: Vec<MissionItem>) {
        let run = &mut self.flight.mission;
        run.jumps = vec![0; items.len()];
        run.items = items;
        run.restart();
        if self.mode == FlightMode::Mission {
            if self.flight.mission.items.is_empty() {
                self.enter(FlightMode::Loiter);
            } else {
                self.enter(FlightMode::Mission);
            }
        }
    }

    /// `MISSION_SET_CURRENT` / `DO_SET_MISSION_CURRENT`: go on at item `seq` (in Mission mode at
    /// once, else when Mission is entered). Jump counters start again.
    pub fn set_mission_current(&mut self, seq: u16) -> Result<(), Denial> {
        let run = &mut self.flight.mission;
        let n = run.items.len();
        if seq as usize >= n {
            return Err(Denial::NoMissionItem { seq, count: n });
        }
        run.restart();
        run.current = seq as usize;
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
        self.flight.mission.status()
    }

    /// Whether Mission mode may be entered now, and the mission set up to start or resume.
    pub(super) fn mission_entry(&mut self) -> Result<(), Denial> {
        if self.flight.mission.items.is_empty() {
            return Err(Denial::NoMission);
        }
        let Some((origin, here)) = self.last.and_then(|i| Some((i.origin?, i.pos_ned_m))) else {
            return Err(Denial::NoGlobalPosition { command: "MISSION" });
        };
        let home = self.flight.home.map_or(here, |h| h.0);
        let items = &self.flight.mission.items;
        check_mission(items, &self.target_limits(), &origin, &home)
            .map_err(|(item, why)| Denial::MissionItem { item, why })?;
        if self.flight.mission.state == MissionState::Complete {
            self.flight.mission.restart();
        }
        Ok(())
    }

    /// `DO_CHANGE_SPEED`: the horizontal speed of automatic flight from now on (the leg in
    /// progress too).
    pub fn change_speed(&mut self, change: SpeedChange) -> Result<(), Denial> {
        self.flight.change_speed(change, self.task.line_mut())
    }

    /// `CONDITION_YAW`: turn to `yaw_rad` at `rate_rad_s` (or `MPC_YAWRAUTO_MAX`), in Hold and
    /// Mission while flying (in Mission until the next item).
    pub fn condition_yaw(&mut self, yaw_rad: f64, rate_rad_s: Option<f64>) -> Result<(), Denial> {
        if !matches!(self.mode, FlightMode::Loiter | FlightMode::Mission)
            || self.flight.land.state() != LandedState::InAir
        {
            return Err(Denial::WrongMode {
                command: "yaw command",
                needs: "flying in Hold or Mission only",
            });
        }
        if !yaw_rad.is_finite() {
            return Err(Denial::NotFinite {
                command: "yaw command",
                what: "angle not finite",
            });
        }
        let rate = rate_rad_s.filter(|r| r.is_finite() && *r > 0.0);
        self.flight.yaw_goal = Some((wrap_pi(yaw_rad), rate));
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
            return Err(Denial::NoPositionEstimate {
                command: "reposition",
            });
        };
        if !self.flight.armed || self.flight.land.state() != LandedState::InAir {
            return Err(Denial::NotFlying {
                command: "reposition",
            });
        }
        if !(change_mode || self.mode == FlightMode::Loiter) {
            return Err(Denial::WrongMode {
                command: "reposition",
                needs: "not in Hold (and no mode change asked)",
            });
        }
        if self.mode == FlightMode::Descend {
            return Err(Denial::FailsafeDescent {
                command: "reposition",
            });
        }
        let mut to = self.task.held().map_or(i.pos_ned_m, |h| h.0);
        for k in 0..3 {
            if target[k].is_finite() {
                to[k] = target[k];
            }
        }
        // Only the parts the command sets: a kept one may be outside a limit lowered since.
        let home = self.flight.home.map_or(i.pos_ned_m, |h| h.0);
        self.target_limits()
            .check_target(&target, &home)
            .map_err(|why| Denial::Target {
                command: "reposition",
                why,
            })?;
        self.operator_takes_over()?;
        if let Some(s) = speed_m_s.filter(|s| s.is_finite() && *s > 0.0) {
            self.flight.speed_override = Some(s.min(20.0));
        }
        let leg = self.flight.leg(i.pos_ned_m, to);
        let yaw = self.flight.auto_yaw.unwrap_or(i.yaw_rad);
        self.enter_with(
            FlightMode::Loiter,
            Task::Hold(Hold::after(Some(leg), (to, yaw))),
        );
        if let Some(y) = yaw_rad.filter(|y| y.is_finite()) {
            self.flight.yaw_goal = Some((wrap_pi(y), None));
        }
        Ok(())
    }
}
