//! The autopilot: one pure step from a sensor sample to motor commands, with everything a
//! vehicle does around the flight core.
//!
//! ```text
//! sample ─► failure injection ─► sensor monitor ─► frozen IMU? ─► magnetometer checks
//!        ─► auto flight ─► geofence ─► commander (modes, failsafes) ─► FlightCore::step
//!        ─► motor-failure report ─► hover memory ─► commands (failed motors at zero)
//! ```
//!
//! The links around it (a simulator in-process or over UDP, a serial flight board) turn bytes
//! into [`SensorSample`](crate::sample::SensorSample)s and commands into bytes; the records (flight-data CSV, telemetry log,
//! the score against a simulator's truth) observe each [`AutopilotOutput`] from outside. Time
//! comes with the sample; the ground-station link's age with [`StepInputs`]: no clock is read.

mod auto_flight;
mod blind;
mod calibration;
pub mod command;
pub mod rc;
mod state;
mod step;

pub use auto_flight::AutoFlight;
pub use state::VehicleState;

use crate::commander::{Commander, CommanderInput, CommanderStatus, Health, LandedState};
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use crate::core::{FlightCore, FlightCoreConfig, nominal_battery_v};
use crate::math::geo::LocalFrame;
use crate::mixer::MixerError;
use crate::params::FlightParams;
use crate::safety::blind_descent::{BlindDescent, HoverCommands};
use crate::safety::failure_injection::FailureInjector;
use crate::safety::geofence::{FenceMonitor, GeoZone, Geofence};
use crate::sample::StepOutput;
use crate::sensors::battery::{BatteryConfig, BatteryEstimator};
use crate::sensors::imu_calibrator::ImuCalibrator;
use crate::sensors::imu_correction::ImuCorrection;
use crate::sensors::mag_calibrator::MagCalibrator;
use crate::sensors::mag_check::MagFieldMonitor;
use crate::sensors::monitor::SensorMonitor;
use airframe::{Airframe, MAX_ROTORS};
use nalgebra::Vector3;

/// How far back the sensor clock must jump for the source to count as started again (s): more
/// than a lockstep resend or a serial line's backlog, less than any flight.
pub const SOURCE_RESTART_S: f64 = 1.0;
const SOURCE_RESTART_USEC: u64 = (SOURCE_RESTART_S * 1e6) as u64;

/// What arrives with a sample from outside the sensors.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepInputs {
    /// Wall-clock time since the last ground-station heartbeat (s; `None` before the first),
    /// for the link-loss failsafe: the control loop measures it.
    pub gcs_link_age_s: Option<f64>,
    /// A frame from the RC receiver, when one arrived with this sample.
    pub rc: Option<crate::commander::rc_input::RcFrame>,
}

/// What a step did with its sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepKind {
    /// The flight core flew the sample.
    Flown,
    /// The sample's time was the last one's (a lockstep simulator resending, a serial line's
    /// backlog): the last answer again, nothing stepped.
    Repeated,
    /// The IMU is frozen: the hover commands, or the blind descent's; the loops untouched.
    Blind,
}

/// The set-point before the commander has one: hold the origin, heading north (never flown:
/// the motors are disarmed then).
fn origin_setpoint() -> Setpoint {
    Setpoint::Position(PositionSetpoint {
        pos_ned_m: Vector3::zeros(),
        vel_ned_m_s: Vector3::zeros(),
        accel_ned_m_s2: Vector3::zeros(),
        yaw_rad: 0.0,
    })
}

/// One step's result. The flight core's output it flew on is kept once, in the published
/// state ([`VehicleState::estimate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutopilotOutput {
    /// Time of the sample (µs).
    pub t_usec: u64,
    /// What the rotors are told ∈ [0, 1] (failed motors injected at zero).
    pub commands: [f64; MAX_ROTORS],
    /// Motors armed.
    pub armed: bool,
    /// What the step did.
    pub kind: StepKind,
    /// The set-point flown.
    pub setpoint: Setpoint,
    /// The sensor source started again before this sample (its clock went back by more than
    /// [`SOURCE_RESTART_S`]): the autopilot started afresh, and so do the records.
    pub restarted: bool,
}

