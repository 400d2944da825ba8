//! The autopilot's side of the HIL link: messages in, a flight-core step per sensor frame, the
//! `HIL_ACTUATOR_CONTROLS` answer out. The same for the embedded simulator and the UDP link.

use crate::failure_injection::{FailureInjector, Injection, Refusal};
use anyhow::{Context, Result};
use flight_core::commander::{
    Commander, CommanderInput, CommanderStatus, Denial, FlightMode, Health, LandedState,
    OffboardTarget, Sticks,
};
use flight_core::control::Setpoint;
use flight_core::control::position::PositionSetpoint;
use flight_core::core::{FlightCore, FlightCoreConfig, SensorSample, StepOutput};
use flight_core::estimator::translation::GpsMeasurement;
use flight_core::math::geo::{LatLonAlt, LocalFrame};
use flight_core::mission::{MissionItem, MissionPoint, SpeedChange};
use flight_core::params::FlightParams;
use flight_core::safety::blind_descent::{BlindDescent, HoverCommands};
use flight_core::safety::geofence::{FenceMonitor, GeoZone, Geofence};
use flight_core::sensors::battery::{BatteryConfig, BatteryEstimator, BatteryState};
use flight_core::sensors::mag_calibrator::{MagCalState, MagCalStatus, MagCalibrator};
use flight_core::sensors::mag_check::MagFieldMonitor;
use flight_core::sensors::monitor::SensorMonitor;
use hil::SensorUpdate;
use mavlink::dialects::common::MavMessage;
use nalgebra::Vector3;
use sitl_core::Airframe;

use crate::flight_csv::FlightCsv;
use crate::score::FlightScore;

/// A flight flown without a ground station (the command line's `--takeoff`): arm and take off
/// as soon as the estimator is ready, hold for `hover_s`, land; the daemon ends once disarmed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutoFlight {
    /// Take-off altitude above home (m).
    pub takeoff_m: f64,
    /// Time to hold before landing (s); infinite holds until told otherwise.
    pub hover_s: f64,
}

/// What other tasks ask the vehicle (ground-station commands, Ctrl-C).
#[derive(Debug, Clone, PartialEq)]
pub enum VehicleCommand {
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
    /// A ground station's heartbeat arrived; never answered (the control loop keeps its
    /// wall-clock time: see [`Vehicle::set_gcs_link_age`]).
    GcsHeartbeat,
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
    /// Cancel a calibration under way (`MAV_CMD_PREFLIGHT_CALIBRATION`, every param 0).
    CancelCalibration,
}

/// Logs how a magnetometer calibration ended, if it has.
fn log_calibration_end(s: &MagCalStatus) {
    match s.state {
        MagCalState::Collecting | MagCalState::Cancelled => {}
        MagCalState::Succeeded(r) => tracing::info!(
            samples = r.samples,
            coverage = r.coverage,
            residual = format!("{:.2} %", 100.0 * r.residual_rms),
            offset = ?r.offset.as_slice(),
            "magnetometer calibration done"
        ),
        MagCalState::Failed(f) => tracing::warn!("magnetometer calibration failed: {f}"),
    }
}

/// How far back the sensor clock must jump for the source to count as started again (s): more
/// than a lockstep resend or a serial line's backlog, less than any flight.
pub const SOURCE_RESTART_S: f64 = 1.0;
const SOURCE_RESTART_USEC: u64 = (SOURCE_RESTART_S * 1e6) as u64;

