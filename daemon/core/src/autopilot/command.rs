//! What a ground station (or the operator) asks of the autopilot, and how it is carried out
//! or refused.

use super::Autopilot;
use crate::commander::{
    ArmingDenial, Denial, FlightMode, OffboardTarget, OrbitRequest, OrbitYaw, Sticks, TargetFix,
};
use crate::math::geo::{LatLonAlt, LocalFrame};
use crate::mission::{MissionItem, MissionPoint, SpeedChange};
use crate::safety::failure_injection::{Injection, Refusal};
use crate::safety::geofence::{FenceMonitor, GeoZone, Geofence};
use crate::safety::targets::{TargetError, check_point, global_to_ned};
use crate::sample::StepOutput;
use crate::sensors::imu_calibrator::ImuCalKind;
use nalgebra::Vector3;

/// What a ground station (or the operator) asks of the autopilot.
#[derive(Debug, Clone, PartialEq)]
pub enum AutopilotCommand {
    /// Arm; `force` skips the estimator check.
    Arm {
        /// Skip what may be skipped.
        force: bool,
    },
    /// Disarm; `force` also in the air.
    Disarm {
        /// Also in the air.
        force: bool,
    },
    /// Switch flight mode.
    SetMode(FlightMode),
    /// Take off to this altitude above home (m), or the parameter's.
    Takeoff(Option<f64>),
    /// Take off to this altitude above mean sea level (m), as `MAV_CMD_NAV_TAKEOFF` param7
    /// does in PX4: at least the parameter's altitude above home.
    TakeoffAmsl(f64),
    /// Set home here (NED, m), or at the current position.
    SetHome(Option<Vector3<f64>>),
    /// Set home at this global position.
    SetHomeGlobal(LatLonAlt),
    /// Stick positions (`MANUAL_CONTROL`); never answered.
    Sticks(Sticks),
    /// An offboard set-point (`SET_POSITION_TARGET_*`, `SET_ATTITUDE_TARGET`); never answered.
    Offboard(OffboardTarget),
    /// A new mission (an upload finished, or a clear); never answered.
    SetMission(Vec<MissionItem>),
    /// A new geofence (an upload finished, or a clear); never answered.
    SetFence(Vec<GeoZone>),
    /// Go on at this mission item.
    SetMissionCurrent(u16),
    /// Mission mode, from this item if given (`MAV_CMD_MISSION_START`).
    StartMission(Option<u16>),
    /// The speed of automatic flight (`DO_CHANGE_SPEED`).
    ChangeSpeed(SpeedChange),
    /// Turn (`CONDITION_YAW`): to `angle_deg`, or by it when `relative` (clockwise for
    /// `direction` ≥ 0, counter-clockwise for −1), at `rate_deg_s` or the automatic rate.
    ConditionYaw {
        /// The heading, or the turn (deg).
        angle_deg: f64,
        /// The turn rate (deg/s).
        rate_deg_s: Option<f64>,
        /// −1 counter-clockwise, 1 clockwise, 0 the shortest way (relative turns: clockwise).
        direction: i8,
        /// `angle_deg` is a turn from the current heading.
        relative: bool,
    },
    /// Circle a point (`DO_ORBIT`); what is left open keeps the orbit flown, or starting one,
    /// the current position and the defaults.
    Orbit {
        /// The centre, the altitude the circle's.
        center: MissionPoint,
        /// Radius (m), positive clockwise.
        radius_m: Option<f64>,
        /// Tangential speed (m/s).
        speed_m_s: Option<f64>,
        /// Which way to face.
        yaw: Option<OrbitYaw>,
        /// Turns to fly before Hold (0: until another mode).
        turns: Option<f64>,
    },
    /// A fix of the follow target (`FOLLOW_TARGET`).
    FollowTarget {
        /// Where it is.
        at: LatLonAlt,
        /// Its velocity NED (m/s), if it reports one.
        vel_ned_m_s: Option<Vector3<f64>>,
    },
    /// Fly to a point and hold there (`DO_REPOSITION`).
    Reposition {
        /// Where; a part left open keeps the current one.
        at: MissionPoint,
        /// Horizontal speed (m/s), else the cruise speed.
        speed_m_s: Option<f64>,
        /// Heading (rad), else kept.
        yaw_rad: Option<f64>,
        /// Switch to Hold (else only in Hold already).
        change_mode: bool,
    },
    /// Make a motor or sensor fail, or work again (`MAV_CMD_INJECT_FAILURE`).
    InjectFailure(Injection),
    /// Start an onboard magnetometer calibration (`MAV_CMD_PREFLIGHT_CALIBRATION`, param2 1).
    CalibrateMag,
    /// Start an onboard gyro, accelerometer or level-horizon calibration
    /// (`MAV_CMD_PREFLIGHT_CALIBRATION` param1 1, param5 1 or 2).
    CalibrateImu(ImuCalKind),
    /// A ground station calibrates the radio (`MAV_CMD_PREFLIGHT_CALIBRATION` param4 1, as
    /// QGroundControl's radio setup sends): the RC channels are reported, not flown, until
    /// the calibration ends (every param 0), as PX4 disables RC input then.
    CalibrateRadio,
    /// Cancel a calibration under way (`MAV_CMD_PREFLIGHT_CALIBRATION`, every param 0).
    CancelCalibration,
}

