//! Motors, propellers and the battery: actuator commands in, body wrench out.

use crate::airframe::{Airframe, BatterySpec, MAX_ROTORS, RotorSpec};
use nalgebra::Vector3;

/// Open-circuit voltage of one LiPo cell against state of charge (0–1), a typical discharge curve.
const CELL_CURVE: [(f64, f64); 7] = [
    (0.0, 3.30),
    (0.05, 3.50),
    (0.10, 3.60),
    (0.20, 3.70),
    (0.50, 3.80),
    (0.80, 4.00),
    (1.00, 4.20),
];

/// Open-circuit voltage of one cell at state of charge `soc`.
pub fn cell_voltage(soc: f64) -> f64 {
    let soc = soc.clamp(0.0, 1.0);
    for w in CELL_CURVE.windows(2) {
        let ((s0, v0), (s1, v1)) = (w[0], w[1]);
        if soc <= s1 {
            return v0 + (v1 - v0) * (soc - s0) / (s1 - s0);
        }
    }
    CELL_CURVE[CELL_CURVE.len() - 1].1
}

/// A battery whose voltage sags with current: `V = N·V_cell(SoC) − I·R`.
#[derive(Debug, Clone, PartialEq)]
pub struct Battery {
    spec: BatterySpec,
    /// Charge drawn so far (mAh).
    pub consumed_mah: f64,
    /// Current of the last step (A).
    pub current_a: f64,
}

impl Battery {
    /// A full battery.
    pub fn new(spec: &BatterySpec) -> Self {
        Self {
            spec: spec.clone(),
            consumed_mah: 0.0,
            current_a: 0.0,
        }
    }

    /// A battery charged to `remaining` (0–1) of its capacity.
    pub fn charged_to(spec: &BatterySpec, remaining: f64) -> Self {
        Self {
            consumed_mah: (1.0 - remaining.clamp(0.0, 1.0)) * spec.capacity_mah,
            ..Self::new(spec)
        }
    }

    /// State of charge, 0–1.
    pub fn remaining(&self) -> f64 {
        (1.0 - self.consumed_mah / self.spec.capacity_mah).clamp(0.0, 1.0)
    }

    /// Terminal voltage under the last step's load (V).
    pub fn voltage(&self) -> f64 {
        let open = self.spec.cells as f64 * cell_voltage(self.remaining());
        (open - self.current_a * self.spec.internal_resistance_ohm).max(0.0)
    }

    /// Draws the current that delivers `shaft_power_w` to the rotors for `dt` seconds.
    pub fn draw(&mut self, shaft_power_w: f64, dt: f64) {
        let v = self.voltage().max(1.0);
        self.current_a =
            shaft_power_w.max(0.0) / (self.spec.efficiency * v) + self.spec.idle_current_a;
        self.consumed_mah += self.current_a * dt / 3.6;
    }
}

/// Faults injected into one rotor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotorFault {
    /// The motor no longer turns (ESC or motor failure): its speed decays to zero.
    pub failed: bool,
    /// Fraction of nominal thrust and drag torque the propeller still makes (a chipped prop).
    pub effectiveness: f64,
}

impl Default for RotorFault {
    fn default() -> Self {
        Self {
            failed: false,
            effectiveness: 1.0,
        }
    }
}

/// What the rotors do to the body during one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotorWrench {
    /// Total rotor force in FRD (N).
    pub force_frd_n: Vector3<f64>,
    /// Total rotor moment in FRD (N·m): thrust moments, drag reaction and spin-up reaction.
    pub torque_frd_n_m: Vector3<f64>,
    /// Angular momentum of the spinning rotors in FRD (N·m·s): the body feels `−ω × h`
    /// (the gyroscopic torque of Castillo (58)).
    pub rotor_momentum_frd: Vector3<f64>,
    /// Shaft power the motors deliver (W).
    pub shaft_power_w: f64,
    /// Each rotor's thrust (N), along body −z at its hub: what an external flight-dynamics
    /// model applies rotor by rotor.
    pub thrust_n: [f64; MAX_ROTORS],
    /// Each rotor's yaw moment on the body (N·m, about +z): drag and spin-up reaction.
    pub yaw_moment_n_m: [f64; MAX_ROTORS],
}