/// The vehicle: flight core, commander and what has arrived since the last frame.
pub struct Vehicle {
    core: FlightCore,
    commander: Commander,
    /// For new parameters: the configuration is derived from them and the airframe.
    airframe: Airframe,
    /// The parameters flown (to start afresh when the sensor source does).
    params: FlightParams,
    /// Times the sensor source started again from an earlier time.
    source_restarts: u32,
    /// The last sensor sample stepped on, set-point flown and ground truth received.
    last_sample: Option<SensorSample>,
    last_setpoint: Option<Setpoint>,
    last_truth: Option<hil::TruthReport>,
    auto: Option<AutoFlight>,
    /// The auto flight has armed, or an operator asked to end: the run ends once disarmed.
    end_when_disarmed: bool,
    /// Why the auto flight may not arm, as last said (said again only when it changes).
    auto_denial: Option<String>,
    ended: bool,
    update: SensorUpdate,
    last: Option<StepOutput>,
    last_answer: Option<(u64, MavMessage)>,
    repeated_frames: u64,
    rotors: usize,
    nominal_v: f64,
    score: FlightScore,
    csv: Option<FlightCsv>,
    csv_error: Option<std::io::Error>,
    /// How late the control loop woke for the frames it is stepping (deadline pacing only).
    loop_late: Option<std::time::Duration>,
    hover: HoverCommands,
    blind: Option<BlindDescent>,
    last_t_usec: u64,
    gps: Option<hil::GpsReport>,
    battery_v: f64,
    /// State of charge from the reported voltage and current.
    battery: BatteryEstimator,
    /// The uploaded fence, and the same placed in the estimator's frame once it has an origin.
    fence_zones: Vec<GeoZone>,
    fence: Option<FenceMonitor>,
    /// Wall-clock time since the last ground-station heartbeat (s), from the control loop.
    gcs_link_age_s: Option<f64>,
    /// Failures injected by `MAV_CMD_INJECT_FAILURE`, and whether that is allowed
    /// (`SYS_FAILURE_EN`).
    injected: FailureInjector,
    injection_enabled: bool,
    /// Silent and frozen sensors.
    monitor: SensorMonitor,
    /// The magnetometer's field at rest, for the arming checks.
    mag_field: MagFieldMonitor,
    /// When the IMU froze while armed (sensor time): the loops cannot fly without it, and it
    /// is not trusted again before the motors stop.
    imu_frozen_since_usec: Option<u64>,
    /// The last magnetometer calibration (under way or ended).
    mag_cal: Option<MagCalibrator>,
}

/// Magnetometer calibrations started in this process: each run's number, unique across the
/// vehicles a reboot or a restarted source makes, so the ground-station side never takes a new
/// run for one it has reported.
static MAG_CAL_RUNS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);

/// One step's result.
pub struct Step {
    /// The answer to send.
    pub message: MavMessage,
    /// The flight core's output.
    pub output: StepOutput,
    /// Time of the frame (s).
    pub t_s: f64,
}

impl Vehicle {
    /// A vehicle of `airframe`, flying `auto` on its own if given, else waiting for commands.
    pub fn new(
        airframe: &Airframe,
        params: &FlightParams,
        auto: Option<AutoFlight>,
    ) -> Result<Self> {
        let mut commander_params = params.commander;
        if let Some(a) = auto {
            commander_params.takeoff_alt_m = a.takeoff_m;
        }
        Ok(Self {
            core: FlightCore::new(airframe, FlightCoreConfig::from_params(params, airframe))
                .context("building the mixer")?,
            commander: {
                let mut c = Commander::new(commander_params);
                c.set_safety_params(params.safety);
                c
            },
            airframe: airframe.clone(),
            params: params.clone(),
            source_restarts: 0,
            last_sample: None,
            last_setpoint: None,
            last_truth: None,
            auto,
            end_when_disarmed: false,
            auto_denial: None,
            ended: false,
            update: SensorUpdate::default(),
            last: None,
            last_answer: None,
            repeated_frames: 0,
            rotors: airframe.rotors.len(),
            nominal_v: 3.8 * airframe.battery.cells as f64,
            score: FlightScore::new(commander_params.takeoff_alt_m),
            csv: None,
            csv_error: None,
            loop_late: None,
            hover: HoverCommands::new(2.0),
            blind: None,
            last_t_usec: 0,
            gps: None,
            battery_v: 0.0,
            battery: BatteryEstimator::new(BatteryConfig::from_params(
                &params.battery,
                &airframe.battery,
            )),
            gcs_link_age_s: None,
            fence_zones: Vec::new(),
            fence: None,
            injected: FailureInjector::new(airframe.rotors.len()),
            injection_enabled: params.safety.failure_injection != 0,
            monitor: SensorMonitor::new(),
            mag_field: MagFieldMonitor::default(),
            imu_frozen_since_usec: None,
            mag_cal: None,
        })
    }

    /// Writes a flight-data row per frame to `csv` from now on.
    pub fn log_to(&mut self, csv: FlightCsv) {
        self.csv = Some(csv);
    }

    /// How late the control loop woke for the frames it steps next (for the flight-data CSV).
    pub fn set_loop_late(&mut self, late: std::time::Duration) {
        self.loop_late = Some(late);
    }

