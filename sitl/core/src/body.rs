//! Six-degree-of-freedom rigid-body dynamics and the five integrators.
//!
//! Translation in NED, rotation by Euler's equations with the full inertia tensor:
//! `ω̇ = I⁻¹ (M − ω × I ω)` (Lewis (4.43), Davailus (2), Zabunov (63)–(64) in matrix form), and
//! `q̇ = ½ q ⊗ ω` (Lewis (4.45)). The forces are given as a function of the state so that every
//! integrator evaluates them where it needs to.

use crate::quat::{self, from_vec4, to_vec4};
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3, Vector4};
use serde::Deserialize;

/// Position, velocity, attitude and body rate of the rigid body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    /// Centre-of-mass position in the local NED frame (m).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity in NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Attitude: rotates FRD vectors into NED.
    pub q_ned_from_frd: UnitQuaternion<f64>,
    /// Angular velocity in FRD (rad/s).
    pub rate_frd_rad_s: Vector3<f64>,
}

impl Default for BodyState {
    fn default() -> Self {
        Self {
            pos_ned_m: Vector3::zeros(),
            vel_ned_m_s: Vector3::zeros(),
            q_ned_from_frd: UnitQuaternion::identity(),
            rate_frd_rad_s: Vector3::zeros(),
        }
    }
}

/// Accelerations at a state: what the force model returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accel {
    /// Linear acceleration of the centre of mass in NED (m/s²).
    pub lin_ned_m_s2: Vector3<f64>,
    /// Angular acceleration in FRD (rad/s²).
    pub ang_frd_rad_s2: Vector3<f64>,
}

/// Mass and inertia, with the inverse computed once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Inertia tensor in FRD (kg·m²).
    pub inertia: Matrix3<f64>,
    /// Its inverse.
    pub inertia_inv: Matrix3<f64>,
}

impl MassProperties {
    /// Mass properties from a mass and a symmetric positive-definite inertia tensor.
    ///
    /// Returns `None` when the tensor is singular (validated airframes never are).
    pub fn new(mass_kg: f64, inertia: Matrix3<f64>) -> Option<Self> {
        let inertia_inv = inertia.try_inverse()?;
        Some(Self {
            mass_kg,
            inertia,
            inertia_inv,
        })
    }

    /// Euler's equations: `ω̇ = I⁻¹ (M − ω × I ω)`, torque in FRD.
    pub fn angular_accel(&self, rate: &Vector3<f64>, torque_frd: &Vector3<f64>) -> Vector3<f64> {
        self.inertia_inv * (torque_frd - rate.cross(&(self.inertia * rate)))
    }

    /// Rotational kinetic energy `½ ωᵀ I ω` (Zabunov (66)), J.
    pub fn rotational_energy(&self, rate: &Vector3<f64>) -> f64 {
        0.5 * rate.dot(&(self.inertia * rate))
    }

    /// Angular momentum in the world frame, `L = q (I ω) q*` (Zabunov (65)), N·m·s.
    pub fn angular_momentum_ned(&self, s: &BodyState) -> Vector3<f64> {
        s.q_ned_from_frd * (self.inertia * s.rate_frd_rad_s)
    }
}

/// The integration scheme of one physics step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// Classical fourth-order Runge–Kutta on (p, v, q, ω) with q as a 4-vector; q is renormalised
    /// after the step (RK4 leaves the sphere by O(Δt⁵) per step). Order 4. The default.
    #[default]
    Rk4,
    /// Lie-group explicit midpoint (RKMK2): rates at mid-step, then
    /// `q_{n+1} = q_n ⊗ exp(ω_{n+½} Δt/2)` (Davailus (21)). A product of unit quaternions, so
    /// unit by construction. Order 2.
    ExpMap,
    /// Semi-implicit (symplectic) Euler with the unit-hypersphere step of Zabunov (69) for q:
    /// the attitude moves along a great circle of the unit 3-sphere, so it stays unit by
    /// construction. Order 1.
    Hypersphere,
    /// Symplectic Euler–Cromer of Zabunov (68): `ω_{n+1}` from (68a), then the naive additive
    /// update `q_{n+1} = q_n (1 + ω_{n+1} Δt / 2)` (68c), which grows |q| by
    /// `√(1 + |ω|²Δt²/4)`; q is renormalised after the step. Order 1.
    EulerCromer,
    /// Davailus's second-derivative formulation (3)–(9): the state carries q̇ instead of ω,
    /// `q̈ = ½ q̇ ⊗ ω + ½ q ⊗ ω̇` (5) with `ω = 2 Qᵀ q̇` (6), integrated by RK4. After the step q is
    /// renormalised and q̇ projected onto the tangent space (q·q̇ = 0). Order 4.
    SecondDerivative,
}

