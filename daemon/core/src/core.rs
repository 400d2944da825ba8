//! The flight core: one `step` from a sensor sample and a set-point to motor commands.
//!
//! sensors ─► attitude estimator (q-method + observer) ─► translation estimator ─► position
//! loop ─► kinematic attitude law (Castillo (63)) ─► rate loop (LADRC or PID) ─► mixer.
//! Pure: no clock (time comes with the sample), no I/O, no allocation in `step`.

use crate::control::GroundContact;
use crate::control::disturbance::{DisturbanceObserver, WindEstimate};
use crate::control::motor::MotorSpeedLoop;
use crate::control::position::{AttitudeSetpoint, PositionController};
use crate::control::rate::{LadrcAxis, PidAxis};
use crate::control::reduced_attitude::ReducedAttitude;
use crate::estimator::attitude::AttitudeEstimator;
use crate::estimator::translation::TranslationEstimator;
use crate::mixer::{Mixer, MixerError, MixerOutput};
use crate::safety::motor_failure::MotorFailureDetector;
use airframe::{Airframe, DragSpec, MAX_ROTORS};
use std::sync::OnceLock;

mod config;
mod step;
pub use crate::sample::{SensorSample, StepOutput};
pub use config::{AttitudeLaw, FlightCoreConfig, RateLoopParams};

#[derive(Clone)]
enum RateAxis {
    Ladrc(LadrcAxis),
    Pid(PidAxis),
}

/// The flight core.
#[derive(Clone)]
pub struct FlightCore {
    config: FlightCoreConfig,
    attitude: AttitudeEstimator,
    translation: TranslationEstimator,
    position: PositionController,
    attitude_law: AttitudeLaw,
    rate: [RateAxis; 3],
    mixer: Mixer,
    motor: MotorSpeedLoop,
    motor_failure: MotorFailureDetector,
    /// A quad's reduced-attitude controller for each rotor it may lose (empty for other
    /// airframes; `None` where that rotor's loss has no relaxed hover), each solved the first
    /// time it is asked for: about 1.4 ms of LQR work a rotor that most flights never need.
    three_rotors: Vec<OnceLock<Option<ReducedAttitude>>>,
    /// The quad the three-rotor controllers are solved for.
    quad: Option<Box<Airframe>>,
    /// The rotor lost while a quad flies spinning on the other three.
    spinning_without: Option<usize>,
    /// The allocation flown since the last sample (what the rotors were told).
    last_mix: Option<MixerOutput>,
    in_air: bool,
    /// Whether the outside force may be learned now (climbing away or flying, not landing).
    learn_disturbance: bool,
    ground_contact: GroundContact,
    last_t_usec: Option<u64>,
    /// The attitude estimate's tilt resets seen so far.
    tilt_resets: u64,
    /// The attitude estimate was unknown at the last sample (after a gap in flight).
    attitude_unknown: bool,
    flying: bool,
    /// The position loop's last output, the time since it ran (s), and the time since its
    /// schedule last fell due (s; negative: it ran early, within half a sample).
    position_output: Option<AttitudeSetpoint>,
    since_position_s: f64,
    position_phase_s: f64,
    /// The outside force on the vehicle (wind), learned in the air.
    disturbance: DisturbanceObserver,
    /// The airframe's drag, to read the outside force as a wind.
    drag: DragSpec,
    /// The wind it means, and the time since it was last worked out (s).
    wind: Option<WindEstimate>,
    wind_age_s: f64,
    /// Air density from the last barometer sample (kg/m³).
    air_density_kg_m3: f64,
    /// The pack's nominal voltage (V): 3.8 V a cell, flown while no voltage is reported.
    nominal_battery_v: f64,
    /// Time steps clamped into the accepted range.
    pub dt_clamped: u64,
}

fn rate_axes(p: &RateLoopParams) -> [RateAxis; 3] {
    match p {
        RateLoopParams::Ladrc(l) => [0, 1, 2].map(|i| RateAxis::Ladrc(LadrcAxis::new(l[i]))),
        RateLoopParams::Pid(q) => [0, 1, 2].map(|i| RateAxis::Pid(PidAxis::new(q[i]))),
    }
}

