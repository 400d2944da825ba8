//! Quaternion algebra for the flight core and the simulator's integrators, on nalgebra's
//! Hamilton, scalar-first quaternions.
//!
//! Convention (docs/conventions.md): `q_ned_from_frd` rotates body (FRD) vectors into the world
//! (NED), `v_ned = q ⊗ (0, v_frd) ⊗ q*`; kinematics `q̇ = ½ q ⊗ (0, ω_frd)` (Castillo (48),
//! Lewis (4.45)).

use nalgebra::{Matrix3, Matrix4x3, Quaternion, UnitQuaternion, Vector3, Vector4};

/// The pure quaternion `(0, v)`.
#[inline]
pub fn pure(v: &Vector3<f64>) -> Quaternion<f64> {
    Quaternion::from_parts(0.0, *v)
}

/// Exponential of a quaternion: `e^q = e^{q₀} (cos|q̄|, q̄/|q̄| sin|q̄|)` (Davailus (20), Castillo (93)).
#[inline]
pub fn exp(q: &Quaternion<f64>) -> Quaternion<f64> {
    let v = q.imag();
    let theta = v.norm();
    let scale = q.w.exp();
    let sinc = if theta < 1e-8 {
        1.0 - theta * theta / 6.0
    } else {
        theta.sin() / theta
    };
    Quaternion::from_parts(scale * theta.cos(), v * (scale * sinc))
}

/// Logarithm of a non-zero quaternion: `ln q = (ln|q|, q̄/|q̄| acos(q₀/|q|))`, the inverse of
/// [`exp`] for vector parts of norm below π.
#[inline]
pub fn ln(q: &Quaternion<f64>) -> Quaternion<f64> {
    let n = q.norm();
    let v = q.imag();
    let vn = v.norm();
    let angle = vn.atan2(q.w); // = acos(q₀/|q|), robust near 0 and π
    let k = if vn < 1e-12 { 1.0 / n } else { angle / vn };
    Quaternion::from_parts(n.ln(), v * k)
}

/// The rotation vector `θ u` of a unit quaternion, on the shortest path (angle ≤ π): `2 ln q` with
/// the sign chosen so that `w ≥ 0`.
#[inline]
pub fn rotation_vector(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let q = shortest(q);
    ln(q.quaternion()).imag() * 2.0
}

/// Exponential of the pure quaternion `(0, v)`: `(cos|v|, v̂ sin|v|)` (Davailus (20)), a unit
/// quaternion.
#[inline]
pub fn exp_pure(v: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::new_unchecked(exp(&pure(v)))
}

/// The unit quaternion of a rotation vector: `exp((0, φ/2))`.
#[inline]
pub fn from_rotation_vector(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    exp_pure(&(phi * 0.5))
}

/// Principal square root of a unit quaternion: half the rotation about the same axis
/// (Davailus (23)); `√q ⊗ √q = q`.
#[inline]
pub fn sqrt(q: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    // (1 + q)/|1 + q| halves the angle; from w ≥ 0, |1 + q| ≥ 1, so this never degenerates.
    let q = shortest(q);
    UnitQuaternion::new_normalize(Quaternion::new(1.0 + q.w, q.i, q.j, q.k))
}

/// Exact attitude propagation at constant body rate over `dt`: `q ⊗ exp(ω Δt/2)` (Davailus (21),
/// Castillo (96)).
#[inline]
pub fn propagate(q: &UnitQuaternion<f64>, rate_frd: &Vector3<f64>, dt: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(q.quaternion() * exp(&pure(&(rate_frd * (0.5 * dt)))))
}

/// `q̇ = ½ q ⊗ (0, ω)`: Davailus (4) with the Q matrix of (3).
#[inline]
pub fn q_dot(q: &Quaternion<f64>, rate_frd: &Vector3<f64>) -> Quaternion<f64> {
    (q * pure(rate_frd)) * 0.5
}

/// Body rate from the quaternion and its derivative: `ω = 2 Qᵀ q̇` (Davailus (6)–(9)), the vector
/// part of `2 q* ⊗ q̇`.
#[inline]
pub fn rate_from_q_dot(q: &Quaternion<f64>, q_dot: &Quaternion<f64>) -> Vector3<f64> {
    (q.conjugate() * q_dot).imag() * 2.0
}