    /// Writes the rest of the flight-data CSV, reporting the first write error of the flight.
    pub fn finish_log(&mut self) -> Result<()> {
        if let Some(e) = self.csv_error.take() {
            return Err(e).context("writing the flight-data CSV");
        }
        if let Some(csv) = self.csv.as_mut() {
            csv.finish().context("writing the flight-data CSV")?;
        }
        Ok(())
    }

    /// Flies with new parameters from the next step on (a ground station's PARAM_SET); the
    /// estimates, integrators and the flight in progress are kept.
    pub fn set_params(&mut self, params: &FlightParams) {
        self.params = params.clone();
        self.core
            .set_config(FlightCoreConfig::from_params(params, &self.airframe));
        self.commander.set_params(params.commander);
        self.commander.set_safety_params(params.safety);
        self.injection_enabled = params.safety.failure_injection != 0;
        self.battery.set_config(BatteryConfig::from_params(
            &params.battery,
            &self.airframe.battery,
        ));
    }

    /// The last sensor sample stepped on.
    pub fn sample(&self) -> Option<SensorSample> {
        self.last_sample
    }

    /// The set-point flown (armed only).
    pub fn setpoint(&self) -> Option<Setpoint> {
        self.last_setpoint
    }

    /// The simulator's last ground truth (SITL only).
    pub fn truth(&self) -> Option<hil::TruthReport> {
        self.last_truth
    }

    /// The largest collective thrust (N): what `ATTITUDE_TARGET`'s thrust is a fraction of.
    pub fn max_thrust_n(&self) -> f64 {
        self.core.config().position.max_thrust_n
    }

    /// The commander's state.
    pub fn status(&self) -> CommanderStatus {
        self.commander.status()
    }

    /// Whether the run is over: the auto flight has landed and disarmed, or an operator asked
    /// to end and the vehicle is disarmed.
    pub fn finished(&self) -> bool {
        self.ended
    }

    /// The last GPS solution received.
    pub fn gps(&self) -> Option<hil::GpsReport> {
        self.gps
    }

    /// The battery voltage (V): the board's report, else the pack's nominal voltage.
    pub fn battery_v(&self) -> f64 {
        self.battery_v
    }

    /// The battery as estimated from the board's (or simulator's) reports.
    pub fn battery(&self) -> BatteryState {
        self.battery.state()
    }

    /// The auto flight is waiting for the estimator before it takes off.
    pub fn awaiting_takeoff(&self) -> bool {
        self.auto.is_some() && !self.end_when_disarmed
    }

    /// Whether the armed state or the mode changed since the last call.
    pub fn take_changed(&mut self) -> bool {
        self.commander.take_changed()
    }

    /// The magnetometer calibration under way, or the last one.
    pub fn mag_calibration(&self) -> Option<MagCalStatus> {
        self.mag_cal.as_ref().map(MagCalibrator::status)
    }

    fn calibrating(&self) -> bool {
        self.mag_cal.as_ref().is_some_and(MagCalibrator::collecting)
    }

