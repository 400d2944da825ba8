//! The torque-free asymmetric top in closed form: the reference the integrators are checked against.
//!
//! Rates: Davailus (42)–(44), `ω₁ = α dn(pt, k)`, `ω₂ = β sn(pt, k)`, `ω₃ = γ cn(pt, k)`, for a body
//! spinning mostly about its axis of largest inertia (here body x, with `I_x > I_y > I_z` and
//! `L² > 2E I_y`), started from `ω(0) = (α, 0, γ)`.
//!
//! Attitude: Davailus (45) writes `q(t) = q(0) ⊗ exp(∫ q_ω/2 dt)`, which is exact only while ω
//! keeps a fixed direction (the rates do not commute). We build the attitude instead from the two
//! free-body invariants (Zabunov (65)–(66)): the world-frame angular momentum `L` is constant, so
//! in a frame whose z axis is `L` the body's nutation θ and spin ψ follow in closed form from ω(t),
//! and only the precession φ needs a quadrature of a closed-form integrand,
//! `φ̇ = |L| (I₁Ω₁² + I₂Ω₂²) / (I₁²Ω₁² + I₂²Ω₂²)` (Landau & Lifshitz, Mechanics §37), done here
//! with composite 5-point Gauss–Legendre to machine precision.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Jacobi elliptic functions `(sn, cn, dn)` of argument `u` and parameter `m = k²` (0 ≤ m < 1),
/// by the descending Landen transformation (arithmetic–geometric mean; Abramowitz & Stegun 16.4).
pub fn jacobi_sn_cn_dn(u: f64, m: f64) -> (f64, f64, f64) {
    if m < 1e-15 {
        return (u.sin(), u.cos(), 1.0);
    }
    const N: usize = 16;
    let mut a = [0.0f64; N + 1];
    let mut c = [0.0f64; N + 1];
    a[0] = 1.0;
    let mut b = (1.0 - m).sqrt();
    c[0] = m.sqrt();
    let mut n = 0;
    while n < N && c[n].abs() > 1e-16 {
        a[n + 1] = 0.5 * (a[n] + b);
        c[n + 1] = 0.5 * (a[n] - b);
        b = (a[n] * b).sqrt();
        n += 1;
    }
    let mut phi = (1u64 << n) as f64 * a[n] * u;
    for i in (1..=n).rev() {
        phi = 0.5 * (phi + (c[i] / a[i] * phi.sin()).asin());
    }
    let (sn, cn) = phi.sin_cos();
    // dn ∈ [√(1−m), 1] for real u: the square root is exact and never meets A&S's 0/0 at u = K.
    (sn, cn, (1.0 - m * sn * sn).sqrt())
}

/// Complete elliptic integral of the first kind `K(m)`, `m = k²`, by the AGM: `π / (2 AGM(1, √(1−m)))`.
pub fn elliptic_k(m: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - m).sqrt());
    for _ in 0..40 {
        if (a - b).abs() < 1e-16 * a {
            break;
        }
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    std::f64::consts::PI / (2.0 * a)
}

/// A torque-free body with principal moments `I_x > I_y > I_z` along FRD, started from
/// `ω(0) = (α, 0, γ)` with α, γ > 0 and attitude `q0`.
#[derive(Debug, Clone)]
pub struct TorqueFreeTop {
    i: Vector3<f64>,
    alpha: f64,
    beta: f64,
    gamma: f64,
    p: f64,
    m: f64,
    l: f64,
    c: UnitQuaternion<f64>,
}

/// Why a torque-free reference cannot be built for the given body.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TorqueFreeError {
    /// Needs `I_x > I_y > I_z`.
    #[error("principal moments must satisfy I_x > I_y > I_z")]
    Ordering,
    /// Needs α, γ > 0 and `L² > 2 E I_y` (motion about the x axis, the dn axis).
    #[error("initial rate must be (alpha > 0, 0, gamma > 0) with L^2 > 2 E I_y")]
    InitialRate,
}

