//! Airframes: mass, inertia tensor, rotors, drag and battery, read from `params/airframes/*.toml`.
//!
//! Shared by the simulator (which turns rotor speeds into forces) and the autopilot's mixer (which
//! builds its allocation from the geometry): one schema, one validation, two independent uses.
//!
//! The file gives rotor properties once in `[rotor_defaults]` and each rotor's position and spin in
//! `[[rotors]]`; a rotor may override any default (a bent prop, a different motor). Its
//! `[landing_gear]` (optional) is where its feet stand ([`LandingGear`]). Parsing
//! resolves every rotor to a complete [`RotorSpec`] and loading validates the physics
//! (positive mass, a symmetric positive-definite inertia tensor that a real body can have, 1–16
//! rotors, an allocation of rank 4) before anything flies.

pub mod config;
mod landing_gear;

use config::{Checker, parse_toml, read_toml};
pub use config::{ConfigError, Violation};
pub use landing_gear::{LandingGear, MAX_FEET};
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::Deserialize;
use std::path::Path;

/// Standard gravity (m/s²).
pub const GRAVITY_M_S2: f64 = 9.806_65;

/// Most rotors a vehicle may have: `HIL_ACTUATOR_CONTROLS` carries 16 channels.
pub const MAX_ROTORS: usize = 16;

/// Direction of rotation seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Spin {
    /// Counter-clockwise from above: the rotor spins about body −z and its reaction torque on the
    /// body is +z (nose right).
    Ccw,
    /// Clockwise from above: reaction torque −z (nose left).
    Cw,
}

impl Spin {
    /// Sign of the reaction torque about body z: +1 for ccw, −1 for cw (docs/conventions.md).
    pub fn sign(self) -> f64 {
        match self {
            Spin::Ccw => 1.0,
            Spin::Cw => -1.0,
        }
    }
}

/// Every physical property of one rotor, motor and propeller.
#[derive(Debug, Clone, PartialEq)]
pub struct RotorSpec {
    /// Hub position in the body frame FRD (m), relative to the centre of mass.
    pub position_frd_m: Vector3<f64>,
    /// Direction of rotation.
    pub spin: Spin,
    /// Thrust coefficient `K_T` of `T = K_T ρ n² D⁴` (Lewis (4.28)), dimensionless.
    pub k_t: f64,
    /// Torque coefficient `K_Q` of `Q = K_Q ρ n² D⁵` (Lewis (4.29)), dimensionless.
    pub k_q: f64,
    /// Propeller diameter `D` (m).
    pub diameter_m: f64,
    /// Motor time constant `τ` of `τ Ω̇ + Ω = a f(u, V)` (Lewis (6.8)), s.
    pub time_constant_s: f64,
    /// Highest rotor speed the motor reaches (rad/s).
    pub max_speed_rad_s: f64,
    /// Motor gain `a` of Lewis (6.8), rad/s per volt of effective motor voltage `u·V_batt`.
    pub motor_gain_rad_s_per_v: f64,
    /// Moment of inertia of the spinning parts about the rotor axis (kg·m²), for the gyroscopic
    /// and spin-up torques (Castillo (58)).
    pub inertia_kg_m2: f64,
}

impl RotorSpec {
    /// Yaw moment per newton of thrust, `c = K_Q D / K_T` (Lewis (4.34)), m.
    pub fn yaw_moment_per_thrust_m(&self) -> f64 {
        self.k_q * self.diameter_m / self.k_t
    }

    /// Thrust at rotor speed `omega` (rad/s): Lewis (4.27)–(4.28), `n = Ω/2π`.
    pub fn thrust_n(&self, air_density: f64, omega_rad_s: f64) -> f64 {
        let n = omega_rad_s / std::f64::consts::TAU;
        self.k_t * air_density * n * n * self.diameter_m.powi(4)
    }

    /// Aerodynamic drag torque on the propeller at speed `omega`: Lewis (4.29).
    pub fn drag_torque_n_m(&self, air_density: f64, omega_rad_s: f64) -> f64 {
        let n = omega_rad_s / std::f64::consts::TAU;
        self.k_q * air_density * n * n * self.diameter_m.powi(5)
    }