    /// Carries out a command, or says why not.
    pub fn command(&mut self, c: VehicleCommand) -> Result<(), Denial> {
        let arming = matches!(
            c,
            VehicleCommand::Arm { .. }
                | VehicleCommand::Takeoff(_)
                | VehicleCommand::TakeoffAmsl(_)
                | VehicleCommand::StartMission(_)
        );
        if arming && self.calibrating() {
            return Err("arming refused: calibrating the magnetometer".into());
        }
        let origin = self.origin();
        let c_ = &mut self.commander;
        match c {
            VehicleCommand::CalibrateMag => {
                if c_.status().armed {
                    return Err("calibration refused: disarm first".into());
                }
                if self.calibrating() {
                    return Err("a magnetometer calibration is already running".into());
                }
                let run = MAG_CAL_RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                let strength = self.params.attitude.mag_intensity_gauss;
                self.mag_cal = Some(MagCalibrator::new(run, strength));
                tracing::info!(
                    run,
                    "magnetometer calibration started: turn the vehicle through every orientation"
                );
                Ok(())
            }
            VehicleCommand::CancelCalibration => {
                if let Some(cal) = self.mag_cal.as_mut().filter(|c| c.collecting()) {
                    cal.cancel();
                    tracing::warn!("magnetometer calibration cancelled");
                }
                Ok(())
            }
            VehicleCommand::Arm { force } => c_.arm(force),
            VehicleCommand::Disarm { force } => c_.disarm(force),
            VehicleCommand::SetMode(m) => c_.set_mode(m),
            VehicleCommand::Takeoff(alt) => c_.takeoff(alt),
            VehicleCommand::SetHome(p) => c_.set_home(p),
            VehicleCommand::TakeoffAmsl(amsl_m) => {
                let (Some(out), Some(origin)) = (self.last, origin) else {
                    return Err("take-off refused: no global position yet".into());
                };
                let home_down = c_.home().map_or(out.translation.pos_ned_m.z, |h| h.z);
                let home_amsl = origin.alt_m - home_down;
                let above_home = (amsl_m - home_amsl).max(c_.params().takeoff_alt_m);
                c_.takeoff(Some(above_home))
            }
            VehicleCommand::SetHomeGlobal(p) => {
                let Some(origin) = origin else {
                    return Err("home refused: no global position yet".into());
                };
                c_.set_home(Some(LocalFrame::new(origin).to_ned(&p)))
            }
            VehicleCommand::Sticks(s) => {
                c_.manual_control(s);
                Ok(())
            }
            VehicleCommand::GcsHeartbeat => Ok(()),
            VehicleCommand::InjectFailure(_) if !self.injection_enabled => {
                Err(Refusal::Disabled.to_string())
            }
            VehicleCommand::InjectFailure(i) => {
                let said = self.injected.inject(i).map_err(|e| e.to_string())?;
                tracing::warn!("{said}");
                Ok(())
            }
            VehicleCommand::Offboard(t) => {
                c_.offboard_setpoint(t);
                Ok(())
            }
            VehicleCommand::SetMission(items) => {
                c_.set_mission(items);
                Ok(())
            }
            VehicleCommand::SetFence(zones) => {
                self.fence =
                    origin.map(|o| FenceMonitor::new(Geofence::new(&zones, &LocalFrame::new(o))));
                self.fence_zones = zones;
                Ok(())
            }
            VehicleCommand::SetMissionCurrent(seq) => c_.set_mission_current(seq),
            VehicleCommand::StartMission(first) => c_.start_mission(first),
            VehicleCommand::ChangeSpeed(change) => c_.change_speed(change),
            VehicleCommand::ConditionYaw {
                angle_deg,
                rate_deg_s,
                direction,
                relative,
            } => {
                let yaw = self
                    .last
                    .and_then(|o| o.attitude)
                    .map_or(0.0, |a| a.q.euler_angles().2);
                let target = if relative {
                    yaw + angle_deg.to_radians() * if direction < 0 { -1.0 } else { 1.0 }
                } else {
                    angle_deg.to_radians()
                };
                c_.condition_yaw(target, rate_deg_s.map(f64::to_radians))
            }
            VehicleCommand::Reposition {
                at,
                speed_m_s,
                yaw_rad,
                change_mode,
            } => {
                let (Some(out), Some(origin)) = (self.last, origin) else {
                    return Err("reposition refused: no global position yet".into());
                };
                let home = c_.home().unwrap_or(out.translation.pos_ned_m);
                // The parts left open stay NaN: the commander keeps them.
                let target = at.to_ned(&origin, &home, &Vector3::repeat(f64::NAN));
                c_.reposition(target, speed_m_s, yaw_rad, change_mode)
            }
        }
    }

    /// The wall-clock time since the last ground-station heartbeat (s; `None` before the
    /// first), for the link-loss failsafe: the control loop measures it, the vehicle has no
    /// clock of its own.
    pub fn set_gcs_link_age(&mut self, age_s: Option<f64>) {
        self.gcs_link_age_s = age_s;
    }

    /// The flight's figures against the simulator's truth, where it sends one.
    pub fn score(&self) -> &FlightScore {
        &self.score
    }

    /// Sensor frames that repeated or went back in time, answered or dropped without a step.
    pub fn repeated_frames(&self) -> u64 {
        self.repeated_frames
    }

    /// The estimator's local origin, once the GPS has set it.
    pub fn origin(&self) -> Option<LatLonAlt> {
        self.last.and_then(|o| o.translation.origin)
    }

