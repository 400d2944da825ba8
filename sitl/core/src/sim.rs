//! The simulated vehicle: rigid body, rotors, battery, air, ground contact, faults and sensors.
//!
//! [`Simulator::step`] advances physics by one fixed step under actuator commands;
//! [`Simulator::sample_sensors`] then reports what the flight board would measure. No I/O, no
//! clock: the simulation time is the step count times the step.

use crate::GRAVITY_M_S2;
use crate::airframe::{Airframe, MAX_ROTORS};
use crate::body::{Accel, BodyState, Integrator, MassProperties};
use crate::environment::{AirState, Wind, WindConfig, isa};
use crate::powertrain::{Battery, RotorWrench, Rotors};
use crate::rng::Rng;
use crate::sensors::{EarthField, SensorConfig, SensorFrame, SensorSuite, Truth};
use nalgebra::{DVector, UnitQuaternion, Vector3};
use navmath::geo::{LatLonAlt, LocalFrame};

use events::Pulse;
pub use events::{Event, SimAction};
pub use external_body::{ExternalBody, ExternalBodyError, ExternalBodyStep, StepLoads};
use ground::{Contact, Ground};
use hand::Hand;
pub use hand::{Face, PLACE_S, SET_DOWN_S, TUMBLE_RAMP_S, tumble_attitude};
pub use truth::TruthState;

/// How the simulation is set up.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Physics step (s).
    pub dt_s: f64,
    /// Integration scheme.
    pub integrator: Integrator,
    /// Seed of every random process (sensor noise, turbulence).
    pub seed: u64,
    /// Sensor parameters.
    pub sensors: SensorConfig,
    /// Earth magnetic field at the site.
    pub earth_field: EarthField,
    /// Geodetic (WGS-84) position of the local NED origin (on the ground).
    pub home: LatLonAlt,
    /// Wind and turbulence.
    pub wind: WindConfig,
    /// The battery's charge at the start (0–1).
    pub battery_charge: f64,
    /// A hand does what the autopilot's calibrations ask of the person holding the vehicle
    /// (`SIM_CAL_HAND`): turns it, places it on its faces, holds it still.
    pub calibration_hand: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            dt_s: 0.001,
            integrator: Integrator::Rk4,
            seed: 1,
            sensors: SensorConfig::preset(crate::sensors::SensorPreset::Typical),
            earth_field: EarthField::default(),
            home: LatLonAlt::default(),
            wind: WindConfig::default(),
            battery_charge: 1.0,
            calibration_hand: true,
        }
    }
}

/// Counters of everything the simulator had to correct or refuse.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SimStats {
    /// Steps taken.
    pub steps: u64,
    /// Actuator values outside [0, 1] that were clamped.
    pub clamped_commands: u64,
    /// Non-finite actuator values replaced by 0.
    pub nonfinite_commands: u64,
    /// Touchdowns (transitions from flying to landed; a bounce shorter than
    /// [`BOUNCE_S`] is the same touchdown).
    pub touchdowns: u64,
    /// Vertical speed at the last touchdown (m/s, positive down).
    pub last_touchdown_speed_m_s: f64,
}

/// Time in the air after which a contact is a new touchdown, not a bounce of the last (s).
pub const BOUNCE_S: f64 = 0.5;

/// How long a vehicle set down settles on its legs before the world starts (s).
const SETTLE_S: f64 = 2.0;

/// Below these a body on the ground is at rest and its step is skipped, as a physics engine
/// lets a resting body sleep: speed (m/s), body rate (rad/s), and the accelerations the loads
/// would give it (m/s², rad/s²).
const REST_SPEED: f64 = 1e-9;
const REST_ACCEL: f64 = 1e-9;

/// The whole simulated vehicle and its world.
pub struct Simulator {
    airframe: Airframe,
    mass: MassProperties,
    cfg: SimConfig,
    dt_usec: u64,
    time_usec: u64,
    body: BodyState,
    rotors: Rotors,
    battery: Battery,
    wind: Wind,
    sensors: SensorSuite,
    ground: Ground,
    landed: bool,
    /// When a foot last touched the ground (µs).
    last_contact_usec: Option<u64>,
    accel_ned: Vector3<f64>,
    ang_accel_frd: Vector3<f64>,
    air: AirState,
    /// The local frame at home: the truth's geodetic position.
    home: LocalFrame,
    wind_ned: Vector3<f64>,
    pulses: Vec<Pulse>,
    hand: Option<Hand>,
    calibration_hand: bool,
    events: Vec<Event>,
    max_speeds: [f64; MAX_ROTORS],
    stats: SimStats,
    hover_thrust_n: DVector<f64>,
}