impl Autopilot {
    /// Carries out a command, or says why not.
    pub fn command(&mut self, c: AutopilotCommand) -> Result<(), Denial> {
        let result = self.carry_out(c);
        self.publish();
        result
    }

    /// The command's work.
    fn carry_out(&mut self, c: AutopilotCommand) -> Result<(), Denial> {
        let arming = matches!(
            c,
            AutopilotCommand::Arm { .. }
                | AutopilotCommand::Takeoff(_)
                | AutopilotCommand::TakeoffAmsl(_)
                | AutopilotCommand::StartMission(_)
        );
        if arming && let Some(kind) = self.calibrating() {
            return Err(ArmingDenial::Calibrating(kind).into());
        }
        match c {
            AutopilotCommand::CalibrateMag => self.start_mag_calibration(),
            AutopilotCommand::CalibrateImu(kind) => self.start_imu_calibration(kind),
            AutopilotCommand::CalibrateRadio => self.calibrate_radio(),
            AutopilotCommand::CancelCalibration => {
                self.cancel_calibration();
                self.end_radio_calibration();
                Ok(())
            }
            AutopilotCommand::Arm { force } => self.commander.arm(force),
            AutopilotCommand::Disarm { force } => self.commander.disarm(force),
            AutopilotCommand::SetMode(m) => self.commander.set_mode(m),
            AutopilotCommand::Takeoff(alt) => self.commander.takeoff(alt),
            AutopilotCommand::SetHome(p) => self.commander.set_home(p),
            AutopilotCommand::Sticks(s) => {
                self.joystick(s);
                Ok(())
            }
            AutopilotCommand::InjectFailure(i) => self.inject_failure(i),
            AutopilotCommand::Offboard(t) => {
                self.commander.offboard_setpoint(t);
                Ok(())
            }
            AutopilotCommand::SetMission(items) => {
                self.commander.set_mission(items);
                Ok(())
            }
            AutopilotCommand::SetFence(zones) => {
                self.set_fence(zones);
                Ok(())
            }
            AutopilotCommand::SetMissionCurrent(seq) => self.commander.set_mission_current(seq),
            AutopilotCommand::StartMission(first) => self.commander.start_mission(first),
            AutopilotCommand::ChangeSpeed(change) => self.commander.change_speed(change),
            AutopilotCommand::ConditionYaw {
                angle_deg,
                rate_deg_s,
                direction,
                relative,
            } => self.condition_yaw(angle_deg, rate_deg_s, direction, relative),
            AutopilotCommand::TakeoffAmsl(amsl_m) => self.takeoff_amsl(amsl_m),
            AutopilotCommand::SetHomeGlobal(p) => {
                let (_, origin) = self.global("home")?;
                let home = global_to_ned(&p, &origin).map_err(target("home"))?;
                self.commander.set_home(Some(home))
            }
            AutopilotCommand::Reposition {
                at,
                speed_m_s,
                yaw_rad,
                change_mode,
            } => {
                let target = self.place("reposition", &at)?;
                let c = &mut self.commander;
                c.reposition(target, speed_m_s, yaw_rad, change_mode)
            }
            AutopilotCommand::FollowTarget { at, vel_ned_m_s } => {
                let command = "follow target";
                let (_, origin) = self.global(command)?;
                let pos = global_to_ned(&at, &origin).map_err(target(command))?;
                self.commander.follow_target_fix(TargetFix {
                    pos_ned_m: pos,
                    vel_ned_m_s,
                })
            }
            AutopilotCommand::Orbit {
                center,
                radius_m,
                speed_m_s,
                yaw,
                turns,
            } => {
                let c = self.place("orbit", &center)?;
                self.commander.orbit(OrbitRequest {
                    radius_m,
                    speed_m_s,
                    yaw,
                    turns,
                    center_ne_m: (!c.x.is_nan()).then(|| c.xy()),
                    center_down_m: (!c.z.is_nan()).then_some(c.z),
                })
            }
        }
    }

