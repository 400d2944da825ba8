//! Magnetometer calibration: the least-squares ellipsoid fit behind Castillo (75)–(79).
//!
//! Raw readings taken in every orientation lie on an ellipsoid: the Earth's field (a sphere)
//! bent by soft iron and moved by hard iron. Castillo fits it with MATLAB's `ellipsoid_fit`
//! (Castillo §5.1.1) and reads off the offset (76), the principal axes R (77) and the radii
//! (78), whose inverses are the scale E (79). This is the same fit: the general quadric
//!
//! ```text
//! A x² + B y² + C z² + 2D xy + 2E xz + 2F yz + 2G x + 2H y + 2I z = 1
//! ```
//!
//! by linear least squares, its centre (the offset), and the eigen-decomposition of its shape
//! (R and the radii). The data are centred and scaled before the fit so that the normal
//! equations stay well conditioned whatever the sensor's unit.
//!
//! The fit knows the ellipsoid's shape, not the field's strength: E maps it onto a sphere whose
//! radius is the strength the caller expects at the site (`ATT_MAG_STR`, gauss), so that the
//! calibrated field keeps its unit and the strength check keeps its meaning.

use nalgebra::{Matrix3, Matrix4, Rotation3, SMatrix, SVector, Vector3};

/// Why a set of samples gives no calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FitError {
    /// Fewer finite samples than a fit needs.
    TooFewSamples {
        /// Finite samples given.
        got: usize,
        /// Samples needed.
        need: usize,
    },
    /// The samples do not cover enough orientations (a vehicle turned about one axis only).
    PoorCoverage {
        /// Directions (of [`COVERAGE_DIRECTIONS`]) with samples.
        covered: usize,
        /// Directions needed.
        need: usize,
    },
    /// The best quadric is not an ellipsoid (degenerate or inconsistent data).
    NotAnEllipsoid,
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FitError::TooFewSamples { got, need } => {
                write!(f, "{got} samples, at least {need} needed")
            }
            FitError::PoorCoverage { covered, need } => write!(
                f,
                "samples cover {covered} of {COVERAGE_DIRECTIONS} directions, {need} needed: turn the vehicle through every orientation"
            ),
            FitError::NotAnEllipsoid => write!(f, "the samples do not lie on an ellipsoid"),
        }
    }
}

impl std::error::Error for FitError {}

/// Samples a fit needs at least (nine unknowns, with room for noise).
pub const MIN_SAMPLES: usize = 50;
/// Directions the coverage is counted in: the 26 of a cube's faces, edges and corners.
pub const COVERAGE_DIRECTIONS: usize = 26;
/// Directions the samples must reach (PX4 and ArduPilot likewise want most sides seen).
pub const MIN_COVERAGE: usize = 20;

/// A fitted ellipsoid: `m_raw = offset + R diag(radii) u` for unit vectors `u`.
#[derive(Debug, Clone, PartialEq)]
pub struct Ellipsoid {
    /// Centre: the hard-iron offset, Castillo (76).
    pub offset: Vector3<f64>,
    /// Principal axes (a proper rotation), Castillo (77).
    pub rotation: Rotation3<f64>,
    /// Semi-axes along the columns of `rotation`, Castillo (78).
    pub radii: Vector3<f64>,
    /// RMS of (|calibrated| − 1) over the samples on the unit sphere: the fit's residual.
    pub residual_rms: f64,
    /// Directions covered (of [`COVERAGE_DIRECTIONS`]).
    pub coverage: usize,
}

impl Ellipsoid {
    /// Castillo's scale E (79) taking the ellipsoid onto a sphere of radius `strength`.
    pub fn scale(&self, strength: f64) -> Vector3<f64> {
        self.radii.map(|r| strength / r)
    }

    /// The soft-iron correction `R E Rᵀ` of Castillo (75) in body axes, E for `strength`.
    pub fn correction(&self, strength: f64) -> Matrix3<f64> {
        let r = self.rotation.matrix();
        r * Matrix3::from_diagonal(&self.scale(strength)) * r.transpose()
    }