/// Why a simulator cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The step must be positive and at most 50 ms.
    #[error("physics step must be within (0, 0.05] s, got {0}")]
    Step(f64),
    /// An event names a rotor the airframe does not have.
    #[error("event at t = {t_s} s names motor {motor}, but the airframe has {count} rotors")]
    Motor {
        /// Event time.
        t_s: f64,
        /// 1-based motor number.
        motor: usize,
        /// Rotor count.
        count: usize,
    },
    /// The inertia tensor is singular (validated airframes never are).
    #[error("inertia tensor is singular")]
    Inertia,
}

impl Simulator {
    /// A vehicle of `airframe` in state `initial`; at or below ground level (z ≥ 0) it starts
    /// standing on its feet, level at the initial heading, settled on its legs.
    pub fn new(airframe: &Airframe, cfg: SimConfig, initial: BodyState) -> Result<Self, SimError> {
        if !(cfg.dt_s > 0.0 && cfg.dt_s <= 0.05) {
            return Err(SimError::Step(cfg.dt_s));
        }
        let mass = MassProperties::new(airframe.mass_kg, airframe.inertia_kg_m2)
            .ok_or(SimError::Inertia)?;
        let mut max_speeds = [0.0; MAX_ROTORS];
        for (m, r) in max_speeds.iter_mut().zip(&airframe.rotors) {
            *m = r.max_speed_rad_s;
        }
        // Minimum-norm rotor thrusts for the hover wrench [−W, 0, 0, 0]: B⁺ w.
        let b = airframe.effectiveness();
        let w = DVector::from_vec(vec![-airframe.weight_n(), 0.0, 0.0, 0.0]);
        let hover_thrust_n = b
            .clone()
            .pseudo_inverse(1e-12)
            .map(|p| p * w)
            .unwrap_or_else(|_| {
                DVector::from_element(
                    airframe.rotors.len(),
                    airframe.weight_n() / airframe.rotors.len() as f64,
                )
            });
        let sensors = SensorSuite::new(
            cfg.sensors.clone(),
            cfg.earth_field,
            cfg.home,
            airframe.imu_position_frd_m,
            cfg.seed,
        );
        let wind = Wind::new(&cfg.wind, Rng::stream(cfg.seed, 8));
        let mut sim = Self {
            mass,
            dt_usec: (cfg.dt_s * 1e6).round() as u64,
            time_usec: 0,
            body: initial,
            rotors: Rotors::new(airframe),
            battery: Battery::charged_to(&airframe.battery, cfg.battery_charge),
            wind,
            sensors,
            ground: Ground::new(airframe, cfg.dt_s),
            landed: false,
            last_contact_usec: None,
            accel_ned: Vector3::zeros(),
            ang_accel_frd: Vector3::zeros(),
            air: isa(cfg.home.alt_m - initial.pos_ned_m.z),
            home: LocalFrame::new(cfg.home),
            wind_ned: Vector3::from(cfg.wind.mean_ned_m_s),
            pulses: Vec::new(),
            hand: None,
            calibration_hand: cfg.calibration_hand,
            events: Vec::new(),
            max_speeds,
            stats: SimStats::default(),
            hover_thrust_n,
            airframe: airframe.clone(),
            cfg,
        };
        if sim.body.pos_ned_m.z >= 0.0 {
            sim.stand_on_feet();
        }
        Ok(sim)
    }

    /// Whether the hand does what the autopilot's calibrations ask ([`SimConfig::calibration_hand`]).
    pub fn calibration_hand(&self) -> bool {
        self.calibration_hand
    }

    /// Simulation time (s).
    pub fn time_s(&self) -> f64 {
        self.time_usec as f64 * 1e-6
    }

    /// Simulation time (µs): the clock of the whole SITL run.
    pub fn time_usec(&self) -> u64 {
        self.time_usec
    }