/// The pack's nominal voltage (V): 3.8 V a LiPo cell.
pub fn nominal_battery_v(airframe: &Airframe) -> f64 {
    3.8 * airframe.battery.cells as f64
}

/// How often the wind is worked out from the outside force (s): the rate of the fastest
/// stream or log topic that carries it.
const WIND_PERIOD_S: f64 = 0.1;

/// ISA air density from a pressure altitude (kg/m³).
fn air_density(pressure_alt_m: f64) -> f64 {
    crate::SEA_LEVEL_AIR_DENSITY_KG_M3
        * (1.0 - 2.255_77e-5 * pressure_alt_m.clamp(-500.0, 11_000.0)).powf(4.255_9)
}

impl FlightCore {
    /// A flight core for an airframe.
    pub fn new(airframe: &Airframe, config: FlightCoreConfig) -> Result<Self, MixerError> {
        Ok(Self {
            attitude: AttitudeEstimator::new(&config.attitude),
            translation: TranslationEstimator::new(config.translation),
            position: PositionController::new(config.position),
            attitude_law: config.attitude_law,
            rate: rate_axes(&config.rate),
            mixer: Mixer::new(airframe)?,
            motor: MotorSpeedLoop::new(airframe, config.motor),
            motor_failure: MotorFailureDetector::new(airframe, config.motor_failure),
            three_rotors: if airframe.rotors.len() == 4 {
                vec![OnceLock::new(); 4]
            } else {
                Vec::new()
            },
            quad: (airframe.rotors.len() == 4).then(|| Box::new(airframe.clone())),
            spinning_without: None,
            last_mix: None,
            in_air: false,
            learn_disturbance: false,
            ground_contact: GroundContact::None,
            last_t_usec: None,
            tilt_resets: 0,
            attitude_unknown: false,
            flying: false,
            position_output: None,
            since_position_s: 0.0,
            position_phase_s: 0.0,
            disturbance: DisturbanceObserver::new(config.position.disturbance_tau_s),
            drag: airframe.drag.clone(),
            wind: None,
            wind_age_s: 0.0,
            air_density_kg_m3: air_density(0.0),
            nominal_battery_v: nominal_battery_v(airframe),
            dt_clamped: 0,
            config,
        })
    }

    /// The configuration flown.
    pub fn config(&self) -> &FlightCoreConfig {
        &self.config
    }

    /// Changes the configuration in flight (a parameter set from a ground station): gains,
    /// limits and estimator settings take effect at the next step and every state (estimates,
    /// integrators, observers) is kept. Only a change of rate controller (LADRC ↔ PID) starts
    /// that loop afresh.
    pub fn set_config(&mut self, config: FlightCoreConfig) {
        self.attitude.set_params(&config.attitude);
        self.translation.set_params(config.translation);
        self.position.params = config.position;
        self.disturbance.tau_s = config.position.disturbance_tau_s;
        self.attitude_law = config.attitude_law;
        match (&mut self.rate, &config.rate) {
            (axes, RateLoopParams::Ladrc(p))
                if axes.iter().all(|a| matches!(a, RateAxis::Ladrc(_))) =>
            {
                for (a, p) in axes.iter_mut().zip(p) {
                    if let RateAxis::Ladrc(l) = a {
                        l.params = *p;
                    }
                }
            }
            (axes, RateLoopParams::Pid(p))
                if axes.iter().all(|a| matches!(a, RateAxis::Pid(_))) =>
            {
                for (a, p) in axes.iter_mut().zip(p) {
                    if let RateAxis::Pid(l) = a {
                        l.params = *p;
                    }
                }
            }
            (axes, p) => *axes = rate_axes(p),
        }
        self.motor.set_params(config.motor);
        self.motor_failure.set_params(config.motor_failure);
        self.config = config;
    }

