//! Wahba's problem: the attitude that best maps reference vectors onto their body-frame
//! measurements, by Davenport's q-method (Castillo (80)–(90)).

use nalgebra::{Matrix3, Matrix4, UnitQuaternion, Vector3, Vector4};

/// One vector seen in the body frame and known in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorObservation {
    /// Measured direction in FRD (any length; normalised here).
    pub body: Vector3<f64>,
    /// The same direction in NED (any length; normalised here).
    pub reference: Vector3<f64>,
    /// Weight `a_i` of (80) (> 0).
    pub weight: f64,
}

/// Why a set of observations cannot give an attitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ObservationError {
    /// A component is NaN or infinite.
    #[error("observation is not finite")]
    NonFinite,
    /// A vector has (almost) zero length: no direction.
    #[error("observation vector has zero length")]
    Zero,
    /// The vectors are (almost) parallel: rotation about them is unobservable.
    #[error("observation vectors are parallel")]
    Parallel,
    /// Fewer than two usable vectors.
    #[error("at least two non-parallel vectors are needed")]
    TooFew,
}

/// Davenport's K matrix (Castillo (86)–(89)), scalar part last: `[[S − tr(B) I, z], [zᵀ, tr(B)]]`
/// with `B = Σ aᵢ bᵢ rᵢᵀ` (83), `S = B + Bᵀ` (88), `z = Σ aᵢ bᵢ × rᵢ` (89). Also returns B.
fn davenport_k(
    obs: &[VectorObservation],
) -> Result<(Matrix4<f64>, Matrix3<f64>), ObservationError> {
    let mut b = Matrix3::zeros();
    let mut z = Vector3::zeros();
    let mut usable: Vec<Vector3<f64>> = Vec::with_capacity(obs.len());
    for o in obs {
        if !(o
            .body
            .iter()
            .chain(o.reference.iter())
            .all(|x| x.is_finite())
            && o.weight.is_finite())
        {
            return Err(ObservationError::NonFinite);
        }
        if o.weight <= 0.0 {
            continue;
        }
        let (nb, nr) = (o.body.norm(), o.reference.norm());
        if nb < 1e-9 || nr < 1e-9 {
            return Err(ObservationError::Zero);
        }
        let (bi, ri) = (o.body / nb, o.reference / nr);
        b += bi * ri.transpose() * o.weight;
        z += bi.cross(&ri) * o.weight;
        usable.push(bi);
    }
    if usable.len() < 2 {
        return Err(ObservationError::TooFew);
    }
    // Observable only if some pair of body vectors spans a plane (sin of the angle > 1e-3).
    let spans = usable
        .iter()
        .enumerate()
        .any(|(i, a)| usable[i + 1..].iter().any(|c| a.cross(c).norm() > 1e-3));
    if !spans {
        return Err(ObservationError::Parallel);
    }
    let s = b + b.transpose();
    let sigma = b.trace();
    let mut k = Matrix4::zeros();
    k.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(s - Matrix3::identity() * sigma));
    k.fixed_view_mut::<3, 1>(0, 3).copy_from(&z);
    k.fixed_view_mut::<1, 3>(3, 0).copy_from(&z.transpose());
    k[(3, 3)] = sigma;
    Ok((k, b))
}

/// The K eigenvector (q̄, q₀) is the quaternion of the reference→body attitude matrix in
/// Shuster's convention, which is the transpose of our Hamilton `q_ned_from_frd` with the same
/// components: so `q_ned_from_frd = (q₀, q̄)`. Returned with `w ≥ 0`.
fn from_k_eigenvector(v: &Vector4<f64>) -> UnitQuaternion<f64> {
    let q = nalgebra::Quaternion::new(v[3], v[0], v[1], v[2]);
    crate::math::quat::shortest(&UnitQuaternion::new_normalize(q))
}

/// Davenport's q-method: the eigenvector of K for its largest eigenvalue (Castillo (90)), by a
/// symmetric eigen-solver. The reference solution.
pub fn davenport(obs: &[VectorObservation]) -> Result<UnitQuaternion<f64>, ObservationError> {
    let (k, _) = davenport_k(obs)?;
    let eig = k.symmetric_eigen();
    let i = eig.eigenvalues.imax();
    Ok(from_k_eigenvector(&eig.eigenvectors.column(i).into_owned()))
}

