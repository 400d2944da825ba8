//! The attitude (outer) loop: desired attitude → body-rate reference.
//!
//! Castillo's kinematic law (63): with the error `q_e = q_d* ⊗ q_b` (54),
//! `Ω_r = −k_k sign(q_e0) q̄_e + Ω_d′`, `Ω_d′ = q_e* ⊗ Ω_d ⊗ q_e` (the desired frame's rate seen in
//! the body). Under perfect rate tracking the error Lyapunov function `V = 2(1 − |q_e0|)` decays
//! at least as `V(0) e^{−k_k t/2}` (66)–(68).
//!
//! Beyond the paper: tilt before yaw (the yaw part of the error, from Lewis's tilt/yaw split
//! (4.12), is scaled by a weight below one so a large heading error never delays levelling), and
//! body-rate limits.

use crate::math::quat::{self, TiltYaw};
use nalgebra::{UnitQuaternion, Vector3};

/// Parameters of the kinematic attitude law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicParams {
    /// Gain k_k (1/s) of (63).
    pub k_k: f64,
    /// Weight of the yaw error relative to tilt, (0, 1]; 1 is Castillo's law exactly.
    pub yaw_weight: f64,
    /// Largest roll/pitch rate reference (rad/s).
    pub max_tilt_rate: f64,
    /// Largest yaw rate reference (rad/s).
    pub max_yaw_rate: f64,
}

/// The attitude loop's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateReference {
    /// Body-rate reference Ω_r (rad/s, FRD).
    pub rate: Vector3<f64>,
    /// The error quaternion q_e of (54), `w ≥ 0`.
    pub error: UnitQuaternion<f64>,
}

/// Castillo's kinematic law (63).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicAttitude {
    /// Its parameters.
    pub params: KinematicParams,
}

impl KinematicAttitude {
    /// The rate reference for attitude `q_b` (`q_ned_from_frd`), desired attitude `q_d` and the
    /// desired frame's own body rate `omega_d` (zero for a fixed set-point).
    pub fn update(
        &self,
        q_b: &UnitQuaternion<f64>,
        q_d: &UnitQuaternion<f64>,
        omega_d: &Vector3<f64>,
    ) -> RateReference {
        let p = &self.params;
        let q_e = quat::shortest(&(q_d.inverse() * q_b)); // (54), sign(q_e0) folded in: w ≥ 0
        let feed_forward = q_e.inverse() * omega_d; // Ω_d′ = q_e* ⊗ Ω_d ⊗ q_e
        let correction = if p.yaw_weight >= 1.0 {
            -q_e.imag() * p.k_k // (63)
        } else {
            // Tilt first: split the body-to-desired rotation q_e* into q_H ⊗ q_V (Lewis (4.12)) and
            // shrink the yaw part.
            let split = TiltYaw::of(&q_e.inverse());
            let reduced = TiltYaw {
                yaw: split.yaw * p.yaw_weight,
                ..split
            }
            .compose();
            quat::shortest(&reduced).imag() * p.k_k
        };
        let mut rate = correction + feed_forward;
        let tilt = rate.xy().norm();
        if tilt > p.max_tilt_rate {
            let s = p.max_tilt_rate / tilt;
            rate.x *= s;
            rate.y *= s;
        }
        rate.z = rate.z.clamp(-p.max_yaw_rate, p.max_yaw_rate);
        RateReference { rate, error: q_e }
    }
}

/// Parameters of Lewis's tilt/yaw PD law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltYawPdParams {
    /// Tilt proportional gain K_PH (N·m/rad).
    pub k_p_tilt: f64,
    /// Tilt derivative gain K_DH (N·m·s/rad).
    pub k_d_tilt: f64,
    /// Yaw proportional gain K_Pz (N·m/rad).
    pub k_p_yaw: f64,
    /// Yaw derivative gain K_Dz (N·m·s/rad).
    pub k_d_yaw: f64,
}

/// Lewis & De Ruyter's attitude law (4.19)–(4.21): moments straight from the tilt/yaw error,
/// `M_x = K_PH α_H cos β_H − K_DH ω_x`, `M_y = K_PH α_H sin β_H − K_DH ω_y`,
/// `M_z = K_Pz ψ − K_Dz ω_z`. An alternative to the kinematic law + rate loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltYawPd {
    /// Its parameters.
    pub params: TiltYawPdParams,
}