    /// Castillo (75) in body axes: the field `R E Rᵀ (m_raw − offset)`, E for `strength`.
    pub fn correct(&self, raw: &Vector3<f64>, strength: f64) -> Vector3<f64> {
        self.correction(strength) * (raw - self.offset)
    }
}
/// The quadric `vᵀ [x², y², z², 2xy, 2xz, 2yz, 2x, 2y, 2z] = 1` through the samples, centred on
/// `mean` and scaled by `spread`, by least squares.
fn quadric(
    samples: &[Vector3<f64>],
    mean: &Vector3<f64>,
    spread: f64,
) -> Result<SVector<f64, 9>, FitError> {
    // Least squares of D v = 1, D's rows [x², y², z², 2xy, 2xz, 2yz, 2x, 2y, 2z].
    let mut dtd = SMatrix::<f64, 9, 9>::zeros();
    let mut dt1 = SVector::<f64, 9>::zeros();
    for s in samples {
        let p = (s - mean) / spread;
        let row = SVector::<f64, 9>::from_column_slice(&[
            p.x * p.x,
            p.y * p.y,
            p.z * p.z,
            2.0 * p.x * p.y,
            2.0 * p.x * p.z,
            2.0 * p.y * p.z,
            2.0 * p.x,
            2.0 * p.y,
            2.0 * p.z,
        ]);
        dtd += row * row.transpose();
        dt1 += row;
    }
    let v = dtd.cholesky().ok_or(FitError::NotAnEllipsoid)?.solve(&dt1);
    if v.iter().any(|x| !x.is_finite()) {
        return Err(FitError::NotAnEllipsoid);
    }
    Ok(v)
}

/// Index of the nearest to `v` of the 26 directions of a cube's faces, edges and corners
/// ((x, y, z) each −1, 0 or +1, not all 0, numbered in that order, x slowest). The nearest one
/// with k non-zero components takes the signs of v's k largest components and is
/// (|v₁| + … + |v_k|)/√k along v: the best of k = 1, 2, 3 is the nearest (no table, no search:
/// this runs for every sample when the onboard calibration counts its coverage).
pub(crate) fn direction(v: &Vector3<f64>) -> Option<usize> {
    if v.iter().any(|x| !x.is_finite()) || *v == Vector3::zeros() {
        return None;
    }
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| v[b].abs().total_cmp(&v[a].abs()));
    let a = order.map(|i| v[i].abs());
    let scores = [
        a[0],
        (a[0] + a[1]) / 2f64.sqrt(),
        (a[0] + a[1] + a[2]) / 3f64.sqrt(),
    ];
    let k = (0..3).max_by(|&i, &j| scores[i].total_cmp(&scores[j]))? + 1;
    let mut d = [0i8; 3];
    for &i in &order[..k] {
        d[i] = if v[i] < 0.0 { -1 } else { 1 };
    }
    let cell = (d[0] + 1) as usize * 9 + (d[1] + 1) as usize * 3 + (d[2] + 1) as usize;
    Some(if cell > 13 { cell - 1 } else { cell }) // the centre, 13, is not a direction
}

