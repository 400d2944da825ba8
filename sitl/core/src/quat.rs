//! The few quaternion operations the integrators need, in the papers' words.
//!
//! Convention (ARCHITECTURE.md): Hamilton product, scalar first, `q_ned_from_frd` rotates body
//! vectors into the world, kinematics `q̇ = ½ q ⊗ (0, ω_frd)` (Castillo (48), Lewis (4.45)).

use nalgebra::{Quaternion, UnitQuaternion, Vector3, Vector4};

/// The pure quaternion `(0, v)`.
pub fn pure(v: &Vector3<f64>) -> Quaternion<f64> {
    Quaternion::new(0.0, v.x, v.y, v.z)
}

/// Exponential of the pure quaternion `(0, v)`: `(cos|v|, v̂ sin|v|)` (Davailus (20)).
///
/// Accurate for small `|v|` through the series of `sin x / x`.
pub fn exp_pure(v: &Vector3<f64>) -> UnitQuaternion<f64> {
    let theta = v.norm();
    let sinc = if theta < 1e-4 {
        1.0 - theta * theta / 6.0
    } else {
        theta.sin() / theta
    };
    UnitQuaternion::new_unchecked(Quaternion::new(
        theta.cos(),
        v.x * sinc,
        v.y * sinc,
        v.z * sinc,
    ))
}

/// Exact rotation over `dt` at constant body rate: `q(t+Δt) = q(t) ⊗ exp(q_ω Δt / 2)` (Davailus (21)).
pub fn propagate(q: &UnitQuaternion<f64>, rate_frd: &Vector3<f64>, dt: f64) -> UnitQuaternion<f64> {
    q * exp_pure(&(rate_frd * (0.5 * dt)))
}

/// `q̇ = ½ q ⊗ (0, ω)` as a 4-vector (w, x, y, z): Davailus (4) with the Q matrix of (3).
pub fn q_dot(q: &Quaternion<f64>, rate_frd: &Vector3<f64>) -> Quaternion<f64> {
    (q * pure(rate_frd)) * 0.5
}

/// Body rate from the quaternion and its derivative: `ω = 2 Qᵀ q̇` (Davailus (6)–(9)),
/// the vector part of `2 q* ⊗ q̇`.
pub fn rate_from_q_dot(q: &Quaternion<f64>, q_dot: &Quaternion<f64>) -> Vector3<f64> {
    (q.conjugate() * q_dot).imag() * 2.0
}

/// The unit-hypersphere step of Zabunov (69): move along the great circle through `q` in the
/// direction of `q̇` by the arc `φ = |q̇| Δt`: `q_{n+1} = q cos φ + (q̇/|q̇|) sin φ`.
///
/// With `q̇ = ½ q ⊗ ω` this is exactly `q ⊗ exp(ω Δt / 2)`, the exponential map of Davailus (21):
/// both land on the sphere by construction.
pub fn hypersphere_step(
    q: &UnitQuaternion<f64>,
    q_dot: &Quaternion<f64>,
    dt: f64,
) -> UnitQuaternion<f64> {
    let speed = q_dot.norm();
    if speed == 0.0 {
        return *q;
    }
    let phi = speed * dt;
    let next = q.quaternion() * phi.cos() + q_dot * (phi.sin() / speed);
    // Unit up to rounding; renormalise to stop rounding drift accumulating.
    UnitQuaternion::new_normalize(next)
}

/// Stores a quaternion as a 4-vector (w, x, y, z) for generic ODE arithmetic.
pub fn to_vec4(q: &Quaternion<f64>) -> Vector4<f64> {
    Vector4::new(q.w, q.i, q.j, q.k)
}

/// The inverse of [`to_vec4`].
pub fn from_vec4(v: &Vector4<f64>) -> Quaternion<f64> {
    Quaternion::new(v[0], v[1], v[2], v[3])
}

/// The rotation angle between two attitudes (rad), in `[0, π]`.
pub fn angle_between(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.rotation_to(b).angle()
}