impl TiltYawPd {
    /// Body moments (N·m) for attitude `q`, desired `q_d` and body rate `rate`.
    pub fn update(
        &self,
        q: &UnitQuaternion<f64>,
        q_d: &UnitQuaternion<f64>,
        rate: &Vector3<f64>,
    ) -> Vector3<f64> {
        let p = &self.params;
        // Lewis (4.2) q̃ = q_d ⊗ q*, rotated into the body (4.10)–(4.11): the body-frame rotation
        // from the current to the desired attitude.
        let e = TiltYaw::of(&quat::error_body(q, q_d));
        let (sb, cb) = e.tilt_axis_angle.sin_cos();
        Vector3::new(
            p.k_p_tilt * e.tilt * cb - p.k_d_tilt * rate.x, // (4.19)
            p.k_p_tilt * e.tilt * sb - p.k_d_tilt * rate.y, // (4.20)
            p.k_p_yaw * e.yaw - p.k_d_yaw * rate.z,         // (4.21)
        )
    }
}

crate::params::param_group! {
    /// Attitude loop (Castillo's kinematic law (63) or Lewis's tilt/yaw PD).
    AttitudeControlGroup, "attitude_control", ATTITUDE_CONTROL_META {
        /// 0: Castillo's kinematic law over the rate loop; 1: Lewis's tilt/yaw PD moments.
        law: u32 = 0, "MC_ATT_LAW", "", [0.0, 1.0], "Attitude law: 0 Castillo kinematic (63) + rate loop, 1 Lewis tilt/yaw PD (4.19)-(4.21)";
        /// Castillo's k_k.
        k_k: f64 = 6.0, "MC_ATT_KK", "1/s", [0.1, 30.0], "Gain k_k of Castillo's kinematic law (63)";
        /// Yaw weight relative to tilt.
        yaw_weight: f64 = 0.4, "MC_YAW_WEIGHT", "", [0.0, 1.0], "Weight of the yaw error relative to tilt";
        /// Roll/pitch rate limit.
        max_tilt_rate_deg_s: f64 = 200.0, "MC_ROLLRATE_MAX", "deg/s", [10.0, 1800.0], "Largest roll and pitch rate reference";
        /// Yaw rate limit.
        max_yaw_rate_deg_s: f64 = 90.0, "MC_YAWRATE_MAX", "deg/s", [5.0, 1800.0], "Largest yaw rate reference";
        /// Lewis K_PH per unit inertia.
        pd_k_p_tilt: f64 = 36.0, "MC_PD_TILT_P", "1/s^2", [0.0, 500.0], "Lewis tilt proportional gain K_PH, per kg m^2 of inertia";
        /// Lewis K_DH per unit inertia.
        pd_k_d_tilt: f64 = 10.0, "MC_PD_TILT_D", "1/s", [0.0, 100.0], "Lewis tilt derivative gain K_DH, per kg m^2 of inertia";
        /// Lewis K_Pz per unit inertia.
        pd_k_p_yaw: f64 = 9.0, "MC_PD_YAW_P", "1/s^2", [0.0, 500.0], "Lewis yaw proportional gain K_Pz, per kg m^2 of inertia";
        /// Lewis K_Dz per unit inertia.
        pd_k_d_yaw: f64 = 5.0, "MC_PD_YAW_D", "1/s", [0.0, 100.0], "Lewis yaw derivative gain K_Dz, per kg m^2 of inertia";
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Quaternion;

    fn castillo() -> KinematicAttitude {
        KinematicAttitude {
            params: KinematicParams {
                k_k: 5.0,
                yaw_weight: 1.0,
                max_tilt_rate: 1e9,
                max_yaw_rate: 1e9,
            },
        }
    }

    /// Castillo 4.3 (Fig. 15): q_d(0) = (1, 0, 0, 0), Ω_d = sin(2t)(1, 1, 1), q_b(0) =
    /// (0.06, 0.48, 0.84, −0.24) (173.12° away), k_k = 5, Ω_b = Ω_r. The Lyapunov function
    /// V = 2(1 − |q_e0|) (66) stays below V(0) e^{−k_k t/2} (68) throughout.
    #[test]
    fn kinematic_loop_meets_the_lyapunov_bound_from_173_degrees() {
        let law = castillo();
        let mut q_b = UnitQuaternion::new_normalize(Quaternion::new(0.06, 0.48, 0.84, -0.24));
        let mut q_d = UnitQuaternion::identity();
        let v = |q_b: &UnitQuaternion<f64>, q_d: &UnitQuaternion<f64>| {
            2.0 * (1.0 - (q_d.inverse() * q_b).w.abs())
        };
        let v0 = v(&q_b, &q_d);
        assert!((q_b.angle().to_degrees() - 173.12).abs() < 0.01);
        let dt = 1e-4;
        let mut worst_ratio = 0.0f64;
        for k in 0..50_000 {
            let t = k as f64 * dt;
            // Rates at mid-step for second-order accurate kinematics.
            let w_d = Vector3::repeat((2.0 * (t + 0.5 * dt)).sin());
            let r = law.update(&q_b, &q_d, &w_d);
            q_b = quat::propagate(&q_b, &r.rate, dt);
            q_d = quat::propagate(&q_d, &w_d, dt);
            let t1 = t + dt;
            let bound = v0 * (-law.params.k_k * t1 / 2.0).exp();
            worst_ratio = worst_ratio.max(v(&q_b, &q_d) / bound);
        }
        println!(
            "kinematic loop: max V(t) / (V(0) e^(-k_k t/2)) = {worst_ratio:.3}, final error {:.2e} rad",
            (q_d.inverse() * q_b).angle()
        );
        assert!(worst_ratio <= 1.0 + 1e-6, "(68) violated: {worst_ratio}");
        // Near convergence the angle decays as e^{−k_k t/2}: π e^{−12.5} ≈ 1.2e-5 rad after 5 s.
        assert!((q_d.inverse() * q_b).angle() < 2e-5);
    }

    #[test]
    fn rate_reference_points_the_right_way_and_respects_limits() {
        let mut law = castillo();
        // Desired: 10° nose up. The body must pitch up: positive pitch rate.
        let q_d = UnitQuaternion::from_euler_angles(0.0, 10f64.to_radians(), 0.0);
        let r = law.update(&UnitQuaternion::identity(), &q_d, &Vector3::zeros());
        assert!(
            r.rate.y > 0.0 && r.rate.x.abs() < 1e-12 && r.rate.z.abs() < 1e-12,
            "{:?}",
            r.rate
        );
        law.params.max_tilt_rate = 0.1;
        law.params.max_yaw_rate = 0.05;
        let q_d = UnitQuaternion::from_euler_angles(1.0, -1.0, 2.0);
        let r = law.update(&UnitQuaternion::identity(), &q_d, &Vector3::zeros());
        assert!(r.rate.xy().norm() <= 0.1 + 1e-12 && r.rate.z.abs() <= 0.05 + 1e-12);
    }

    /// With a yaw weight below one, a pure heading error gives a proportionally smaller yaw rate,
    /// and a tilt error is untouched.
    #[test]
    fn tilt_takes_priority_over_yaw() {
        let mut law = castillo();
        let yaw_only = UnitQuaternion::from_euler_angles(0.0, 0.0, 1.0);
        let full = law
            .update(&UnitQuaternion::identity(), &yaw_only, &Vector3::zeros())
            .rate;
        law.params.yaw_weight = 0.4;
        let weighted = law
            .update(&UnitQuaternion::identity(), &yaw_only, &Vector3::zeros())
            .rate;
        assert!(
            weighted.z > 0.0 && weighted.z < 0.5 * full.z,
            "{weighted:?} vs {full:?}"
        );
        let tilt_only = UnitQuaternion::from_euler_angles(0.3, 0.0, 0.0);
        let a = law
            .update(&UnitQuaternion::identity(), &tilt_only, &Vector3::zeros())
            .rate;
        law.params.yaw_weight = 1.0;
        let b = law
            .update(&UnitQuaternion::identity(), &tilt_only, &Vector3::zeros())
            .rate;
        assert!((a - b).norm() < 1e-12);
    }

    #[test]
    fn lewis_pd_pushes_toward_the_set_point() {
        let pd = TiltYawPd {
            params: TiltYawPdParams {
                k_p_tilt: 2.0,
                k_d_tilt: 0.3,
                k_p_yaw: 1.0,
                k_d_yaw: 0.2,
            },
        };
        // Want roll right 0.2 rad and yaw right 0.5 rad: positive M_x and M_z.
        let m = pd.update(
            &UnitQuaternion::identity(),
            &UnitQuaternion::from_euler_angles(0.2, 0.0, 0.5),
            &Vector3::zeros(),
        );
        assert!(m.x > 0.0 && m.z > 0.0, "{m:?}");
        assert!((m.z - 0.5).abs() < 1e-9);
        // Damping opposes the rate.
        let m = pd.update(
            &UnitQuaternion::identity(),
            &UnitQuaternion::identity(),
            &Vector3::new(1.0, -1.0, 2.0),
        );
        assert!((m - Vector3::new(-0.3, 0.3, -0.4)).norm() < 1e-12);
    }
}