/// Rotor speeds and the motor model `τ Ω̇ + Ω = a f(u, V_batt)` of Lewis (6.8), with
/// `f(u, V) = u·V` (the ESC applies the fraction u of the battery voltage) and the result clamped to
/// the motor's top speed.
///
/// The lag is integrated exactly for a command held over the step (zero-order hold), so it is
/// stable and accurate at any step size; the rigid body sees the speeds at mid-step.
#[derive(Debug, Clone)]
pub struct Rotors {
    specs: Vec<RotorSpec>,
    /// Rotor speeds (rad/s), always ≥ 0.
    pub speed_rad_s: [f64; MAX_ROTORS],
    /// Injected faults.
    pub faults: [RotorFault; MAX_ROTORS],
    decay: [(f64, f64, f64); MAX_ROTORS], // (dt, e^{-dt/τ}, e^{-dt/2τ}) cached per rotor
}

impl Rotors {
    /// Rotors at rest.
    pub fn new(airframe: &Airframe) -> Self {
        Self {
            specs: airframe.rotors.clone(),
            speed_rad_s: [0.0; MAX_ROTORS],
            faults: [RotorFault::default(); MAX_ROTORS],
            decay: [(f64::NAN, 0.0, 0.0); MAX_ROTORS],
        }
    }

    /// Number of rotors.
    pub fn len(&self) -> usize {
        self.specs.len()
    }

    /// Whether there are no rotors (never, for a validated airframe).
    pub fn is_empty(&self) -> bool {
        self.specs.is_empty()
    }

    /// Steady-state speed for command `u` ∈ [0, 1] at battery voltage `v`: Lewis (6.8).
    pub fn commanded_speed(spec: &RotorSpec, u: f64, v_batt: f64) -> f64 {
        (spec.motor_gain_rad_s_per_v * u * v_batt).clamp(0.0, spec.max_speed_rad_s)
    }

    /// Command that holds `speed` at battery voltage `v`: the inverse motor curve (Lewis (6.12)).
    pub fn command_for_speed(spec: &RotorSpec, speed_rad_s: f64, v_batt: f64) -> f64 {
        speed_rad_s / (spec.motor_gain_rad_s_per_v * v_batt)
    }

    /// Advances the motors by `dt` under commands `u` (already sanitised to [0, 1]) and returns the
    /// wrench on the body from the mid-step speeds, in air of density `rho`.
    pub fn step(&mut self, u: &[f64], v_batt: f64, rho: f64, dt: f64) -> RotorWrench {
        let mut w_mid = [0.0; MAX_ROTORS];
        let mut w_dot_mid = [0.0; MAX_ROTORS];
        for (i, spec) in self.specs.iter().enumerate() {
            let target = if self.faults[i].failed {
                0.0
            } else {
                Self::commanded_speed(spec, u.get(i).copied().unwrap_or(0.0), v_batt)
            };
            if self.decay[i].0 != dt {
                let tau = spec.time_constant_s;
                self.decay[i] = (dt, (-dt / tau).exp(), (-0.5 * dt / tau).exp());
            }
            let (_, full, half) = self.decay[i];
            let w0 = self.speed_rad_s[i];
            w_mid[i] = target + (w0 - target) * half;
            w_dot_mid[i] = (target - w_mid[i]) / spec.time_constant_s;
            self.speed_rad_s[i] = (target + (w0 - target) * full).max(0.0);
        }
        self.wrench_at(&w_mid, &w_dot_mid, rho)
    }

    /// Sets the speeds as if they had been held for long (no spin-up torque).
    fn set_steady(&mut self, speeds: &[f64]) {
        for (s, v) in self.speed_rad_s.iter_mut().zip(speeds) {
            *s = v.max(0.0);
        }
    }