    /// The airframe being flown.
    pub fn airframe(&self) -> &Airframe {
        &self.airframe
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// Counters.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// Rotor speeds (rad/s).
    pub fn rotor_speeds(&self) -> &[f64] {
        &self.rotors.speed_rad_s[..self.rotors.len()]
    }

    /// Sets every rotor's speed (rad/s), e.g. to start in hover.
    pub fn set_rotor_speeds(&mut self, speeds: &[f64]) {
        for (s, v) in self.rotors.speed_rad_s.iter_mut().zip(speeds) {
            *s = v.max(0.0);
        }
    }

    /// The sensor models, to change how they draw their noise.
    pub fn sensors_mut(&mut self) -> &mut SensorSuite {
        &mut self.sensors
    }

    /// The sensors, for fault injection and scoring (true biases).
    pub fn sensors(&self) -> &SensorSuite {
        &self.sensors
    }

    /// Rotor speeds of the minimum-norm hover thrust split in the current air (rad/s):
    /// Lewis (4.30) applied to `B⁺ [−W, 0, 0, 0]`.
    pub fn hover_speeds(&self) -> [f64; MAX_ROTORS] {
        let mut out = [0.0; MAX_ROTORS];
        for (i, spec) in self.airframe.rotors.iter().enumerate() {
            out[i] = spec.speed_for_thrust_rad_s(self.air.density_kg_m3, self.hover_thrust_n[i]);
        }
        out
    }

    /// Commands that hold the hover speeds at the present battery voltage: the inverse motor
    /// curve of Lewis (6.12).
    pub fn hover_commands(&self) -> [f64; MAX_ROTORS] {
        let speeds = self.hover_speeds();
        let v = self.battery.voltage();
        let mut out = [0.0; MAX_ROTORS];
        for (i, spec) in self.airframe.rotors.iter().enumerate() {
            out[i] = Rotors::command_for_speed(spec, speeds[i], v);
        }
        out
    }

    /// The true state now.
    pub fn truth(&self) -> TruthState {
        TruthState {
            time_usec: self.time_usec,
            body: self.body,
            accel_ned_m_s2: self.accel_ned,
            home: self.home,
            wind_ned_m_s: self.wind_ned,
            landed: self.landed,
            battery_voltage_v: self.battery.voltage(),
            battery_current_a: self.battery.current_a,
            battery_remaining: self.battery.remaining(),
        }
    }

    /// Mass properties in use.
    pub fn mass_properties(&self) -> &MassProperties {
        &self.mass
    }

    /// Stands the vehicle on its feet where it is, level at its heading, and lets it settle on
    /// its legs under its weight alone ([`SETTLE_S`], outside the world's time): it starts at
    /// rest, as a vehicle put down by hand does.
    fn stand_on_feet(&mut self) {
        let (_, _, yaw) = self.body.q_ned_from_frd.euler_angles();
        self.body.pos_ned_m.z = 0.0;
        self.body.vel_ned_m_s = Vector3::zeros();
        self.body.rate_frd_rad_s = Vector3::zeros();
        self.body.q_ned_from_frd = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
        self.ground.release();
        let still = Loads {
            rotor: RotorWrench {
                force_frd_n: Vector3::zeros(),
                torque_frd_n_m: Vector3::zeros(),
                rotor_momentum_frd: Vector3::zeros(),
                shaft_power_w: 0.0,
                thrust_n: [0.0; MAX_ROTORS],
                yaw_moment_n_m: [0.0; MAX_ROTORS],
            },
            rho: self.air.density_kg_m3,
            wind_ned: Vector3::zeros(),
            ext_force_ned: Vector3::zeros(),
            ext_torque_frd: Vector3::zeros(),
        };
        let dt = self.cfg.dt_s;
        // Level on legs of equal depth around the centre of mass, z = 0 is the rest already and
        // the first steps say so; other legs settle.
        for _ in 0..(SETTLE_S / dt).round() as usize {
            self.integrate(&still);
            if self.body.vel_ned_m_s.norm() < 1e-9 && self.body.rate_frd_rad_s.norm() < 1e-9 {
                break;
            }
        }
        self.landed = true;
        self.last_contact_usec = Some(self.time_usec);
    }

    /// Whether the body rests on the ground with nothing to move it: it stays as it is this
    /// step (the integrator would move it by less than `REST_ACCEL` dt², and at a quarter of
    /// the cost on the ground, where a vehicle waits most of its time on the ground).
    fn resting(&self, loads: &Loads) -> bool {
        let b = &self.body;
        if !self.landed
            || b.vel_ned_m_s.norm() >= REST_SPEED
            || b.rate_frd_rad_s.norm() >= REST_SPEED
        {
            return false;
        }
        let forces = Forces {
            loads,
            mass: &self.mass,
            drag: &self.airframe.drag,
            ground: self.ground.contact(b),
        };
        let a = forces.accel(b);
        a.lin_ned_m_s2.norm() < REST_ACCEL && a.ang_frd_rad_s2.norm() < REST_ACCEL
    }

    /// Moves the rigid body one step under `loads`, gravity and the ground; whether a point of
    /// it touches the ground after.
    fn integrate(&mut self, loads: &Loads) -> bool {
        let forces = Forces {
            loads,
            mass: &self.mass,
            drag: &self.airframe.drag,
            ground: self.ground.contact(&self.body),
        };
        self.body = self
            .cfg
            .integrator
            .step(&self.body, self.cfg.dt_s, |s| forces.accel(s));
        self.ground.settle_anchors(&self.body)
    }

    /// Sanitises actuator commands: NaN → 0, clamped to [0, 1], both counted.
    fn sanitise(&mut self, controls: &[f64]) -> [f64; MAX_ROTORS] {
        let mut u = [0.0; MAX_ROTORS];
        for (i, &c) in controls.iter().take(self.rotors.len()).enumerate() {
            u[i] = if !c.is_finite() {
                self.stats.nonfinite_commands += 1;
                0.0
            } else if !(0.0..=1.0).contains(&c) {
                self.stats.clamped_commands += 1;
                c.clamp(0.0, 1.0)
            } else {
                c
            };
        }
        u
    }

    /// What acts this step, before the body moves: due events, the rotors over the step, the
    /// air and the wind at the vehicle, the external pulses.
    fn begin_step(&mut self, controls: &[f64]) -> Loads {
        let dt = self.cfg.dt_s;
        let t = self.time_s();
        while self.events.last().is_some_and(|e| e.t_s <= t + 1e-9) {
            if let Some(e) = self.events.pop() {
                self.apply(e.action);
            }
        }
        let u = self.sanitise(controls);
        let altitude_agl = -self.body.pos_ned_m.z;
        self.air = isa(self.cfg.home.alt_m + altitude_agl);
        let v_batt = self.battery.voltage();
        let rotor = self.rotors.step(&u, v_batt, self.air.density_kg_m3, dt);
        self.wind_ned = self
            .wind
            .step(t, dt, &self.body.vel_ned_m_s, altitude_agl.max(0.0));
        let mut ext_force_ned = Vector3::zeros();
        let mut ext_torque_frd = Vector3::zeros();
        self.pulses.retain(|p| t < p.until_s);
        for p in &self.pulses {
            ext_force_ned += p.force_ned_n;
            ext_torque_frd += p.torque_frd_n_m;
        }
        Loads {
            rotor,
            rho: self.air.density_kg_m3,
            wind_ned: self.wind_ned,
            ext_force_ned,
            ext_torque_frd,
        }
    }

    /// The battery and the clock after the body has moved.
    fn end_step(&mut self, rotor: &RotorWrench) {
        self.battery.draw(rotor.shaft_power_w, self.cfg.dt_s);
        self.time_usec += self.dt_usec;
        self.stats.steps += 1;
    }

    /// Advances the world by one step under actuator commands `controls[i]` ∈ [0, 1] for rotor i.
    pub fn step(&mut self, controls: &[f64]) {
        let dt = self.cfg.dt_s;
        let loads = self.begin_step(controls);
        let before = self.body;
        if let Some(hand) = self.hand {
            self.turn_by_hand(hand, dt);
        } else {
            let touching = self.resting(&loads) || self.integrate(&loads);
            if touching {
                let bounce_usec = (BOUNCE_S * 1e6) as u64;
                let airborne = self
                    .last_contact_usec
                    .is_none_or(|last| self.time_usec.saturating_sub(last) > bounce_usec);
                if !self.landed && airborne {
                    self.stats.touchdowns += 1;
                    self.stats.last_touchdown_speed_m_s = before.vel_ned_m_s.z;
                }
                self.last_contact_usec = Some(self.time_usec);
            }
            self.landed = touching;
        }
        self.accel_ned = (self.body.vel_ned_m_s - before.vel_ned_m_s) / dt;
        self.ang_accel_frd = (self.body.rate_frd_rad_s - before.rate_frd_rad_s) / dt;
        self.end_step(&loads.rotor);
    }

    /// Advances the world by one step as [`Simulator::step`] does, but the rigid body, gravity
    /// and the ground are `body`'s (an external flight-dynamics model such as JSBSim): it gets
    /// the loads of the step, taken at its start, and says where the body is after it. Rotors,
    /// battery, air, wind, events and sensors stay this simulator's.
    pub fn step_with(
        &mut self,
        controls: &[f64],
        body: &mut dyn ExternalBody,
    ) -> Result<(), ExternalBodyError> {
        let loads = self.begin_step(controls);
        let forces = Forces {
            loads: &loads,
            mass: &self.mass,
            drag: &self.airframe.drag,
            ground: Contact::NONE,
        };
        let (aero_force_frd_n, aero_moment_frd_n_m) = forces.body_loads(&self.body);
        let after = body.advance(&StepLoads {
            dt_s: self.cfg.dt_s,
            rotor: loads.rotor,
            aero_force_frd_n,
            aero_moment_frd_n_m,
        })?;
        if after.on_ground && !self.landed {
            self.stats.touchdowns += 1;
            self.stats.last_touchdown_speed_m_s = self.body.vel_ned_m_s.z;
        }
        self.landed = after.on_ground;
        self.body = after.body;
        // What the accelerometer feels, as the acceleration the sensor models take: a = R f + g.
        self.accel_ned = after
            .body
            .q_ned_from_frd
            .transform_vector(&after.specific_force_frd_m_s2)
            + Vector3::new(0.0, 0.0, GRAVITY_M_S2);
        self.ang_accel_frd = after.ang_accel_frd_rad_s2;
        self.end_step(&loads.rotor);
        Ok(())
    }

    /// What the sensors report after the last step.
    pub fn sample_sensors(&mut self) -> &SensorFrame {
        let n = self.rotors.len();
        let truth = Truth {
            time_usec: self.time_usec,
            pos_ned_m: self.body.pos_ned_m,
            vel_ned_m_s: self.body.vel_ned_m_s,
            accel_ned_m_s2: self.accel_ned,
            q_ned_from_frd: self.body.q_ned_from_frd,
            rate_frd_rad_s: self.body.rate_frd_rad_s,
            ang_accel_frd_rad_s2: self.ang_accel_frd,
            air: self.air,
            rotor_speed_rad_s: &self.rotors.speed_rad_s[..n],
            rotor_max_speed_rad_s: &self.max_speeds[..n],
        };
        self.sensors.sample(&truth)
    }
}

/// What acts on the body during one step, apart from gravity and the ground.
struct Loads {
    rotor: RotorWrench,
    rho: f64,
    wind_ned: Vector3<f64>,
    ext_force_ned: Vector3<f64>,
    ext_torque_frd: Vector3<f64>,
}

/// The forces of one step, as a function of the state the integrator asks about.
struct Forces<'a> {
    loads: &'a Loads,
    mass: &'a MassProperties,
    drag: &'a crate::airframe::DragSpec,
    /// The ground's push, taken at the step's start and held over it (as the rotors' loads
    /// are): a quarter of the contact's cost for RK4, and the legs' bounce (ω dt ≤ 0.5, damped
    /// at ζ 0.7) stays stable.
    ground: Contact,
}