/// The unit-hypersphere step of Zabunov (69): move along the great circle through `q` in the
/// direction of `q̇` by the arc `φ = |q̇| Δt`: `q cos φ + (q̇/|q̇|) sin φ`. With `q̇ = ½ q ⊗ ω`
/// this is exactly [`propagate`], the exponential map of Davailus (21); the result is
/// renormalised so that rounding does not accumulate.
#[inline]
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
    UnitQuaternion::new_normalize(q.quaternion() * phi.cos() + q_dot * (phi.sin() / speed))
}

/// A quaternion as a 4-vector (w, x, y, z), for generic ODE arithmetic.
#[inline]
pub fn to_vec4(q: &Quaternion<f64>) -> Vector4<f64> {
    Vector4::new(q.w, q.i, q.j, q.k)
}

/// The inverse of [`to_vec4`].
#[inline]
pub fn from_vec4(v: &Vector4<f64>) -> Quaternion<f64> {
    Quaternion::new(v[0], v[1], v[2], v[3])
}

/// The product `q ⊗ (0, ω)` as a matrix acting on ω (Castillo (51)):
/// `[−q̄ᵀ; q₀ I + S(q̄)]`, with S the skew-symmetric operator of (52).
#[inline]
pub fn product_matrix(q: &Quaternion<f64>) -> Matrix4x3<f64> {
    let s = skew(&q.imag());
    let lower = Matrix3::identity() * q.w + s;
    Matrix4x3::new(
        -q.i,
        -q.j,
        -q.k, //
        lower[(0, 0)],
        lower[(0, 1)],
        lower[(0, 2)], //
        lower[(1, 0)],
        lower[(1, 1)],
        lower[(1, 2)], //
        lower[(2, 0)],
        lower[(2, 1)],
        lower[(2, 2)],
    )
}

/// The skew-symmetric matrix `S(v)` with `S(v) x = v × x` (Castillo (52)).
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Rotation matrix of a unit quaternion: Zabunov (33).
#[inline]
pub fn to_rotation_matrix(q: &UnitQuaternion<f64>) -> Matrix3<f64> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    Matrix3::new(
        w * w + x * x - y * y - z * z,
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        w * w - x * x + y * y - z * z,
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        w * w - x * x - y * y + z * z,
    )
}

/// The numerically stable rotation matrix → quaternion conversion of Zabunov (Fig. 2): from the
/// trace when it is positive (|w| > ½), otherwise from the largest diagonal element, so no step
/// divides by a small number. Returns `w ≥ 0`.
#[inline]
pub fn from_rotation_matrix(r: &Matrix3<f64>) -> UnitQuaternion<f64> {
    let tr = r.trace();
    let q = if tr > 0.0 {
        let s = 2.0 * (1.0 + tr).sqrt(); // s = 4w
        Quaternion::new(
            0.25 * s,
            (r[(2, 1)] - r[(1, 2)]) / s,
            (r[(0, 2)] - r[(2, 0)]) / s,
            (r[(1, 0)] - r[(0, 1)]) / s,
        )
    } else if r[(0, 0)] > r[(1, 1)] && r[(0, 0)] > r[(2, 2)] {
        let s = 2.0 * (1.0 + r[(0, 0)] - r[(1, 1)] - r[(2, 2)]).sqrt(); // s = 4x
        Quaternion::new(
            (r[(2, 1)] - r[(1, 2)]) / s,
            0.25 * s,
            (r[(0, 1)] + r[(1, 0)]) / s,
            (r[(0, 2)] + r[(2, 0)]) / s,
        )
    } else if r[(1, 1)] > r[(2, 2)] {
        let s = 2.0 * (1.0 + r[(1, 1)] - r[(0, 0)] - r[(2, 2)]).sqrt(); // s = 4y
        Quaternion::new(
            (r[(0, 2)] - r[(2, 0)]) / s,
            (r[(0, 1)] + r[(1, 0)]) / s,
            0.25 * s,
            (r[(1, 2)] + r[(2, 1)]) / s,
        )
    } else {
        let s = 2.0 * (1.0 + r[(2, 2)] - r[(0, 0)] - r[(1, 1)]).sqrt(); // s = 4z
        Quaternion::new(
            (r[(1, 0)] - r[(0, 1)]) / s,
            (r[(0, 2)] + r[(2, 0)]) / s,
            (r[(1, 2)] + r[(2, 1)]) / s,
            0.25 * s,
        )
    };
    shortest(&UnitQuaternion::new_normalize(q))
}