    /// A new geofence, placed in the estimator's frame once it has an origin.
    fn set_fence(&mut self, zones: Vec<GeoZone>) {
        let last = self.estimate();
        let origin = last.and_then(|o| o.translation.origin);
        self.fence = origin.map(|o| FenceMonitor::new(Geofence::new(&zones, &LocalFrame::new(o))));
        self.fence_zones = zones;
        // Judged now, not at the next step: an arm in the same batch of commands must meet
        // the new fence.
        if let (Some(f), Some(tr)) = (&self.fence, last.map(|e| e.translation)) {
            let outside = tr.horizontal_valid && !f.fence.allows(&tr.pos_ned_m.xy());
            self.commander.note_geofence_breached(outside);
        }
    }

    /// What a command naming a place on the Earth needs: the estimate and its origin, else
    /// `command` is refused.
    fn global(&self, command: &'static str) -> Result<(StepOutput, LatLonAlt), Denial> {
        let last = self.estimate();
        match (last, last.and_then(|o| o.translation.origin)) {
            (Some(out), Some(origin)) => Ok((out, origin)),
            _ => Err(Denial::NoGlobalPosition { command }),
        }
    }

    /// A mission point of `command` in the estimator's frame (NED, m; what it leaves open NaN,
    /// kept by the commander), its altitude taken from home.
    fn place(&self, command: &'static str, at: &MissionPoint) -> Result<Vector3<f64>, Denial> {
        let (out, origin) = self.global(command)?;
        check_point(at).map_err(target(command))?;
        let home = self.commander.home().unwrap_or(out.translation.pos_ned_m);
        Ok(at.to_ned(&origin, &home, &Vector3::repeat(f64::NAN)))
    }

    /// `CONDITION_YAW`: to `angle_deg`, or by it when `relative` (clockwise for `direction`
    /// ≥ 0), at `rate_deg_s` or the automatic rate.
    fn condition_yaw(
        &mut self,
        angle_deg: f64,
        rate_deg_s: Option<f64>,
        direction: i8,
        relative: bool,
    ) -> Result<(), Denial> {
        let yaw = self
            .estimate()
            .and_then(|o| o.attitude)
            .map_or(0.0, |a| a.euler_rad.2);
        let target = if relative {
            yaw + angle_deg.to_radians() * if direction < 0 { -1.0 } else { 1.0 }
        } else {
            angle_deg.to_radians()
        };
        self.commander
            .condition_yaw(target, rate_deg_s.map(f64::to_radians))
    }

    /// A failure injected, if `SYS_FAILURE_EN` allows it.
    fn inject_failure(&mut self, i: Injection) -> Result<(), Denial> {
        if !self.injection_enabled {
            return Err(Refusal::Disabled.into());
        }
        let said = self.injected.inject(i)?;
        tracing::warn!("{said}");
        Ok(())
    }

    /// Take-off to an altitude above mean sea level: at least the parameter's above home.
    fn takeoff_amsl(&mut self, amsl_m: f64) -> Result<(), Denial> {
        let (out, origin) = self.global("take-off")?;
        let c = &mut self.commander;
        let home_down = c.home().map_or(out.translation.pos_ned_m.z, |h| h.z);
        let home_amsl = origin.alt_m - home_down;
        let above_home = (amsl_m - home_amsl).max(c.params().takeoff_alt_m);
        c.takeoff(Some(above_home))
    }
}

/// A target refused for `command`.
fn target(command: &'static str) -> impl Fn(TargetError) -> Denial {
    move |why| Denial::Target { command, why }
}