impl Integrator {
    /// Every integrator, for tests and benchmarks.
    pub const ALL: [Integrator; 5] = [
        Integrator::Rk4,
        Integrator::ExpMap,
        Integrator::Hypersphere,
        Integrator::EulerCromer,
        Integrator::SecondDerivative,
    ];

    /// The name used in scenario files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Rk4 => "rk4",
            Integrator::ExpMap => "exp_map",
            Integrator::Hypersphere => "hypersphere",
            Integrator::EulerCromer => "euler_cromer",
            Integrator::SecondDerivative => "second_derivative",
        }
    }

    /// Parses a name as given by [`Integrator::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|i| i.name() == name)
    }

    /// Advances `s` by `dt` under the accelerations `f(state)`.
    pub fn step<F: Fn(&BodyState) -> Accel>(self, s: &BodyState, dt: f64, f: F) -> BodyState {
        match self {
            Integrator::Rk4 => rk4(s, dt, &f),
            Integrator::ExpMap => exp_map(s, dt, &f),
            Integrator::Hypersphere => semi_implicit(s, dt, &f, true),
            Integrator::EulerCromer => semi_implicit(s, dt, &f, false),
            Integrator::SecondDerivative => second_derivative(s, dt, &f),
        }
    }
}

/// A state as a flat derivative-friendly tuple: (p, v, q as 4-vector, ω).
#[derive(Clone, Copy)]
struct Flat {
    p: Vector3<f64>,
    v: Vector3<f64>,
    q: Vector4<f64>,
    w: Vector3<f64>,
}

impl Flat {
    fn of(s: &BodyState) -> Self {
        Self {
            p: s.pos_ned_m,
            v: s.vel_ned_m_s,
            q: to_vec4(s.q_ned_from_frd.quaternion()),
            w: s.rate_frd_rad_s,
        }
    }

    fn axpy(&self, h: f64, d: &Flat) -> Flat {
        Flat {
            p: self.p + d.p * h,
            v: self.v + d.v * h,
            q: self.q + d.q * h,
            w: self.w + d.w * h,
        }
    }

    /// For stage evaluation: the force model sees a normalised attitude.
    fn state(&self) -> BodyState {
        BodyState {
            pos_ned_m: self.p,
            vel_ned_m_s: self.v,
            q_ned_from_frd: UnitQuaternion::new_normalize(from_vec4(&self.q)),
            rate_frd_rad_s: self.w,
        }
    }
}

fn derivative<F: Fn(&BodyState) -> Accel>(x: &Flat, f: &F) -> Flat {
    let a = f(&x.state());
    Flat {
        p: x.v,
        v: a.lin_ned_m_s2,
        q: to_vec4(&quat::q_dot(&from_vec4(&x.q), &x.w)),
        w: a.ang_frd_rad_s2,
    }
}

fn rk4<F: Fn(&BodyState) -> Accel>(s: &BodyState, dt: f64, f: &F) -> BodyState {
    let x = Flat::of(s);
    let k1 = derivative(&x, f);
    let k2 = derivative(&x.axpy(0.5 * dt, &k1), f);
    let k3 = derivative(&x.axpy(0.5 * dt, &k2), f);
    let k4 = derivative(&x.axpy(dt, &k3), f);
    let sum = Flat {
        p: k1.p + (k2.p + k3.p) * 2.0 + k4.p,
        v: k1.v + (k2.v + k3.v) * 2.0 + k4.v,
        q: k1.q + (k2.q + k3.q) * 2.0 + k4.q,
        w: k1.w + (k2.w + k3.w) * 2.0 + k4.w,
    };
    x.axpy(dt / 6.0, &sum).state()
}

fn exp_map<F: Fn(&BodyState) -> Accel>(s: &BodyState, dt: f64, f: &F) -> BodyState {
    let a0 = f(s);
    let half = BodyState {
        pos_ned_m: s.pos_ned_m + s.vel_ned_m_s * (0.5 * dt),
        vel_ned_m_s: s.vel_ned_m_s + a0.lin_ned_m_s2 * (0.5 * dt),
        q_ned_from_frd: quat::propagate(&s.q_ned_from_frd, &s.rate_frd_rad_s, 0.5 * dt),
        rate_frd_rad_s: s.rate_frd_rad_s + a0.ang_frd_rad_s2 * (0.5 * dt),
    };
    let a_half = f(&half);
    BodyState {
        pos_ned_m: s.pos_ned_m + half.vel_ned_m_s * dt,
        vel_ned_m_s: s.vel_ned_m_s + a_half.lin_ned_m_s2 * dt,
        // Davailus (21) with the mid-step rate (propagate renormalises away the rounding).
        q_ned_from_frd: quat::propagate(&s.q_ned_from_frd, &half.rate_frd_rad_s, dt),
        rate_frd_rad_s: s.rate_frd_rad_s + a_half.ang_frd_rad_s2 * dt,
    }
}