impl TorqueFreeTop {
    /// The closed form for principal moments `inertia` (x, y, z) and `ω(0) = (alpha, 0, gamma)`.
    pub fn new(
        inertia: Vector3<f64>,
        alpha: f64,
        gamma: f64,
        q0: UnitQuaternion<f64>,
    ) -> Result<Self, TorqueFreeError> {
        let (ix, iy, iz) = (inertia.x, inertia.y, inertia.z);
        if !(ix > iy && iy > iz && iz > 0.0) {
            return Err(TorqueFreeError::Ordering);
        }
        let e2 = ix * alpha * alpha + iz * gamma * gamma; // 2E
        let l2 = ix * ix * alpha * alpha + iz * iz * gamma * gamma; // L²
        if !(alpha > 0.0 && gamma > 0.0 && l2 > e2 * iy) {
            return Err(TorqueFreeError::InitialRate);
        }
        // Landau §37 with (I1, I2, I3) = (I_z, I_y, I_x).
        let beta = -((e2 * ix - l2) / (iy * (ix - iy))).sqrt();
        let p = ((ix - iy) * (l2 - e2 * iz) / (ix * iy * iz)).sqrt();
        let m = (iy - iz) * (e2 * ix - l2) / ((ix - iy) * (l2 - e2 * iz));
        let mut top = Self {
            i: inertia,
            alpha,
            beta,
            gamma,
            p,
            m,
            l: l2.sqrt(),
            c: UnitQuaternion::identity(),
        };
        // World = C · (L-aligned frame): chosen so that the attitude at t = 0 is q0.
        top.c = q0 * top.attitude_in_l_frame(0.0).inverse();
        Ok(top)
    }

    /// Body rate at time t: Davailus (42)–(44).
    pub fn rate(&self, t: f64) -> Vector3<f64> {
        let (sn, cn, dn) = jacobi_sn_cn_dn(self.p * t, self.m);
        Vector3::new(self.alpha * dn, self.beta * sn, self.gamma * cn)
    }

    /// Period of the rates, `4K(m)/p`.
    pub fn rate_period(&self) -> f64 {
        4.0 * elliptic_k(self.m) / self.p
    }

    /// Attitude `q_ned_from_frd` at time t.
    pub fn attitude(&self, t: f64) -> UnitQuaternion<f64> {
        self.c * self.attitude_in_l_frame(t)
    }

    /// Angular momentum magnitude |L| (N·m·s).
    pub fn angular_momentum(&self) -> f64 {
        self.l
    }

    /// Landau's body axes (1, 2, 3) = (z, −y, x) of ours, a right-handed relabelling.
    fn primed(&self, w: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (
            Vector3::new(w.z, -w.y, w.x),
            Vector3::new(self.i.z, self.i.y, self.i.x),
        )
    }

    fn precession_rate(&self, t: f64) -> f64 {
        let (o, i) = self.primed(&self.rate(t));
        let num = i[0] * o[0] * o[0] + i[1] * o[1] * o[1];
        let den = i[0] * i[0] * o[0] * o[0] + i[1] * i[1] * o[1] * o[1];
        self.l * num / den
    }

    fn precession(&self, t: f64) -> f64 {
        // Composite 5-point Gauss–Legendre: error ~ h¹⁰, far below f64 for h ≤ 0.02 s.
        const X: [f64; 5] = [
            0.0,
            -0.538_469_310_105_683_1,
            0.538_469_310_105_683_1,
            -0.906_179_845_938_664,
            0.906_179_845_938_664,
        ];
        const W: [f64; 5] = [
            0.568_888_888_888_888_9,
            0.478_628_670_499_366_5,
            0.478_628_670_499_366_5,
            0.236_926_885_056_189_1,
            0.236_926_885_056_189_1,
        ];
        let pieces = ((t.abs() / 0.02).ceil() as usize).max(1);
        let h = t / pieces as f64;
        let mut sum = 0.0;
        for k in 0..pieces {
            let mid = (k as f64 + 0.5) * h;
            for j in 0..5 {
                sum += W[j] * self.precession_rate(mid + 0.5 * h * X[j]);
            }
        }
        0.5 * h * sum
    }