    /// Ends the run (Ctrl-C): lands first if in the air.
    pub fn request_land(&mut self) {
        self.end_when_disarmed = true;
        self.auto = None;
        if self.commander.armed() {
            if let Err(e) = self.commander.set_mode(FlightMode::Land) {
                tracing::warn!("landing: {e}");
            }
        } else {
            self.ended = true;
        }
    }

    /// The sensors have no noise (the embedded simulator's ideal preset): repeated readings are
    /// no sign of a frozen sensor.
    pub fn sensors_noise_free(&mut self) {
        self.monitor.noise_free();
    }

    /// The sensor frames stopped: the estimate is invalid from now on. On the ground the motors
    /// stop; in the air an open-loop descent begins on the recent hover commands. Returns
    /// whether the vehicle is in the air.
    pub fn sensors_stopped(&mut self) -> bool {
        self.blind_descent("sensor frames stopped")
    }

    /// The estimate is lost for `why`: on the ground the motors stop, in the air the blind
    /// descent begins. Whether the vehicle is in the air.
    fn blind_descent(&mut self, why: &str) -> bool {
        let in_air = self.commander.sensors_stopped();
        if in_air {
            let home_down = self.commander.home().map_or(0.0, |h| h.z);
            let (height, down) = self.last.map_or((0.0, 0.0), |o| {
                let t = &o.translation;
                (home_down - t.pos_ned_m.z, t.vel_ned_m_s.z)
            });
            let d = BlindDescent::new(self.hover.get(), height, down);
            tracing::error!(
                height_m = format!("{height:.1}"),
                "{why} in the air: estimator invalid; descending open-loop on the hover commands, motors stop in {:.1} s",
                d.stop_after_s()
            );
            self.blind = Some(d);
        } else if !self.commander.armed() {
            tracing::error!("{why} on the ground: estimator invalid; disarmed");
            self.check_end();
        }
        in_air
    }

    /// The answer to send while the frames are silent, `silence_s` after the last one: the
    /// blind descent's commands, else motors off.
    pub fn silent_answer(&mut self, silence_s: f64) -> MavMessage {
        let t_usec = self.last_t_usec + (silence_s * 1e6) as u64;
        if let Some(d) = &self.blind {
            if let Some(c) = d.commands(silence_s) {
                return hil::actuator_controls(t_usec, &c[..self.rotors], true);
            }
            tracing::error!("blind descent over: motors stopped");
            self.blind = None;
            self.commander.disarmed();
            self.check_end();
        }
        hil::actuator_controls(t_usec, &[0.0; airframe::MAX_ROTORS][..self.rotors], false)
    }

    /// A frozen IMU while armed: the estimator would integrate the same reading over and over
    /// and the rate loop fight a rate that never changes. A repeated reading is suspect: that
    /// frame is answered with the hover commands, the loops untouched. Repeated long enough
    /// ([`SensorMonitor`]) it is lost: the frames are answered as if they had gone silent (the
    /// blind descent in the air, motors off on the ground), and the IMU is not trusted again
    /// before the motors stop. `None`: fly this frame as usual.
    fn imu_frozen(&mut self, t_usec: u64) -> Option<Step> {
        let commands = match self.imu_frozen_since_usec {
            None if !(self.commander.armed() && self.monitor.imu_repeating()) => return None,
            None if !self.monitor.lost().imu => Some(self.hover.get()),
            _ => {
                let since = match self.imu_frozen_since_usec {
                    Some(s) => s,
                    None => {
                        self.blind_descent("IMU frozen");
                        self.imu_frozen_since_usec = Some(t_usec);
                        t_usec
                    }
                };
                let t_s = t_usec.saturating_sub(since) as f64 * 1e-6;
                match self.blind.as_ref().map(|d| d.commands(t_s)) {
                    Some(Some(c)) => Some(c),
                    Some(None) => {
                        tracing::error!("blind descent over: motors stopped");
                        self.blind = None;
                        self.commander.disarmed();
                        self.check_end();
                        None
                    }
                    None => None,
                }
            }
        };
        // The world is still watched: the blind descent's landing is scored like any other.
        if let Some(truth) = self.update.truth.take() {
            let status = self.status();
            self.score.add(&truth, None, &status, status.armed);
            self.last_truth = Some(truth);
        }
        let output = self.last?;
        if !self.commander.armed() {
            self.imu_frozen_since_usec = None;
        }
        let message = match commands {
            Some(c) => hil::actuator_controls(t_usec, &c[..self.rotors], true),
            None => {
                hil::actuator_controls(t_usec, &[0.0; airframe::MAX_ROTORS][..self.rotors], false)
            }
        };
        self.last_t_usec = t_usec;
        self.last_answer = Some((t_usec, message.clone()));
        Some(Step {
            message,
            output,
            t_s: t_usec as f64 * 1e-6,
        })
    }