/// The autopilot: flight core, commander, and the checks and failsafes around them.
#[derive(Clone)]
pub struct Autopilot {
    core: FlightCore,
    commander: Commander,
    /// For new parameters: the configuration is derived from them and the airframe.
    airframe: Airframe,
    /// The parameters flown (to start afresh when the sensor source does).
    params: FlightParams,
    rotors: usize,
    nominal_v: f64,
    /// Samples that repeated or went back in time, answered or dropped without a step.
    repeated_frames: u64,
    auto: Option<AutoFlight>,
    /// The auto flight has armed, or an operator asked to end: the run ends once disarmed.
    end_when_disarmed: bool,
    /// Why the auto flight may not arm, as last said (said again only when it changes).
    auto_denial: Option<crate::commander::Denial>,
    ended: bool,
    /// The last answer (repeated for a repeated sample), with the flight core's last output.
    last_answer: Option<AutopilotOutput>,
    /// The vehicle as published after each step and each command ([`Self::state`]): it also
    /// holds the last sample flown, the set-point flown, the last GPS solution and the
    /// battery voltage.
    published: VehicleState,
    /// State of charge from the reported voltage and current.
    battery: BatteryEstimator,
    /// The uploaded fence, and the same placed in the estimator's frame once it has an origin.
    fence_zones: Vec<GeoZone>,
    fence: Option<FenceMonitor>,
    /// Failures injected by `MAV_CMD_INJECT_FAILURE`, and whether that is allowed
    /// (`SYS_FAILURE_EN`).
    injected: FailureInjector,
    injection_enabled: bool,
    /// Silent and frozen sensors.
    monitor: SensorMonitor,
    /// The magnetometer's field at rest, for the arming checks.
    mag_field: MagFieldMonitor,
    /// The last magnetometer calibration (under way or ended).
    mag_cal: Option<MagCalibrator>,
    /// The last gyro, accelerometer or level-horizon calibration (under way or ended).
    imu_cal: Option<ImuCalibrator>,
    /// The IMU's calibration, applied to every sample before the estimators.
    imu_correction: ImuCorrection,
    /// The recent hover commands, and the open-loop descent flown on them without the IMU.
    hover: HoverCommands,
    /// The attitude estimate's tilt and heading resets logged.
    estimate_resets: (u64, u64),
    blind: Option<BlindDescent>,
    /// When the IMU froze while armed (sensor time): the loops cannot fly without it, and it
    /// is not trusted again before the motors stop.
    imu_frozen_since_usec: Option<u64>,
    /// The RC transmitter's switches and the sticks' sources between frames.
    rc: rc::RcState,
}

impl Autopilot {
    /// An autopilot for `airframe`, flying `auto` on its own if given, else waiting for
    /// commands.
    pub fn new(
        airframe: &Airframe,
        params: &FlightParams,
        auto: Option<AutoFlight>,
    ) -> Result<Self, MixerError> {
        let mut commander_params = params.commander;
        if let Some(a) = auto {
            commander_params.takeoff_alt_m = a.takeoff_m;
        }
        let mut commander = Commander::new(commander_params);
        commander.set_safety_params(params.safety);
        let core = FlightCore::new(airframe, FlightCoreConfig::from_params(params, airframe))?;
        let published = VehicleState {
            status: commander.status(),
            estimate: None,
            held_sample: None,
            setpoint: None,
            gps: None,
            battery_v: 0.0,
            battery: Default::default(),
            mag_cal: None,
            imu_cal: None,
            source_restarts: 0,
            rotors: airframe.rotors.len(),
            max_thrust_n: core.config().position.max_thrust_n,
            rc: None,
        };
        let mut autopilot = Self {
            core,
            commander,
            airframe: airframe.clone(),
            params: params.clone(),
            rotors: airframe.rotors.len(),
            nominal_v: nominal_battery_v(airframe),
            repeated_frames: 0,
            auto,
            end_when_disarmed: false,
            auto_denial: None,
            ended: false,
            last_answer: None,
            published,
            battery: BatteryEstimator::new(BatteryConfig::from_params(
                &params.battery,
                &airframe.battery,
            )),
            fence_zones: Vec::new(),
            fence: None,
            injected: FailureInjector::new(airframe.rotors.len()),
            injection_enabled: params.safety.failure_injection != 0,
            monitor: SensorMonitor::new(),
            mag_field: MagFieldMonitor::default(),
            mag_cal: None,
            imu_cal: None,
            imu_correction: ImuCorrection::new(&params.imu, airframe.imu_position_frd_m),
            hover: HoverCommands::new(2.0),
            estimate_resets: (0, 0),
            blind: None,
            imu_frozen_since_usec: None,
            rc: rc::RcState::default(),
        };
        autopilot.publish();
        Ok(autopilot)
    }

    /// Flies with new parameters from the next step on (a ground station's PARAM_SET); the
    /// estimates, integrators and the flight in progress are kept.
    pub fn set_params(&mut self, params: &FlightParams) {
        if params.imu != self.params.imu {
            // A new calibration: what was learned in flight through the old one is wrong.
            self.core.forget_accel_bias();
        }
        self.params = params.clone();
        self.core
            .set_config(FlightCoreConfig::from_params(params, &self.airframe));
        self.commander.set_params(params.commander);
        self.commander.set_safety_params(params.safety);
        self.injection_enabled = params.safety.failure_injection != 0;
        self.imu_correction = ImuCorrection::new(&params.imu, self.airframe.imu_position_frd_m);
        self.battery.set_config(BatteryConfig::from_params(
            &params.battery,
            &self.airframe.battery,
        ));
        self.publish();
    }

    /// The commander's state.
    pub fn status(&self) -> CommanderStatus {
        // Published after every change to the commander.
        self.published.status
    }

    /// Whether the armed state or the mode changed since the last call.
    pub fn take_changed(&mut self) -> bool {
        self.commander.take_changed()
    }

    /// The mission's progress.
    pub fn mission_status(&self) -> crate::mission::MissionStatus {
        self.commander.mission_status()
    }