    /// Rotor speed that produces `thrust` newtons: Lewis (4.30), `Ω = (2π/D²) √(T/(ρ K_T))`.
    pub fn speed_for_thrust_rad_s(&self, air_density: f64, thrust_n: f64) -> f64 {
        std::f64::consts::TAU / (self.diameter_m * self.diameter_m)
            * (thrust_n.max(0.0) / (air_density * self.k_t)).sqrt()
    }
}

/// Body drag and the aerodynamic torque of Castillo (59).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DragSpec {
    /// Linear drag per body axis (N per m/s of air-relative velocity): rotor drag dominates.
    pub linear_n_s_m: [f64; 3],
    /// Quadratic drag per body axis (N per (m/s)²): `½ ρ C_d A` of the frame.
    pub quadratic_n_s2_m2: [f64; 3],
    /// Rotational damping per body axis (N·m per rad/s).
    pub rotational_n_m_s_rad: [f64; 3],
    /// Castillo (59) aerodynamic torque coefficients `C_x, C_y, C_z` (m³): the torque about body
    /// axis i is `½ ρ C_i W_i |W_i|` with `W` the air-relative velocity in FRD.
    #[serde(default)]
    pub aero_torque_m3: [f64; 3],
}

/// The flight battery.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BatterySpec {
    /// Cells in series (a 4S pack has 4).
    pub cells: u32,
    /// Capacity (mAh).
    pub capacity_mah: f64,
    /// Internal resistance of the whole pack (Ω): voltage sags by `I·R`.
    pub internal_resistance_ohm: f64,
    /// Combined motor and ESC efficiency (0–1) turning electrical into shaft power.
    pub efficiency: f64,
    /// Current drawn by avionics, independent of the motors (A).
    pub idle_current_a: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RotorDefaultsFile {
    k_t: Option<f64>,
    k_q: Option<f64>,
    diameter_m: Option<f64>,
    time_constant_s: Option<f64>,
    max_speed_rad_s: Option<f64>,
    motor_gain_rad_s_per_v: Option<f64>,
    inertia_kg_m2: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RotorFile {
    position_m: [f64; 3],
    spin: Spin,
    k_t: Option<f64>,
    k_q: Option<f64>,
    diameter_m: Option<f64>,
    time_constant_s: Option<f64>,
    max_speed_rad_s: Option<f64>,
    motor_gain_rad_s_per_v: Option<f64>,
    inertia_kg_m2: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct AirframeFile {
    name: String,
    #[serde(default)]
    description: String,
    mass_kg: f64,
    inertia_kg_m2: [[f64; 3]; 3],
    #[serde(default)]
    imu_position_m: [f64; 3],
    drag: DragSpec,
    battery: BatterySpec,
    rotor_defaults: Option<RotorDefaultsFile>,
    #[serde(default)]
    rotors: Vec<RotorFile>,
    landing_gear: Option<landing_gear::LandingGearFile>,
}

/// A complete, validated vehicle description.
#[derive(Debug, Clone, PartialEq)]
pub struct Airframe {
    /// Short name, e.g. `quad_x`.
    pub name: String,
    /// Free text.
    pub description: String,
    /// Total mass (kg).
    pub mass_kg: f64,
    /// Inertia tensor about the centre of mass in FRD (kg·m²), full and symmetric (Zabunov (58)).
    pub inertia_kg_m2: Matrix3<f64>,
    /// Position of the IMU in FRD relative to the centre of mass (m): the accelerometer sees the
    /// lever-arm accelerations of Zabunov (50)–(54).
    pub imu_position_frd_m: Vector3<f64>,
    /// Drag and aerodynamic torque.
    pub drag: DragSpec,
    /// Battery.
    pub battery: BatterySpec,
    /// Rotors in output order: rotor i is actuator channel i.
    pub rotors: Vec<RotorSpec>,
    /// What it stands on.
    pub landing_gear: LandingGear,
}

impl Airframe {
    /// Reads, resolves and validates an airframe file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let raw: AirframeFile = read_toml(path)?;
        Self::from_raw(raw, &path.display().to_string())
    }

    /// Parses and validates airframe TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let raw: AirframeFile = parse_toml(text, origin)?;
        Self::from_raw(raw, origin)
    }

    fn from_raw(raw: AirframeFile, file: &str) -> Result<Self, ConfigError> {
        let mut check = Checker::default();
        let defaults = raw.rotor_defaults.unwrap_or(RotorDefaultsFile {
            k_t: None,
            k_q: None,
            diameter_m: None,
            time_constant_s: None,
            max_speed_rad_s: None,
            motor_gain_rad_s_per_v: None,
            inertia_kg_m2: None,
        });
        let mut rotors = Vec::with_capacity(raw.rotors.len());
        for (i, r) in raw.rotors.iter().enumerate() {
            let mut take = |name: &str, own: Option<f64>, dflt: Option<f64>| -> f64 {
                own.or(dflt).unwrap_or_else(|| {
                    check.fail(
                        format!("rotors[{i}].{name}"),
                        "missing: set it on the rotor or in [rotor_defaults]",
                    );
                    f64::NAN
                })
            };
            rotors.push(RotorSpec {
                position_frd_m: Vector3::from(r.position_m),
                spin: r.spin,
                k_t: take("k_t", r.k_t, defaults.k_t),
                k_q: take("k_q", r.k_q, defaults.k_q),
                diameter_m: take("diameter_m", r.diameter_m, defaults.diameter_m),
                time_constant_s: take(
                    "time_constant_s",
                    r.time_constant_s,
                    defaults.time_constant_s,
                ),
                max_speed_rad_s: take(
                    "max_speed_rad_s",
                    r.max_speed_rad_s,
                    defaults.max_speed_rad_s,
                ),
                motor_gain_rad_s_per_v: take(
                    "motor_gain_rad_s_per_v",
                    r.motor_gain_rad_s_per_v,
                    defaults.motor_gain_rad_s_per_v,
                ),
                inertia_kg_m2: take("inertia_kg_m2", r.inertia_kg_m2, defaults.inertia_kg_m2),
            });
        }
        if !check.violations.is_empty() {
            // Missing rotor properties: report them alone, not again as invalid values.
            return Err(ConfigError::Invalid {
                file: file.to_owned(),
                violations: check.violations,
            });
        }
        let hubs: Vec<_> = rotors.iter().map(|r| r.position_frd_m).collect();
        let airframe = Airframe {
            landing_gear: LandingGear::from_file(raw.landing_gear, &hubs),
            name: raw.name,
            description: raw.description,
            mass_kg: raw.mass_kg,
            inertia_kg_m2: Matrix3::from_fn(|r, c| raw.inertia_kg_m2[r][c]),
            imu_position_frd_m: Vector3::from(raw.imu_position_m),
            drag: raw.drag,
            battery: raw.battery,
            rotors,
        };
        airframe.check(&mut check);
        check.finish(file)?;
        Ok(airframe)
    }

    /// Every physical violation in this airframe; empty when it can fly.
    fn check(&self, c: &mut Checker) {
        c.positive("mass_kg", self.mass_kg);
        check_inertia(c, &self.inertia_kg_m2);
        c.finite("imu_position_m", self.imu_position_frd_m.as_slice());
        for (k, v) in [
            ("drag.linear_n_s_m", &self.drag.linear_n_s_m),
            ("drag.quadratic_n_s2_m2", &self.drag.quadratic_n_s2_m2),
            ("drag.rotational_n_m_s_rad", &self.drag.rotational_n_m_s_rad),
        ] {
            for (i, x) in v.iter().enumerate() {
                c.non_negative(format!("{k}[{i}]"), *x);
            }
        }
        c.finite("drag.aero_torque_m3", &self.drag.aero_torque_m3);
        self.landing_gear.check(c);
        let b = &self.battery;
        if !(1..=24).contains(&b.cells) {
            c.fail(
                "battery.cells",
                format!("must be within [1, 24], got {}", b.cells),
            );
        }
        c.positive("battery.capacity_mah", b.capacity_mah);
        c.non_negative("battery.internal_resistance_ohm", b.internal_resistance_ohm);
        c.within("battery.efficiency", b.efficiency, 0.05, 1.0);
        c.non_negative("battery.idle_current_a", b.idle_current_a);
        let n = self.rotors.len();
        if n == 0 || n > MAX_ROTORS {
            c.fail(
                "rotors",
                format!("a multirotor needs 1 to {MAX_ROTORS} rotors, got {n}"),
            );
            return;
        }
        for (i, r) in self.rotors.iter().enumerate() {
            c.finite(
                format!("rotors[{i}].position_m"),
                r.position_frd_m.as_slice(),
            );
            c.positive(format!("rotors[{i}].k_t"), r.k_t);
            c.positive(format!("rotors[{i}].k_q"), r.k_q);
            c.positive(format!("rotors[{i}].diameter_m"), r.diameter_m);
            c.positive(format!("rotors[{i}].time_constant_s"), r.time_constant_s);
            c.positive(format!("rotors[{i}].max_speed_rad_s"), r.max_speed_rad_s);
            c.positive(
                format!("rotors[{i}].motor_gain_rad_s_per_v"),
                r.motor_gain_rad_s_per_v,
            );
            c.non_negative(format!("rotors[{i}].inertia_kg_m2"), r.inertia_kg_m2);
        }
        if c.violations.is_empty() {
            let rank = self.effectiveness().rank(1e-9);
            if rank < 4 {
                c.fail(
                    "rotors",
                    format!(
                        "the rotors' allocation matrix [F_z; M_x; M_y; M_z] has rank {rank} < 4: \
                         the vehicle cannot control thrust, roll, pitch and yaw independently \
                         (check positions and spin directions)"
                    ),
                );
            }
        }
    }

    /// The effectiveness matrix `B` (4 × N) from rotor thrusts `T_i` to the body wrench
    /// `[F_z, M_x, M_y, M_z]` (FRD): column i is `[−1, −y_i, x_i, ±c_i]`
    /// (docs/conventions.md).
    pub fn effectiveness(&self) -> DMatrix<f64> {
        DMatrix::from_fn(4, self.rotors.len(), |row, i| {
            let r = &self.rotors[i];
            match row {
                0 => -1.0,
                1 => -r.position_frd_m.y,
                2 => r.position_frd_m.x,
                _ => r.spin.sign() * r.yaw_moment_per_thrust_m(),
            }
        })
    }

    /// Weight (N) at standard gravity.
    pub fn weight_n(&self) -> f64 {
        self.mass_kg * GRAVITY_M_S2
    }
}