    /// The run ends when disarmed after the auto flight (or an operator's Ctrl-C).
    fn check_end(&mut self) {
        if self.end_when_disarmed && !self.commander.armed() {
            self.ended = true;
        }
    }

    /// The auto flight: take off when ready, land after the hold.
    fn fly_auto(&mut self) {
        let Some(a) = self.auto else {
            return;
        };
        let c = &mut self.commander;
        let s = c.status();
        if !self.end_when_disarmed {
            if s.ready && !s.armed {
                if let Err(e) = c.takeoff(Some(a.takeoff_m)).and_then(|()| c.arm(false)) {
                    if self.auto_denial.as_ref() != Some(&e) {
                        tracing::warn!("auto flight: {e}");
                        self.auto_denial = Some(e);
                    }
                    return;
                }
                tracing::info!(takeoff_m = a.takeoff_m, "auto flight: armed, taking off");
                self.end_when_disarmed = true;
            }
        } else if s.mode == FlightMode::Loiter
            && s.landed == LandedState::InAir
            && s.in_mode_s >= a.hover_s
        {
            tracing::info!("auto flight: landing");
            if let Err(e) = c.set_mode(FlightMode::Land) {
                tracing::warn!("auto flight: {e}");
            }
        }
    }

    /// The sensor frames are back: the loops fly again (the commander keeps descending).
    pub fn sensors_resumed(&mut self) {
        if self.blind.take().is_some() {
            tracing::warn!("sensor frames back: descending closed-loop");
        }
    }

    /// Times the sensor source started again from an earlier time (see
    /// [`Vehicle::on_message`]).
    pub fn source_restarts(&self) -> u32 {
        self.source_restarts
    }

    /// The sensor source started again (its clock went back by more than
    /// [`SOURCE_RESTART_S`]): a simulator restarted, a flight board rebooted. Whatever the
    /// vehicle believed is of another world: it starts afresh — disarmed, estimator aligning
    /// again, commander on the ground —, as a board does when it boots. Kept, as a board's
    /// storage keeps them: the parameters, the mission, the fence, the flight log.
    fn source_restarted(&mut self, back_s: f64) {
        let mut fresh = match Vehicle::new(&self.airframe, &self.params, self.auto) {
            Ok(v) => v,
            Err(e) => {
                // Built from the same airframe and parameters before: not expected.
                tracing::error!("sensor source restarted, the vehicle not rebuilt: {e:#}");
                return;
            }
        };
        tracing::warn!(
            back_s = format!("{back_s:.1}"),
            was_armed = self.commander.armed(),
            "sensor source restarted (its clock went back): the vehicle starts afresh"
        );
        let _ = fresh.command(VehicleCommand::SetMission(
            self.commander.mission_items().to_vec(),
        ));
        let _ = fresh.command(VehicleCommand::SetFence(std::mem::take(
            &mut self.fence_zones,
        )));
        fresh.csv = self.csv.take();
        fresh.csv_error = self.csv_error.take();
        fresh.update = std::mem::take(&mut self.update);
        fresh.repeated_frames = self.repeated_frames;
        fresh.source_restarts = self.source_restarts + 1;
        // A calibration under way cannot go on in a clock that went back: ended, and said so.
        fresh.mag_cal = self.mag_cal.take().map(|mut c| {
            c.cancel();
            c
        });
        *self = fresh;
    }