    /// The wrench of rotors at speeds `w` accelerating at `w_dot`.
    fn wrench_at(&self, w: &[f64; MAX_ROTORS], w_dot: &[f64; MAX_ROTORS], rho: f64) -> RotorWrench {
        let mut force = Vector3::zeros();
        let mut torque = Vector3::zeros();
        let mut momentum_z = 0.0;
        let mut power = 0.0;
        let mut thrusts = [0.0; MAX_ROTORS];
        let mut yaw_moments = [0.0; MAX_ROTORS];
        for (i, spec) in self.specs.iter().enumerate() {
            let eff = self.faults[i].effectiveness;
            let thrust = eff * spec.thrust_n(rho, w[i]); // Lewis (4.28)
            let drag_torque = eff * spec.drag_torque_n_m(rho, w[i]); // Lewis (4.29)
            let s = spec.spin.sign();
            let p = &spec.position_frd_m;
            // Thrust along −z at the hub: moment r × (0, 0, −T) = (−y T, x T, 0).
            force.z -= thrust;
            torque.x -= p.y * thrust;
            torque.y += p.x * thrust;
            // Reaction to the drag torque (+z for ccw) and to spinning the rotor up (a ccw rotor
            // spins about −z; the motor pushing it faster pushes the body about +z).
            let yaw = s * (drag_torque + spec.inertia_kg_m2 * w_dot[i]);
            torque.z += yaw;
            thrusts[i] = thrust;
            yaw_moments[i] = yaw;
            // Rotor angular momentum: ccw spins about −z.
            momentum_z -= s * spec.inertia_kg_m2 * w[i];
            power += drag_torque * w[i];
        }
        RotorWrench {
            force_frd_n: force,
            torque_frd_n_m: torque,
            rotor_momentum_frd: Vector3::new(0.0, 0.0, momentum_z),
            shaft_power_w: power,
            thrust_n: thrusts,
            yaw_moment_n_m: yaw_moments,
        }
    }
}

/// The steady-state body wrench `[F_z, M_x, M_y, M_z]` (FRD) of the rotors turning at `speeds`
/// (rad/s) in air of density `rho`, computed rotor by rotor from the physics of [`Rotors::step`]:
/// the simulator's side of the check that a mixer's allocation reproduces the vehicle.
pub fn steady_wrench(airframe: &Airframe, speeds: &[f64], rho: f64) -> [f64; 4] {
    let mut rotors = Rotors::new(airframe);
    rotors.set_steady(speeds);
    let w = rotors.wrench_at(&rotors.speed_rad_s.clone(), &[0.0; MAX_ROTORS], rho);
    [
        w.force_frd_n.z,
        w.torque_frd_n_m.x,
        w.torque_frd_n_m.y,
        w.torque_frd_n_m.z,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lipo_curve_is_monotonic_and_bounded() {
        let mut last = 0.0;
        for k in 0..=100 {
            let v = cell_voltage(k as f64 / 100.0);
            assert!(v >= last && (3.3..=4.2).contains(&v));
            last = v;
        }
    }

    #[test]
    fn battery_sags_under_load_and_drains() {
        let spec = BatterySpec {
            cells: 4,
            capacity_mah: 5000.0,
            internal_resistance_ohm: 0.025,
            efficiency: 0.7,
            idle_current_a: 0.5,
        };
        let mut b = Battery::new(&spec);
        let v_rest = b.voltage();
        assert!((v_rest - 16.8).abs() < 1e-9);
        b.draw(300.0, 1.0);
        assert!(b.current_a > 20.0);
        assert!(b.voltage() < v_rest - 0.5, "no sag: {}", b.voltage());
        // 1 hour at that current drains far more than the capacity: empty, never negative.
        for _ in 0..3600 {
            b.draw(300.0, 1.0);
        }
        assert_eq!(b.remaining(), 0.0);
        assert!(b.voltage() >= 0.0);
    }
}