/// Symmetric, positive definite, and satisfying the triangle inequalities of principal moments
/// (`I_1 + I_2 ≥ I_3`), which every real mass distribution does.
fn check_inertia(c: &mut Checker, i: &Matrix3<f64>) {
    if i.iter().any(|x| !x.is_finite()) {
        c.fail("inertia_kg_m2", "must be finite");
        return;
    }
    let scale = i.abs().max().max(f64::MIN_POSITIVE);
    if (i - i.transpose()).abs().max() > 1e-9 * scale {
        c.fail(
            "inertia_kg_m2",
            "must be symmetric (I_xy = I_yx, I_xz = I_zx, I_yz = I_zy)",
        );
        return;
    }
    let eig = i.symmetric_eigenvalues();
    if eig.iter().any(|&l| l <= 0.0) {
        c.fail(
            "inertia_kg_m2",
            format!("must be positive definite; principal moments are {eig:?}"),
        );
        return;
    }
    let (a, b, d) = (eig[0], eig[1], eig[2]);
    let tol = 1e-9 * scale;
    if a + b < d - tol || a + d < b - tol || b + d < a - tol {
        c.fail(
            "inertia_kg_m2",
            format!(
                "principal moments {eig:?} violate the triangle inequality I1 + I2 >= I3 \
                 that every physical body satisfies"
            ),
        );
    }
}

#[cfg(test)]
mod tests;