/// The representative of the same rotation with `w ≥ 0` (the shortest rotation).
#[inline]
pub fn shortest(q: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    if q.w < 0.0 {
        UnitQuaternion::new_unchecked(-q.into_inner())
    } else {
        *q
    }
}

/// Error quaternion in the body frame of the current attitude, shortest path:
/// `q_e = q* ⊗ q_d` (the rotation that takes the current body frame to the desired one,
/// expressed in the current body frame), with `w ≥ 0`. Lewis's world-frame error
/// `q̃ = q_d ⊗ q*` (4.2) rotated into the body by (4.10) is this same quaternion.
#[inline]
pub fn error_body(q: &UnitQuaternion<f64>, q_desired: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    shortest(&(q.inverse() * q_desired))
}

/// A body-frame error split into tilt and yaw: `q_e = q_H ⊗ q_V` (Lewis (4.12)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltYaw {
    /// Tilt angle `α_H` ∈ [0, π) (rad): Lewis (4.14).
    pub tilt: f64,
    /// Direction of the tilt axis in the body x–y plane, `β_H` (rad): Lewis (4.18).
    pub tilt_axis_angle: f64,
    /// Yaw angle `ψ` ∈ [−π, π) (rad): Lewis (4.15).
    pub yaw: f64,
}

impl TiltYaw {
    /// Decomposes a unit quaternion into a tilt about a horizontal axis followed by a yaw.
    ///
    /// Lewis (4.14)–(4.18), with (4.17) as it follows from (4.13): `r_y = (sin(ψ/2) q₁ +
    /// cos(ψ/2) q₂) / sin(α_H/2)` (the printed minus sign does not recompose).
    #[inline]
    pub fn of(q: &UnitQuaternion<f64>) -> Self {
        let q = shortest(q);
        let (q0, q1, q2, q3) = (q.w, q.i, q.j, q.k);
        let tilt = (1.0 - 2.0 * (q1 * q1 + q2 * q2)).clamp(-1.0, 1.0).acos(); // (4.14)
        let yaw = 2.0 * q3.atan2(q0); // (4.15)
        let yaw = if yaw >= std::f64::consts::PI {
            yaw - std::f64::consts::TAU
        } else {
            yaw
        };
        let (s, c) = (0.5 * yaw).sin_cos();
        // (4.16)–(4.17); the common factor sin(α_H/2) > 0 cancels in atan2 (4.18).
        let rx = c * q1 - s * q2;
        let ry = s * q1 + c * q2;
        Self {
            tilt,
            tilt_axis_angle: ry.atan2(rx),
            yaw,
        }
    }

    /// The tilt quaternion `q_H` (about the horizontal axis at `β_H`).
    #[inline]
    pub fn tilt_quaternion(&self) -> UnitQuaternion<f64> {
        let (sb, cb) = self.tilt_axis_angle.sin_cos();
        from_rotation_vector(&(Vector3::new(cb, sb, 0.0) * self.tilt))
    }

    /// The yaw quaternion `q_V` (about body z).
    #[inline]
    pub fn yaw_quaternion(&self) -> UnitQuaternion<f64> {
        from_rotation_vector(&Vector3::new(0.0, 0.0, self.yaw))
    }

    /// `q_H ⊗ q_V`: the quaternion this was decomposed from (up to sign).
    #[inline]
    pub fn compose(&self) -> UnitQuaternion<f64> {
        self.tilt_quaternion() * self.yaw_quaternion()
    }
}

#[cfg(test)]
mod tests;