    /// Folds one message in; a complete sensor frame runs a step and returns the answer.
    /// A frame more than [`SOURCE_RESTART_S`] older than the last one is a source that
    /// started again: the vehicle does too.
    pub fn on_message(&mut self, msg: &MavMessage) -> Option<Step> {
        if !self.update.absorb(msg) {
            return None;
        }
        let t_usec = self.update.time_usec?;
        if let Some((t_last, _)) = &self.last_answer
            && t_usec.saturating_add(SOURCE_RESTART_USEC) < *t_last
        {
            let back_s = (*t_last - t_usec) as f64 * 1e-6;
            self.source_restarted(back_s);
        }
        let u = &mut self.update;
        let (t_usec, gyro, accel) = (u.time_usec?, u.gyro_frd?, u.accel_frd?);
        if let (Some((t_last, answer)), Some(output)) = (&self.last_answer, self.last)
            && t_usec <= *t_last
        {
            // A frame seen before (a lockstep simulator resends until it hears an answer; a
            // serial line delivers what queued before the port was opened): answer it again
            // without stepping; an older one is stale and dropped.
            self.repeated_frames += 1;
            u.mag_frd = None;
            u.pressure_alt_m = None;
            u.gps = None;
            u.rotor_speed_rad_s = None;
            u.truth = None;
            return (t_usec == *t_last).then(|| Step {
                message: answer.clone(),
                output,
                t_s: t_usec as f64 * 1e-6,
            });
        }
        let mut sample = SensorSample {
            t_usec,
            gyro,
            accel,
            mag: u.mag_frd.take(),
            baro_alt_m: u.pressure_alt_m.take(),
            gps: u.gps.take().map(|g| {
                self.gps = Some(g);
                GpsMeasurement {
                    fix_type: g.fix_type,
                    position: LatLonAlt {
                        lat_deg: g.lat_deg,
                        lon_deg: g.lon_deg,
                        alt_m: g.alt_m,
                    },
                    vel_ned_m_s: g.vel_ned_m_s,
                    h_acc_m: g.h_acc_m,
                }
            }),
            battery_v: {
                self.battery_v = u.battery_v.unwrap_or(self.nominal_v);
                self.battery_v
            },
            rotor_speed_rad_s: u.rotor_speed_rad_s.take(),
        };
        if let Some(v) = u.battery_v {
            let current = u
                .esc_current_a
                .map(|c| c[..self.rotors.min(c.len())].iter().sum::<f64>());
            let throttle = self.last.map_or(0.0, |o| {
                o.commands[..self.rotors].iter().sum::<f64>() / self.rotors.max(1) as f64
            });
            let dt = if self.last.is_some() {
                t_usec.saturating_sub(self.last_t_usec) as f64 * 1e-6
            } else {
                0.0
            };
            self.battery.step(v, current, throttle, dt);
        }
        self.injected.apply_to_sample(&mut sample);
        // Lost sensors are taken out: the estimators fall back as for a sensor that is off.
        self.monitor.update(&mut sample);
        if let Some(step) = self.imu_frozen(t_usec) {
            return Some(step);
        }
        if self.last.is_some() {
            let dt = t_usec.saturating_sub(self.last_t_usec) as f64 * 1e-6;
            let p = &self.core.config().attitude;
            self.mag_field.update(sample.mag, &sample.accel, p, dt);
        }
        let t_s = t_usec as f64 * 1e-6;
        if let Some(cal) = self.mag_cal.as_mut().filter(|c| c.collecting()) {
            cal.step(t_s, sample.mag);
            log_calibration_end(&cal.status());
        }
        let (setpoint, armed) = match self.last {
            Some(e) => {
                let ready = e.attitude.is_some_and(|a| a.valid)
                    && e.translation.horizontal_valid
                    && e.translation.vertical_valid;
                self.fly_auto();
                if self.fence.is_none()
                    && let Some(o) = e.translation.origin
                {
                    let fence = Geofence::new(&self.fence_zones, &LocalFrame::new(o));
                    self.fence = Some(FenceMonitor::new(fence));
                }
                // Outside the uploaded fence, or about to be: as PX4's GF_PREDICT, the point
                // where a failsafe stop (MPC_ACC_FS_BRK) would come to rest must be inside too.
                let in_air = self.commander.landed() == LandedState::InAir;
                let brake = self.commander.params().failsafe_brake_m_s2;
                let tr = &e.translation;
                let outside_fence = tr.horizontal_valid
                    && self.fence.as_mut().is_some_and(|f| {
                        f.update(&tr.pos_ned_m.xy(), &tr.vel_ned_m_s.xy(), in_air, brake)
                    });
                let out = self.commander.update(&CommanderInput {
                    t_s,
                    ready,
                    horizontal_valid: e.translation.horizontal_valid,
                    pos_ned_m: e.translation.pos_ned_m,
                    vel_ned_m_s: e.translation.vel_ned_m_s,
                    yaw_rad: e.attitude.map_or(0.0, |a| a.q.euler_angles().2),
                    hover_thrust: {
                        let p = &self.core.config().position;
                        p.mass_kg * flight_core::GRAVITY_M_S2 / p.max_thrust_n.max(1e-9)
                    },
                    origin: e.translation.origin,
                    health: Health {
                        attitude_valid: e.attitude.is_some_and(|a| a.valid),
                        gyro_bias_settled: e.attitude.is_some_and(|a| a.bias_settled),
                        altitude_valid: e.translation.vertical_valid,
                        roll_pitch_rad: e.attitude.map_or((0.0, 0.0), |a| {
                            let (roll, pitch, _) = a.q.euler_angles();
                            (roll, pitch)
                        }),
                        gcs_link_age_s: self.gcs_link_age_s,
                        motor_failed: self
                            .core
                            .failed_rotors()
                            .iter()
                            .position(|&f| f)
                            .map(|i| i + 1),
                        sensors_lost: self.monitor.lost(),
                        battery_remaining: self.battery.state().remaining,
                        geofence_breached: outside_fence,
                        mag: self.mag_field.status(&self.core.config().attitude),
                    },
                });
                for e in self.commander.take_safety_events() {
                    tracing::warn!("{e}");
                }
                self.check_end();
                out
            }
            None => (
                Setpoint::Position(PositionSetpoint {
                    pos_ned_m: Vector3::zeros(),
                    vel_ned_m_s: Vector3::zeros(),
                    accel_ned_m_s2: Vector3::zeros(),
                    yaw_rad: 0.0,
                }),
                false,
            ),
        };
        let status = self.commander.status();
        if status.armed && status.landed == LandedState::OnGround {
            // Spooling up on the ground: the position loop starts fresh at take-off.
            self.core.reset_position_loop();
        }
        let truth = self.update.truth.take();
        self.core.set_in_air(matches!(
            status.landed,
            LandedState::InAir | LandedState::Landing
        ));
        let output = self.core.step(&sample, &setpoint, armed);
        if let Some(f) = output.motor_failure {
            tracing::error!(
                motor = f.rotor + 1,
                by = ?f.by,
                lost = format!("{:.0} %", 100.0 * f.lost_fraction),
                reallocated = self.core.config().motor_failure.reallocate,
                "motor failure detected"
            );
        }
        // Magnetometer and barometer as last seen (a frame carries them only when fresh).
        let prev = self.last_sample;
        self.last_sample = Some(SensorSample {
            mag: sample.mag.or(prev.and_then(|p| p.mag)),
            baro_alt_m: sample.baro_alt_m.or(prev.and_then(|p| p.baro_alt_m)),
            ..sample
        });
        self.last_setpoint = armed.then_some(setpoint);
        if truth.is_some() {
            self.last_truth = truth;
        }
        if armed && !self.monitor.imu_repeating() {
            // Not while the IMU repeats itself: if it is freezing, the loops fly blind and the
            // blind descent must not inherit what they command meanwhile.
            let dt = t_usec.saturating_sub(self.last_t_usec) as f64 * 1e-6;
            self.hover.update(&output.commands, dt);
        } else if !armed {
            self.hover.reset();
        }
        self.last_t_usec = t_usec;
        self.last = Some(output);
        if let Some(truth) = &truth {
            let estimate = output.attitude.map(|a| a.q);
            self.score.add(truth, estimate, &status, armed);
        }
        if let Some(csv) = self.csv.as_mut()
            && let Err(e) = csv.record(
                t_s,
                &status,
                armed,
                &setpoint,
                &output,
                truth.as_ref(),
                &self.score,
                self.loop_late,
                &sample,
            )
        {
            // A full disk must not stop the flight: stop logging, report at the end.
            tracing::error!("flight-data CSV: {e}; logging stopped");
            self.csv = None;
            self.csv_error = Some(e);
        }
        let mut commands = output.commands;
        self.injected
            .apply_to_commands(&mut commands[..self.rotors]);
        let message = hil::actuator_controls(t_usec, &commands[..self.rotors], armed);
        self.last_answer = Some((t_usec, message.clone()));
        Some(Step {
            message,
            output,
            t_s,
        })
    }
}