    /// The flight core's last output.
    fn estimate(&self) -> Option<StepOutput> {
        self.published.estimate
    }

    /// Samples that repeated or went back in time, answered or dropped without a step.
    pub fn repeated_frames(&self) -> u64 {
        self.repeated_frames
    }

    /// The last answer: the last step's, or the one before it repeated.
    pub fn output(&self) -> Option<&AutopilotOutput> {
        self.last_answer.as_ref()
    }

    /// Time of the last answered sample (µs; 0 before the first).
    fn last_t_usec(&self) -> u64 {
        self.last_answer.as_ref().map_or(0, |a| a.t_usec)
    }

    /// Seconds from the last step to `t_usec` (0 before the first).
    fn dt_since_last(&self, t_usec: u64) -> f64 {
        self.last_answer
            .as_ref()
            .map_or(0.0, |a| t_usec.saturating_sub(a.t_usec) as f64 * 1e-6)
    }

    /// The commander's set-point for this step, and whether the motors are armed: the auto
    /// flight, the geofence and the failsafes decide with it. Before the flight core's first
    /// output: the origin, disarmed.
    fn command_setpoint(&mut self, t_s: f64, inputs: &StepInputs) -> (Setpoint, bool) {
        if self.last_answer.is_none() {
            return (origin_setpoint(), false);
        }
        self.fly_auto();
        // Read in place (the fields below are the autopilot's others): no copy of the output.
        let Some(e) = self.published.estimate.as_ref() else {
            return (origin_setpoint(), false);
        };
        let attitude_valid = e.attitude.is_some_and(|a| a.valid);
        let ready =
            attitude_valid && e.translation.horizontal_valid && e.translation.vertical_valid;
        if self.fence.is_none()
            && let Some(o) = e.translation.origin
        {
            let fence = Geofence::new(&self.fence_zones, &LocalFrame::new(o));
            self.fence = Some(FenceMonitor::new(fence));
        }
        // Outside the uploaded fence, or about to be: as PX4's GF_PREDICT, the point where a
        // failsafe stop (MPC_ACC_FS_BRK) would come to rest must be inside too.
        let in_air = self.commander.landed() == LandedState::InAir;
        let brake = self.commander.params().failsafe_brake_m_s2;
        let tr = &e.translation;
        let outside_fence = tr.horizontal_valid
            && self
                .fence
                .as_mut()
                .is_some_and(|f| f.update(&tr.pos_ned_m.xy(), &tr.vel_ned_m_s.xy(), in_air, brake));
        let p = &self.core.config().position;
        let (roll, pitch, yaw) = e.attitude.map_or((0.0, 0.0, 0.0), |a| a.euler_rad);
        let out = self.commander.update(&CommanderInput {
            t_s,
            ready,
            horizontal_valid: tr.horizontal_valid,
            pos_ned_m: tr.pos_ned_m,
            vel_ned_m_s: tr.vel_ned_m_s,
            yaw_rad: yaw,
            hover_thrust: p.mass_kg * crate::GRAVITY_M_S2 / p.max_thrust_n.max(1e-9),
            thrust: self.core.thrust_fraction(),
            imu_still: e.attitude.is_some_and(|a| a.imu_still),
            origin: tr.origin,
            health: Health {
                attitude_valid,
                gyro_bias_settled: e.attitude.is_some_and(|a| a.bias_settled),
                altitude_valid: tr.vertical_valid,
                roll_pitch_rad: (roll, pitch),
                gcs_link_age_s: inputs.gcs_link_age_s,
                motor_failed: self
                    .core
                    .failed_rotors()
                    .iter()
                    .position(|&f| f)
                    .map(|i| i + 1),
                spinning: self.core.spinning_without().is_some(),
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

    /// The sensor source started again (its clock went back by more than
    /// [`SOURCE_RESTART_S`]): a simulator restarted, a flight board rebooted. Whatever the
    /// autopilot believed is of another world: it starts afresh — disarmed, estimator aligning
    /// again, commander on the ground —, as a board does when it boots. Kept, as a board's
    /// storage keeps them: the parameters, the mission and the fence.
    fn source_restarted(&mut self, back_s: f64) {
        let mut fresh = match Autopilot::new(&self.airframe, &self.params, self.auto) {
            Ok(a) => a,
            Err(e) => {
                // Built from the same airframe and parameters before: not expected.
                tracing::error!("sensor source restarted, the autopilot not rebuilt: {e}");
                return;
            }
        };
        tracing::warn!(
            back_s = format!("{back_s:.1}"),
            was_armed = self.commander.armed(),
            "sensor source restarted (its clock went back): the vehicle starts afresh"
        );
        fresh
            .commander
            .set_mission(self.commander.mission_items().to_vec());
        fresh.fence_zones = std::mem::take(&mut self.fence_zones);
        fresh.repeated_frames = self.repeated_frames;
        fresh.published.source_restarts = self.published.source_restarts + 1;
        // A calibration under way cannot go on in a clock that went back: ended, and said so.
        self.end_calibrations();
        fresh.mag_cal = self.mag_cal.take();
        fresh.imu_cal = self.imu_cal.take();
        *self = fresh;
    }
}