    fn attitude_in_l_frame(&self, t: f64) -> UnitQuaternion<f64> {
        let (o, i) = self.primed(&self.rate(t));
        let theta = (i[2] * o[2] / self.l).clamp(-1.0, 1.0).acos();
        let psi = (i[0] * o[0]).atan2(i[1] * o[1]);
        let phi = self.precession(t);
        let z = Vector3::z_axis();
        let x = Vector3::x_axis();
        // Body' → L-frame: Rz(φ) Rx(θ) Rz(ψ); then ours → body' by the relabelling P.
        let r_primed = Rotation3::from_axis_angle(&z, phi)
            * Rotation3::from_axis_angle(&x, theta)
            * Rotation3::from_axis_angle(&z, psi);
        let p = Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, //
            0.0, -1.0, 0.0, //
            1.0, 0.0, 0.0,
        ));
        UnitQuaternion::from_rotation_matrix(&(r_primed * p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobi_functions_satisfy_their_identities_and_limits() {
        for &m in &[0.0, 0.1, 0.5, 0.9, 0.999] {
            for k in 0..50 {
                let u = -3.0 + 0.17 * k as f64;
                let (sn, cn, dn) = jacobi_sn_cn_dn(u, m);
                assert!((sn * sn + cn * cn - 1.0).abs() < 1e-13);
                assert!((dn * dn + m * sn * sn - 1.0).abs() < 1e-13);
            }
        }
        // sn(K) = 1, cn(K) = 0, dn(K) = √(1−m).
        let m = 0.7;
        let (sn, cn, dn) = jacobi_sn_cn_dn(elliptic_k(m), m);
        assert!(
            (sn - 1.0).abs() < 1e-12 && cn.abs() < 1e-7 && (dn - (0.3f64).sqrt()).abs() < 1e-12
        );
        // K(0) = π/2 and a tabulated value K(0.5) = 1.854 074 677 301 372.
        assert!((elliptic_k(0.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert!((elliptic_k(0.5) - 1.854_074_677_301_372).abs() < 1e-13);
    }

    #[test]
    fn closed_form_rates_satisfy_eulers_equations() {
        let i = Vector3::new(0.3, 0.2, 0.1);
        let top = TorqueFreeTop::new(i, 2.0, 1.5, UnitQuaternion::identity()).unwrap();
        let h = 1e-5;
        for k in 0..40 {
            let t = 0.23 * k as f64;
            let w = top.rate(t);
            let wd = (top.rate(t + h) - top.rate(t - h)) / (2.0 * h);
            // I ω̇ + ω × I ω = 0 for a diagonal I.
            let iw = w.component_mul(&i);
            let residual = wd.component_mul(&i) + w.cross(&iw);
            assert!(residual.norm() < 1e-7, "t={t} residual {residual:?}");
        }
        assert_eq!(top.rate(0.0), Vector3::new(2.0, 0.0, 1.5));
    }

    #[test]
    fn closed_form_attitude_matches_its_rates_and_conserves_momentum() {
        let i = Vector3::new(0.3, 0.2, 0.1);
        let q0 = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0);
        let top = TorqueFreeTop::new(i, 2.0, 1.5, q0).unwrap();
        assert!(top.attitude(0.0).angle_to(&q0) < 1e-12);
        let l0 = q0 * top.rate(0.0).component_mul(&i);
        let h = 1e-5;
        for k in 1..30 {
            let t = 0.31 * k as f64;
            let q = top.attitude(t);
            // The L-frame construction must conserve the world angular momentum...
            let l = q * top.rate(t).component_mul(&i);
            assert!((l - l0).norm() < 1e-10, "t={t}: L drifted {:?}", l - l0);
            // ...and its derivative must be ½ q ⊗ ω (the kinematics), checked by differences.
            let q_mid = top.attitude(t);
            let w_from_q = (q_mid.inverse() * top.attitude(t + h)).scaled_axis()
                - (q_mid.inverse() * top.attitude(t - h)).scaled_axis();
            let w_from_q = w_from_q / (2.0 * h);
            assert!(
                (w_from_q - top.rate(t)).norm() < 1e-6,
                "t={t}: {w_from_q:?} vs {:?}",
                top.rate(t)
            );
        }
    }
}