/// The same optimum by QUEST (Shuster): Newton iteration for λ_max on K's characteristic
/// polynomial from `λ₀ = Σ aᵢ`, then the optimal quaternion from the adjugate of `(λ+σ)I − S`.
/// About ten times cheaper than the eigen-solver; falls back to it when the rotation is near
/// 180° (where the adjugate form loses precision).
pub fn quest(obs: &[VectorObservation]) -> Result<UnitQuaternion<f64>, ObservationError> {
    let (k, b) = davenport_k(obs)?;
    let s = b + b.transpose();
    let sigma = b.trace();
    let z = Vector3::new(k[(0, 3)], k[(1, 3)], k[(2, 3)]);
    let kappa = adjugate_trace(&s);
    let delta = s.determinant();
    let a = sigma * sigma - kappa;
    let bb = sigma * sigma + z.dot(&z);
    let c = delta + z.dot(&(s * z));
    let d = z.dot(&(s * s * z));
    let total_weight: f64 = obs.iter().map(|o| o.weight.max(0.0)).sum();
    let mut lambda = total_weight;
    for _ in 0..20 {
        let f = lambda.powi(4) - (a + bb) * lambda * lambda - c * lambda + (a * bb + c * sigma - d);
        let df = 4.0 * lambda.powi(3) - 2.0 * (a + bb) * lambda - c;
        if df.abs() < 1e-15 {
            break;
        }
        let step = f / df;
        lambda -= step;
        if step.abs() < 1e-13 * total_weight {
            break;
        }
    }
    let alpha = lambda * lambda - sigma * sigma + kappa;
    let beta = lambda - sigma;
    let gamma = (lambda + sigma) * alpha - delta;
    let x = (Matrix3::identity() * alpha + s * beta + s * s) * z;
    let norm = (gamma * gamma + x.norm_squared()).sqrt();
    // Near 180° both γ and x vanish together; trust the eigen-solver there.
    if norm < 1e-6 * total_weight.powi(3) || !norm.is_finite() {
        return davenport(obs);
    }
    Ok(from_k_eigenvector(&Vector4::new(x.x, x.y, x.z, gamma)))
}

/// Trace of the adjugate of a symmetric 3×3 matrix (the sum of its principal 2×2 minors).
fn adjugate_trace(s: &Matrix3<f64>) -> f64 {
    s[(1, 1)] * s[(2, 2)] - s[(1, 2)] * s[(2, 1)] + s[(0, 0)] * s[(2, 2)] - s[(0, 2)] * s[(2, 0)]
        + s[(0, 0)] * s[(1, 1)]
        - s[(0, 1)] * s[(1, 0)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn obs(q: &UnitQuaternion<f64>, r: Vector3<f64>, w: f64) -> VectorObservation {
        VectorObservation {
            body: q.inverse() * r,
            reference: r,
            weight: w,
        }
    }

    fn unit_quat() -> impl Strategy<Value = UnitQuaternion<f64>> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
            .prop_filter("non-zero", |(w, x, y, z)| {
                w * w + x * x + y * y + z * z > 1e-3
            })
            .prop_map(|(w, x, y, z)| {
                UnitQuaternion::new_normalize(nalgebra::Quaternion::new(w, x, y, z))
            })
    }

    proptest! {
        /// Exact observations of gravity and the Earth field recover the attitude, and the QUEST
        /// fast path agrees with the eigen-solver everywhere, 180° rotations included.
        #[test]
        fn q_method_recovers_the_attitude_and_quest_agrees(q in unit_quat(), wa in 0.1..2.0f64, wm in 0.05..2.0f64) {
            let o = [obs(&q, Vector3::new(0.0, 0.0, -1.0), wa), obs(&q, Vector3::new(0.22, 0.01, 0.43), wm)];
            let d = davenport(&o).unwrap();
            let f = quest(&o).unwrap();
            prop_assert!(d.angle_to(&q) < 1e-9, "davenport {d:?} vs {q:?}");
            prop_assert!(f.angle_to(&d) < 1e-7, "quest {f:?} vs davenport {d:?}");
            prop_assert!(d.w >= 0.0 && f.w >= 0.0);
        }
    }

    #[test]
    fn noisy_observations_weigh_as_wahba_says() {
        // With the accelerometer weighted far above the magnetometer, a bent magnetometer vector
        // changes the heading but hardly the tilt.
        let q = UnitQuaternion::from_euler_angles(0.2, -0.1, 0.7);
        let g = Vector3::new(0.0, 0.0, -1.0);
        let m = Vector3::new(0.2, 0.0, 0.45);
        let bent = UnitQuaternion::from_euler_angles(0.05, 0.0, 0.0) * (q.inverse() * m);
        let o = [
            obs(&q, g, 1.0),
            VectorObservation {
                body: bent,
                reference: m,
                weight: 0.01,
            },
        ];
        let est = quest(&o).unwrap();
        // Tilt is where NED-down points in the body; only the heading should have moved.
        let tilt_err = (est.inverse() * Vector3::z()).angle(&(q.inverse() * Vector3::z()));
        assert!(tilt_err < 1e-3, "{tilt_err}");
        let heading_err = (crate::math::quat::TiltYaw::of(&est).yaw
            - crate::math::quat::TiltYaw::of(&q).yaw)
            .abs();
        assert!(
            heading_err > 0.01,
            "the bent magnetometer must move the heading: {heading_err}"
        );
    }

    #[test]
    fn degenerate_observations_are_refused_with_a_reason() {
        let g = Vector3::new(0.0, 0.0, -1.0);
        let mk = |b: Vector3<f64>, r: Vector3<f64>| VectorObservation {
            body: b,
            reference: r,
            weight: 1.0,
        };
        assert_eq!(
            davenport(&[mk(g, g), mk(Vector3::new(f64::NAN, 0.0, 0.0), g)]),
            Err(ObservationError::NonFinite)
        );
        assert_eq!(
            davenport(&[mk(g, g), mk(Vector3::zeros(), g)]),
            Err(ObservationError::Zero)
        );
        assert_eq!(
            davenport(&[mk(g, g), mk(g * 2.0, g)]),
            Err(ObservationError::Parallel)
        );
        assert_eq!(quest(&[mk(g, g)]), Err(ObservationError::TooFew));
    }
}
