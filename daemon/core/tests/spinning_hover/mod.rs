//! A quad without a rotor in its relaxed hover in the simulator, flown on the truth by the
//! reduced-attitude controller around a position PD: the harness of the three-rotor tests.
#![allow(clippy::unwrap_used, dead_code)]

use airframe::Airframe;
use flight_core::control::reduced_attitude::ReducedAttitude;
use flight_core::control::relaxed_hover::{self, RelaxedHover};
use nalgebra::{UnitQuaternion, Vector3};
use sitl_core::body::BodyState;
use sitl_core::powertrain::Rotors;
use sitl_core::sim::{SimConfig, Simulator};

/// The flight: the airframe, its hover, the controller and the simulator.
pub struct SpinningHover {
    /// The airframe flown.
    pub airframe: Airframe,
    /// The relaxed hover the controller flies about (solved for a 30 rad/s spin).
    pub hover: RelaxedHover,
    /// The simulator.
    pub sim: Simulator,
    /// Where it started and holds (NED, m): 20 m up.
    pub start: Vector3<f64>,
    control: ReducedAttitude,
}

impl SpinningHover {
    /// `name` without rotor `lost`, in its relaxed hover at 20 m with the axis `tilt_deg` off the
    /// vertical (about body x), in the simulator `cfg`.
    pub fn new(name: &str, lost: usize, tilt_deg: f64, cfg: SimConfig) -> Self {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
        let a = Airframe::load(&dir.join(format!("{name}.toml"))).unwrap();
        let at = BodyState {
            pos_ned_m: Vector3::new(0.0, 0.0, -20.0),
            ..BodyState::default()
        };
        let probe = Simulator::new(&a, SimConfig::default(), at).unwrap();
        let rho = sitl_core::environment::isa(probe.truth().position().alt_m).density_kg_m3;
        let hover = relaxed_hover::solve_within_spin(&a, lost, 30.0, rho).unwrap();
        let control = ReducedAttitude::new(&a, hover.clone(), 1000.0).unwrap();
        let n = hover.axis_frd;
        let up = UnitQuaternion::rotation_between(&n, &-Vector3::z()).unwrap();
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians());
        let initial = BodyState {
            q_ned_from_frd: tilt * up,
            rate_frd_rad_s: n * hover.spin_rad_s,
            ..at
        };
        let mut sim = Simulator::new(&a, cfg, initial).unwrap();
        let speeds: Vec<f64> = a
            .rotors
            .iter()
            .zip(&hover.thrust_n)
            .map(|(r, &t)| r.speed_for_thrust_rad_s(hover.air_density, t))
            .collect();
        sim.set_rotor_speeds(&speeds);
        Self {
            airframe: a,
            hover,
            sim,
            start: at.pos_ned_m,
            control,
        }
    }

    /// One simulator step (1 ms): a position PD on the truth (horizontal acceleration at most
    /// 3 m/s²) asks a direction and a lift, the controller's thrusts become motor commands.
    /// Returns the direction asked and the truth the step began from.
    pub fn step(&mut self) -> (Vector3<f64>, BodyState) {
        let a = &self.airframe;
        let g = Vector3::new(0.0, 0.0, airframe::GRAVITY_M_S2);
        let t = self.sim.truth();
        let body = t.body;
        let mut accel = (self.start - body.pos_ned_m) - body.vel_ned_m_s * 1.8;
        let horizontal = accel.xy().norm();
        if horizontal > 3.0 {
            accel.x *= 3.0 / horizontal;
            accel.y *= 3.0 / horizontal;
        }
        let lift = accel - g;
        let up_ned = lift.normalize();
        let thrusts = self.control.update(
            &up_ned,
            a.mass_kg * lift.norm(),
            &body.q_ned_from_frd,
            &body.rate_frd_rad_s,
        );
        let rho = self.hover.air_density;
        let v = t.battery_voltage_v;
        let commands: Vec<f64> = a
            .rotors
            .iter()
            .zip(&thrusts)
            .map(|(r, &f)| Rotors::command_for_speed(r, r.speed_for_thrust_rad_s(rho, f), v))
            .collect();
        self.sim.step(&commands);
        (up_ned, body)
    }
}