    /// Tells the core whether the vehicle is flying (the commander's landed state): the
    /// thrust-imbalance check of motor-failure detection runs only in the air.
    pub fn set_in_air(&mut self, in_air: bool) {
        self.in_air = in_air;
    }

    /// Tells the core whether to learn the outside force (the commander taking off or flying)
    /// or hold what it learned (landing: near the ground its legs' friction would read as a
    /// push, and answering it would tip the vehicle over on them).
    pub fn set_learn_disturbance(&mut self, learn: bool) {
        self.learn_disturbance = learn;
    }

    /// Tells the core how far a landing has come on the ground (the commander's land
    /// detector): in contact the position loop stops holding the horizontal position, maybe
    /// landed the thrust is cut to idle with the attitude level and the rate loop's
    /// integrators cleared, so that the ground holds the vehicle, not the loops.
    pub fn set_ground_contact(&mut self, contact: GroundContact) {
        self.ground_contact = contact;
    }

    /// Rotors declared failed this flight (true = failed).
    pub fn failed_rotors(&self) -> &[bool] {
        self.motor_failure.failed()
    }

    /// The rotor lost while a quad flies spinning on its other three (the reduced-attitude
    /// controller flying), if it does.
    pub fn spinning_without(&self) -> Option<usize> {
        self.spinning_without
    }

    /// Whether a quad can fly on when `rotor` stops: the reduced-attitude controller of that
    /// loss exists (false for other airframes, which re-allocate instead).
    pub fn flies_on_three_rotors(&self, rotor: usize) -> bool {
        self.three_rotor_control(rotor).is_some()
    }

    /// The reduced-attitude controller for the loss of `rotor`, solved on first use (a quad
    /// only; `None` where that loss has no relaxed hover, said once in the log).
    fn three_rotor_control(&self, rotor: usize) -> Option<&ReducedAttitude> {
        let (cell, quad) = (self.three_rotors.get(rotor)?, self.quad.as_deref()?);
        cell.get_or_init(|| {
            let control = ReducedAttitude::for_lost_rotor(quad, rotor);
            if control.is_none() {
                tracing::warn!(
                    motor = rotor + 1,
                    "no relaxed hover without this rotor: its loss cannot be flown on three"
                );
            }
            control
        })
        .as_ref()
    }

    fn reallocate(&mut self) -> Result<(), MixerError> {
        if self.config.motor_failure.reallocate {
            self.mixer.set_failed(self.motor_failure.failed())
        } else {
            Ok(())
        }
    }

    /// The mixer (to mark failed rotors).
    pub fn mixer_mut(&mut self) -> &mut Mixer {
        &mut self.mixer
    }

    /// Forgets the position loop's integrator and set-point history: on the ground before
    /// take-off, so that the spool-up does not wind it against the ground.
    pub fn reset_position_loop(&mut self) {
        self.position.reset();
        self.position_output = None;
        self.position_phase_s = 0.0;
    }

    fn reset_controllers(&mut self) {
        self.reset_position_loop();
        // The wind is learned afresh each flight (it may have changed, or the vehicle moved).
        self.disturbance.reset();
        self.wind = None;
        self.rate = rate_axes(&self.config.rate);
        // A new flight judges the rotors afresh.
        self.motor_failure.reset();
        self.spinning_without = None;
        self.last_mix = None;
        // Every rotor working is always allocatable.
        let _ = self.mixer.set_failed(&[false; MAX_ROTORS]);
    }

    /// Forgets the accelerometer bias learned in flight (the accelerometer's calibration
    /// changed).
    pub fn forget_accel_bias(&mut self) {
        self.attitude.forget_accel_bias();
    }

    /// The rotors' mean thrust fraction over the interval just sampled (0 when they were not
    /// driven): what the motor currents' magnetic field scales with, and what a land detector
    /// watches.
    pub fn thrust_fraction(&self) -> f64 {
        let max = self.config.position.max_thrust_n;
        match &self.last_mix {
            Some(m) if max > 0.0 => m.thrust_n.iter().sum::<f64>() / max,
            _ => 0.0,
        }
    }
}