/// Fits the ellipsoid to raw magnetometer samples (any unit; non-finite samples skipped).
pub fn fit_ellipsoid(samples: &[Vector3<f64>]) -> Result<Ellipsoid, FitError> {
    let finite: Vec<Vector3<f64>> = samples
        .iter()
        .copied()
        .filter(|s| s.iter().all(|x| x.is_finite()))
        .collect();
    if finite.len() < MIN_SAMPLES {
        return Err(FitError::TooFewSamples {
            got: finite.len(),
            need: MIN_SAMPLES,
        });
    }
    // Centred and scaled to unit RMS radius: the normal equations below stay well conditioned.
    let mean = finite.iter().sum::<Vector3<f64>>() / finite.len() as f64;
    let spread = (finite
        .iter()
        .map(|s| (s - mean).norm_squared())
        .sum::<f64>()
        / finite.len() as f64)
        .sqrt();
    if spread.is_nan() || spread <= 0.0 {
        return Err(FitError::NotAnEllipsoid);
    }
    let v = quadric(&finite, &mean, spread)?;
    // The quadric as a 4×4 matrix, its centre, and its shape about the centre.
    #[rustfmt::skip]
    let a = Matrix4::new(
        v[0], v[3], v[4], v[6],
        v[3], v[1], v[5], v[7],
        v[4], v[5], v[2], v[8],
        v[6], v[7], v[8], -1.0,
    );
    let a3 = a.fixed_view::<3, 3>(0, 0).into_owned();
    let centre =
        -a3.try_inverse().ok_or(FitError::NotAnEllipsoid)? * Vector3::new(v[6], v[7], v[8]);
    let mut t = Matrix4::identity();
    t.fixed_view_mut::<1, 3>(3, 0)
        .copy_from(&centre.transpose());
    let moved = t * a * t.transpose();
    let k = -moved[(3, 3)];
    if k.is_nan() || k == 0.0 {
        return Err(FitError::NotAnEllipsoid);
    }
    let shape = moved.fixed_view::<3, 3>(0, 0).into_owned() / k;
    // (An eigen-decomposition of a matrix holding NaN never converges.)
    if shape.iter().any(|x| !x.is_finite()) {
        return Err(FitError::NotAnEllipsoid);
    }
    let eig = shape.symmetric_eigen();
    if eig.eigenvalues.iter().any(|&l| l.is_nan() || l <= 0.0) {
        return Err(FitError::NotAnEllipsoid);
    }
    let mut axes = eig.eigenvectors;
    if axes.determinant() < 0.0 {
        axes.column_mut(0).neg_mut(); // a proper rotation: the same ellipsoid
    }
    let ellipsoid = Ellipsoid {
        offset: mean + centre * spread,
        rotation: Rotation3::from_matrix_unchecked(axes),
        radii: eig.eigenvalues.map(|l| spread / l.sqrt()),
        residual_rms: 0.0,
        coverage: 0,
    };
    let mut covered = [false; COVERAGE_DIRECTIONS];
    let mut sum_sq = 0.0;
    for s in &finite {
        let u = ellipsoid.correct(s, 1.0);
        sum_sq += (u.norm() - 1.0).powi(2);
        if let Some(i) = direction(&u) {
            covered[i] = true;
        }
    }
    let coverage = covered.iter().filter(|&&c| c).count();
    if coverage < MIN_COVERAGE {
        return Err(FitError::PoorCoverage {
            covered: coverage,
            need: MIN_COVERAGE,
        });
    }
    Ok(Ellipsoid {
        residual_rms: (sum_sq / finite.len() as f64).sqrt(),
        coverage,
        ..ellipsoid
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use nalgebra::UnitQuaternion;

    /// Unit vectors spread over the sphere (a Fibonacci lattice).
    fn sphere(n: usize) -> Vec<Vector3<f64>> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let a = golden * i as f64;
                Vector3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect()
    }

    #[test]
    fn castillos_own_ellipsoid_is_recovered() {
        // Castillo (76)–(78): offset, axes and radii of a real magnetometer (raw units).
        let offset = Vector3::new(0.4045, -0.5655, 0.0772);
        #[rustfmt::skip]
        // Printed to four digits: made orthonormal (the nearest rotation) first.
        let r = Rotation3::from_matrix_eps(&Matrix3::new(
            -0.9550, 0.2965, -0.0109,
            0.2966, 0.9529, -0.0641,
            0.0086, 0.0644, 0.9979,
        ), 1e-12, 1000, Rotation3::identity());
        let radii = Vector3::new(165.75, 163.69, 148.84);
        let raw: Vec<_> = sphere(500)
            .iter()
            .map(|u| offset + r * u.component_mul(&radii))
            .collect();
        let fit = fit_ellipsoid(&raw).unwrap();
        assert!((fit.offset - offset).norm() < 1e-6, "{fit:?}");
        assert!(fit.residual_rms < 1e-9 && fit.coverage == COVERAGE_DIRECTIONS);
        // The radii in some order, each with its axis (up to sign).
        for i in 0..3 {
            let j = (0..3)
                .min_by(|&a, &b| {
                    (fit.radii[a] - radii[i])
                        .abs()
                        .total_cmp(&(fit.radii[b] - radii[i]).abs())
                })
                .unwrap();
            assert!((fit.radii[j] - radii[i]).abs() < 1e-6, "{fit:?}");
            let axis = r.matrix().column(i);
            assert!(fit.rotation.matrix().column(j).dot(&axis).abs() > 1.0 - 1e-9);
        }
        // Castillo (79): E = diag(1/radii) maps the data onto the unit sphere.
        let e = fit.scale(1.0);
        assert!((e.max() - 1.0 / 148.84).abs() < 1e-9 && (e.min() - 1.0 / 165.75).abs() < 1e-9);
        for m in &raw {
            assert!((fit.correct(m, 1.0).norm() - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn the_correction_undoes_a_soft_and_hard_iron_distortion_in_body_axes() {
        let soft = Matrix3::new(1.08, 0.04, -0.02, 0.04, 0.95, 0.03, -0.02, 0.03, 1.02);
        let hard = Vector3::new(0.12, -0.08, 0.2);
        let field = Vector3::new(0.2, 0.03, 0.43); // NED, 0.48 gauss
        let attitudes: Vec<_> = sphere(400)
            .iter()
            .enumerate()
            .map(|(i, u)| UnitQuaternion::from_scaled_axis(u * (0.5 + 2.5 * (i % 7) as f64 / 6.0)))
            .collect();
        let raw: Vec<_> = attitudes
            .iter()
            .map(|q| soft * (q.inverse() * field) + hard)
            .collect();
        let fit = fit_ellipsoid(&raw).unwrap();
        for (q, m) in attitudes.iter().zip(&raw) {
            let body = q.inverse() * field;
            assert!((fit.correct(m, field.norm()) - body).norm() < 1e-9);
        }
    }

    /// The closed form picks the direction a search over all 26 picks.
    #[test]
    fn the_nearest_direction_is_the_one_a_search_finds() {
        let mut all = vec![];
        for x in -1i8..=1 {
            for y in -1i8..=1 {
                for z in -1i8..=1 {
                    if (x, y, z) != (0, 0, 0) {
                        all.push(Vector3::new(x as f64, y as f64, z as f64).normalize());
                    }
                }
            }
        }
        for (i, d) in all.iter().enumerate() {
            assert_eq!(direction(d), Some(i));
        }
        for u in sphere(5000) {
            let v = u * 0.37;
            let best = (0..26)
                .max_by(|&i, &j| all[i].dot(&v).total_cmp(&all[j].dot(&v)))
                .unwrap();
            let got = direction(&v).unwrap();
            assert!(
                (all[got].dot(&v) - all[best].dot(&v)).abs() < 1e-12,
                "{v:?}"
            );
        }
        assert_eq!(direction(&Vector3::zeros()), None);
        assert_eq!(direction(&Vector3::new(f64::NAN, 1.0, 0.0)), None);
    }

    #[test]
    fn bad_sample_sets_are_refused_with_the_reason() {
        let few: Vec<_> = sphere(20);
        assert_eq!(
            fit_ellipsoid(&few),
            Err(FitError::TooFewSamples {
                got: 20,
                need: MIN_SAMPLES
            })
        );
        // Turned about the vertical only: a circle, not an ellipsoid.
        let circle: Vec<_> = (0..200)
            .map(|i| {
                let a = i as f64 * 0.1;
                Vector3::new(a.cos(), a.sin(), 0.5)
            })
            .collect();
        assert!(fit_ellipsoid(&circle).is_err());
        // One half of the sphere only.
        let half: Vec<_> = sphere(400).into_iter().filter(|u| u.z > 0.3).collect();
        assert!(matches!(
            fit_ellipsoid(&half),
            Err(FitError::PoorCoverage { .. })
        ));
        let constant = vec![Vector3::new(0.1, 0.2, 0.3); 100];
        assert_eq!(fit_ellipsoid(&constant), Err(FitError::NotAnEllipsoid));
        let nan = vec![Vector3::new(f64::NAN, 0.0, 0.0); 100];
        assert!(matches!(
            fit_ellipsoid(&nan),
            Err(FitError::TooFewSamples { got: 0, .. })
        ));
    }
}