impl Forces<'_> {
    /// Everything but the rotors' thrust and yaw moments, gravity and the ground, at the
    /// centre of mass in FRD: drag and the external force (N); the rotors' gyroscopic torque,
    /// aerodynamic torque, damping and the external torque (N·m).
    fn body_loads(&self, s: &BodyState) -> (Vector3<f64>, Vector3<f64>) {
        let l = self.loads;
        let q = &s.q_ned_from_frd;
        let w = &s.rate_frd_rad_s;
        let air_frd = q.inverse_transform_vector(&(s.vel_ned_m_s - l.wind_ned));
        let lin = Vector3::from(self.drag.linear_n_s_m);
        let quad = Vector3::from(self.drag.quadratic_n_s2_m2);
        let drag_frd = -lin.component_mul(&air_frd)
            - quad.component_mul(&air_frd.component_mul(&air_frd.abs()));
        let force = drag_frd + q.inverse_transform_vector(&l.ext_force_ned);
        // Castillo (57)–(59): gyroscopic torque of the spinning rotors −ω × h, aerodynamic
        // torque (signed so that it opposes the air-relative velocity), damping.
        let aero = Vector3::from(self.drag.aero_torque_m3)
            .component_mul(&air_frd.component_mul(&air_frd.abs()))
            * (0.5 * l.rho);
        let damping = Vector3::from(self.drag.rotational_n_m_s_rad).component_mul(w);
        let moment = -w.cross(&l.rotor.rotor_momentum_frd) - aero - damping + l.ext_torque_frd;
        (force, moment)
    }

    fn accel(&self, s: &BodyState) -> Accel {
        let (force_frd, moment_frd) = self.body_loads(s);
        let rotor = &self.loads.rotor;
        let ground = &self.ground;
        let force_ned = s
            .q_ned_from_frd
            .transform_vector(&(rotor.force_frd_n + force_frd))
            + Vector3::new(0.0, 0.0, self.mass.mass_kg * GRAVITY_M_S2)
            + ground.force_ned_n;
        let moment = rotor.torque_frd_n_m + moment_frd + ground.moment_frd_n_m;
        Accel {
            lin_ned_m_s2: force_ned / self.mass.mass_kg,
            ang_frd_rad_s2: self.mass.angular_accel(&s.rate_frd_rad_s, &moment),
        }
    }
}

mod events;
mod external_body;
mod ground;
mod hand;
#[cfg(test)]
mod tests;
mod truth;