/// Zabunov (68): velocities first from the accelerations at the old state (68a), then positions
/// and attitude with the new velocities (68c), or the hypersphere step (69) for the attitude.
fn semi_implicit<F: Fn(&BodyState) -> Accel>(
    s: &BodyState,
    dt: f64,
    f: &F,
    hypersphere: bool,
) -> BodyState {
    let a = f(s);
    let v = s.vel_ned_m_s + a.lin_ned_m_s2 * dt;
    let w = s.rate_frd_rad_s + a.ang_frd_rad_s2 * dt; // (68a)
    let q = s.q_ned_from_frd.quaternion();
    let q_next = if hypersphere {
        quat::hypersphere_step(&s.q_ned_from_frd, &quat::q_dot(q, &w), dt) // (69)
    } else {
        // (68c): q_n (1 + ω Δt / 2), then back onto the sphere.
        UnitQuaternion::new_normalize(
            q * Quaternion::new(1.0, 0.5 * dt * w.x, 0.5 * dt * w.y, 0.5 * dt * w.z),
        )
    };
    BodyState {
        pos_ned_m: s.pos_ned_m + v * dt,
        vel_ned_m_s: v,
        q_ned_from_frd: q_next,
        rate_frd_rad_s: w,
    }
}

/// Davailus (3)–(9): RK4 on (p, v, q, q̇).
fn second_derivative<F: Fn(&BodyState) -> Accel>(s: &BodyState, dt: f64, f: &F) -> BodyState {
    // q̇ is carried as a full 4-vector in place of ω.
    #[derive(Clone, Copy)]
    struct X {
        p: Vector3<f64>,
        v: Vector3<f64>,
        q: Vector4<f64>,
        qd: Vector4<f64>,
    }
    let deriv = |x: &X| -> X {
        let q = from_vec4(&x.q);
        let qd = from_vec4(&x.qd);
        let n2 = q.norm_squared();
        // (6): ω = 2 Qᵀ q̇ / |q|² (the |q|² only matters off the sphere, inside a stage).
        let w = quat::rate_from_q_dot(&q, &qd) / n2;
        let st = BodyState {
            pos_ned_m: x.p,
            vel_ned_m_s: x.v,
            q_ned_from_frd: UnitQuaternion::new_normalize(q),
            rate_frd_rad_s: w,
        };
        let a = f(&st);
        // (5): q̈ = ½ Q̇ ω + ½ Q ω̇ = ½ q̇ ⊗ ω + ½ q ⊗ ω̇.
        let qdd = (qd * quat::pure(&w) + q * quat::pure(&a.ang_frd_rad_s2)) * 0.5;
        X {
            p: x.v,
            v: a.lin_ned_m_s2,
            q: x.qd,
            qd: to_vec4(&qdd),
        }
    };
    let axpy = |x: &X, h: f64, d: &X| X {
        p: x.p + d.p * h,
        v: x.v + d.v * h,
        q: x.q + d.q * h,
        qd: x.qd + d.qd * h,
    };
    let q0 = *s.q_ned_from_frd.quaternion();
    let x0 = X {
        p: s.pos_ned_m,
        v: s.vel_ned_m_s,
        q: to_vec4(&q0),
        qd: to_vec4(&quat::q_dot(&q0, &s.rate_frd_rad_s)), // (4)
    };
    let k1 = deriv(&x0);
    let k2 = deriv(&axpy(&x0, 0.5 * dt, &k1));
    let k3 = deriv(&axpy(&x0, 0.5 * dt, &k2));
    let k4 = deriv(&axpy(&x0, dt, &k3));
    let x1 = X {
        p: x0.p + (k1.p + (k2.p + k3.p) * 2.0 + k4.p) * (dt / 6.0),
        v: x0.v + (k1.v + (k2.v + k3.v) * 2.0 + k4.v) * (dt / 6.0),
        q: x0.q + (k1.q + (k2.q + k3.q) * 2.0 + k4.q) * (dt / 6.0),
        qd: x0.qd + (k1.qd + (k2.qd + k3.qd) * 2.0 + k4.qd) * (dt / 6.0),
    };
    let q1 = UnitQuaternion::new_normalize(from_vec4(&x1.q));
    // Project q̇ onto the tangent space at q and read ω back through (6).
    let qd1 = from_vec4(&x1.qd);
    let qd_tangent = qd1 - q1.quaternion() * q1.quaternion().dot(&qd1);
    BodyState {
        pos_ned_m: x1.p,
        vel_ned_m_s: x1.v,
        q_ned_from_frd: q1,
        rate_frd_rad_s: quat::rate_from_q_dot(q1.quaternion(), &qd_tangent),
    }
}

#[cfg(test)]
mod tests;
