use super::*;
use proptest::prelude::*;

fn unit_quat() -> impl Strategy<Value = UnitQuaternion<f64>> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
        .prop_filter("non-zero", |(w, x, y, z)| {
            w * w + x * x + y * y + z * z > 1e-3
        })
        .prop_map(|(w, x, y, z)| UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z)))
}

fn vec3(r: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

fn same_rotation(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, tol: f64) -> bool {
    a.angle_to(b) < tol
}

proptest! {
    #[test]
    fn propagation_keeps_unit_norm(q in unit_quat(), w in vec3(20.0), dt in 0.0..0.1f64) {
        let mut p = q;
        for _ in 0..100 {
            p = propagate(&p, &w, dt);
        }
        prop_assert!((p.quaternion().norm() - 1.0).abs() < 1e-12);
        let h = hypersphere_step(&q, &(q.quaternion() * Quaternion::from_parts(0.0, w * 0.5)), dt);
        prop_assert!((h.quaternion().norm() - 1.0).abs() < 1e-12);
        prop_assert!(same_rotation(&h, &propagate(&q, &w, dt), 1e-12));
    }

    #[test]
    fn exp_and_ln_are_inverse(q in unit_quat(), scale in 0.1..3.0f64) {
        let q = q.into_inner() * scale;
        let back = exp(&ln(&q));
        prop_assert!((back - q).norm() < 1e-12 * scale.max(1.0));
    }

    #[test]
    fn ln_of_exp_is_identity_below_pi(v in vec3(1.7), s in -1.0..1.0f64) {
        prop_assume!(v.norm() < std::f64::consts::PI - 1e-6);
        let q = Quaternion::from_parts(s, v);
        prop_assert!((ln(&exp(&q)) - q).norm() < 1e-12);
    }

    #[test]
    fn rotation_vector_round_trips(q in unit_quat()) {
        let phi = rotation_vector(&q);
        prop_assert!(phi.norm() <= std::f64::consts::PI + 1e-12);
        prop_assert!(same_rotation(&from_rotation_vector(&phi), &q, 1e-9));
    }

    #[test]
    fn square_root_squares_back(q in unit_quat()) {
        let r = sqrt(&q);
        prop_assert!(same_rotation(&(r * r), &q, 1e-9));
        prop_assert!((r.angle() - 0.5 * q.angle()).abs() < 1e-9);
    }

    #[test]
    fn rotation_matrix_round_trips(q in unit_quat()) {
        let m = to_rotation_matrix(&q);
        prop_assert!((m - q.to_rotation_matrix().into_inner()).abs().max() < 1e-12, "Zabunov (33) = nalgebra");
        let back = from_rotation_matrix(&m);
        prop_assert!(back.w >= 0.0);
        prop_assert!(same_rotation(&back, &q, 1e-9));
    }

    #[test]
    fn product_matrix_is_the_quaternion_product(q in unit_quat(), w in vec3(10.0)) {
        let by_matrix = product_matrix(q.quaternion()) * w;
        let by_product = q.quaternion() * Quaternion::from_parts(0.0, w);
        prop_assert!((by_matrix[0] - by_product.w).abs() < 1e-12);
        prop_assert!((by_matrix.fixed_rows::<3>(1) - by_product.imag()).norm() < 1e-12);
    }

    #[test]
    fn tilt_yaw_decomposition_recomposes(q in unit_quat()) {
        let d = TiltYaw::of(&q);
        prop_assert!((0.0..std::f64::consts::PI + 1e-12).contains(&d.tilt));
        prop_assert!((-std::f64::consts::PI..std::f64::consts::PI).contains(&d.yaw));
        prop_assert!(same_rotation(&d.compose(), &q, 1e-7), "{d:?}");
        // The tilt part moves the body z axis by exactly α_H; the yaw part leaves it alone.
        let z = Vector3::z();
        prop_assert!(((q * z).angle(&z) - d.tilt).abs() < 1e-7);
    }

    #[test]
    fn error_quaternion_is_the_shortest_rotation(q in unit_quat(), e in unit_quat()) {
        let qd = q * e;
        let err = error_body(&q, &qd);
        prop_assert!(err.w >= 0.0);
        prop_assert!(same_rotation(&(q * err), &qd, 1e-9));
        prop_assert!(err.angle() <= std::f64::consts::PI + 1e-12);
    }
}

#[test]
fn near_singular_cases() {
    // Half turns: trace = −1, the trace branch would divide by zero.
    for axis in [
        Vector3::x(),
        Vector3::y(),
        Vector3::z(),
        Vector3::new(1.0, 1.0, 0.0).normalize(),
    ] {
        let q = from_rotation_vector(&(axis * std::f64::consts::PI));
        let back = from_rotation_matrix(&to_rotation_matrix(&q));
        assert!(same_rotation(&back, &q, 1e-12), "{axis:?}");
    }
    // Antipodal: q and −q are the same attitude, the error is the identity.
    let q = UnitQuaternion::from_euler_angles(0.3, -1.2, 2.5);
    let minus = UnitQuaternion::new_unchecked(-q.into_inner());
    assert!(error_body(&q, &minus).angle() < 1e-12);
    assert_eq!(error_body(&q, &minus).w, 1.0);
    // Tiny angles: exp/ln stay accurate.
    let tiny = Vector3::new(1e-10, -2e-10, 3e-10);
    assert!((rotation_vector(&from_rotation_vector(&tiny)) - tiny).norm() < 1e-22);
    // Pure yaw and pure tilt decompose into themselves.
    let yaw = TiltYaw::of(&from_rotation_vector(&Vector3::new(0.0, 0.0, 1.0)));
    assert!(yaw.tilt.abs() < 1e-12 && (yaw.yaw - 1.0).abs() < 1e-12);
    let tilt = TiltYaw::of(&from_rotation_vector(&Vector3::new(0.0, 0.5, 0.0)));
    assert!(
        (tilt.tilt - 0.5).abs() < 1e-12
            && (tilt.tilt_axis_angle - std::f64::consts::FRAC_PI_2).abs() < 1e-12
    );
}
