//! A start in motion: the gyro bias and the attitude fitted to the first seconds at once.
//!
//! Started at rest, the filter takes the mean rate as the bias (`rest.rs`). Started in motion it
//! has no such moment, and a correction-driven bias filter learns a MEMS gyro's turn-on bias
//! (1–2°/s) over tens of seconds, during which the tilt lags by the bias times the
//! accelerometer's time constant and the heading by the bias times the magnetometer's.
//!
//! Instead, the first [`FIT_S`] seconds are fitted in one least-squares problem. The gyro,
//! integrated from the start with the bias it had then, gives `R_k` (start frame ← body). A
//! residual bias `b` turns that frame by `J_k b` with `J_k = Σ R_j dt` (`R_k = Exp(J_k b) R̃_k`),
//! so a field constant in the true start frame, `M`, is seen as
//! `u_k = R_k m_k ≈ M − [u_k]× J_k b`: linear in `(M, b)`. The same holds for the specific force
//! about its mean `A` (the vehicle's accelerations averaging out, or taken off where the position
//! estimator knows them), with the accelerometer's bias as a fourth unknown: fixed in the body,
//! it turns with it in the start frame as a drift would. Twelve unknowns, three rows per vector,
//! weighted by noise densities so the rates of the sensors do not matter. A clean field pins the
//! bias across it within a second; the accelerometer pins the rest, as well as the vehicle's
//! accelerations let it (the part about the field's axis is the slowest: see the covariance).
//! The fit's residuals say whether its model held: a field that turned more than its noise
//! (indoors, near steel) or a sustained acceleration refuses the fit, and the filter goes on as
//! it would have.

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, UnitQuaternion, Vector3};

/// The unknowns: the field `M` (0..3), the specific force's mean `A` (3..6), the gyro bias `b`
/// (6..9) and the accelerometer's bias over its reading's size `β` (9..12).
const UNKNOWNS: usize = 12;
type Normals = SMatrix<f64, UNKNOWNS, UNKNOWNS>;
type Unknowns = SVector<f64, UNKNOWNS>;

/// How long the fit collects (s).
pub const FIT_S: f64 = 4.0;
/// The least RMS rate over the window for the fit to be taken (rad/s): 5°/s.
const MIN_RMS_RATE_RAD_S: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// Noise density of the normalised field's direction (rad·√s): the sensor's noise and a little
/// of the field's unevenness.
const SIGMA_MAG: f64 = 0.002;
/// The same for the specific force's direction: the vehicle's accelerations, 0.05 rad over a
/// second.
const SIGMA_ACCEL: f64 = 0.05;
/// Prior standard deviation of the gyro's bias (rad/s): a MEMS gyro's turn-on bias, 1°/s, as the
/// bias filter starts with.
const SIGMA_GYRO_BIAS: f64 = 0.0175;
/// Prior standard deviation of the accelerometer's bias over its reading (0.2 m/s², the `noisy`
/// preset's): observable only as the body turns.
const SIGMA_ACCEL_BIAS: f64 = 0.02;
/// The accelerometer's noise density is its RMS residual over this correlation time (s), within
/// [`MIN_SIGMA_ACCEL`, `SIGMA_ACCEL`].
const ACCEL_CORRELATION_S: f64 = 0.25;
const MIN_SIGMA_ACCEL: f64 = 0.005;
/// Largest RMS residual of the field's direction beyond the sensor's own noise for the fit to be
/// taken (rad): an uneven field (indoors, near steel) turns along the path by more, and the fit
/// would take that turn for a bias.
const MAX_FIELD_UNEVENNESS: f64 = 0.01;
/// Largest RMS residual of the specific force's direction (rad): a hover's swaying is well
/// below, a take-off's acceleration is not.
const MAX_ACCEL_RESIDUAL: f64 = 0.2;

/// The normal equations of one vector's rows: `N`, `Hᵀ W y`, `yᵀ W y` and the weight summed.
#[derive(Debug, Clone, Copy)]
struct Normal {
    n: Normals,
    z: Unknowns,
    s: f64,
    weight: f64,
}

impl Normal {
    fn new() -> Self {
        Self {
            n: Normals::zeros(),
            z: Unknowns::zeros(),
            s: 0.0,
            weight: 0.0,
        }
    }

    /// Rows `[I at col, −[u]× J at 6..9, R at 9..12 if given] x = u` with weight `w`.
    fn add(
        &mut self,
        col: usize,
        u: &Vector3<f64>,
        j: &Matrix3<f64>,
        r: Option<&Matrix3<f64>>,
        w: f64,
    ) {
        let mut h = SMatrix::<f64, 3, UNKNOWNS>::zeros();
        h.fixed_view_mut::<3, 3>(0, col)
            .copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, 6)
            .copy_from(&(-u.cross_matrix() * j));
        if let Some(r) = r {
            h.fixed_view_mut::<3, 3>(0, 9).copy_from(r);
        }
        self.n += h.transpose() * h * w;
        self.z += h.transpose() * u * w;
        self.s += u.norm_squared() * w;
        self.weight += w;
    }

    /// The RMS residual at `x` (the units of the rows).
    fn rms_residual(&self, x: &Unknowns) -> f64 {
        let rss = self.s - 2.0 * x.dot(&self.z) + x.dot(&(self.n * x));
        (rss.max(0.0) / self.weight.max(1e-12)).sqrt()
    }
}

/// What the fit found.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionStart {
    /// The correction to the bias the gyro was integrated with (rad/s, body frame).
    pub bias_correction: Vector3<f64>,
    /// Its covariance ((rad/s)²).
    pub bias_covariance: Matrix3<f64>,
    /// The start frame from the body now, the bias's drift taken out.
    pub start_from_body: Rotation3<f64>,
    /// The mean specific force's direction in the start frame (points up).
    pub up: Vector3<f64>,
    /// The field's direction in the start frame.
    pub field: Vector3<f64>,
    /// How many magnetometer samples showed it.
    pub field_samples: f64,
}

/// One sample for the fit.
#[derive(Debug, Clone, Copy)]
pub struct FitSample<'a> {
    /// The filter's gyro frame from the body after this sample (`q_gyro`: the gyro integrated
    /// with the bias it had).
    pub gyro_frame: &'a UnitQuaternion<f64>,
    /// The rate less that bias (rad/s).
    pub rate: &'a Vector3<f64>,
    /// The specific force (body, m/s²).
    pub accel: &'a Vector3<f64>,
    /// The vehicle's acceleration (NED, m/s²), where the position estimator knows it.
    pub known_accel: Option<&'a Vector3<f64>>,
    /// The attitude estimated so far, while [`MotionStartFit::wants_estimate`].
    pub estimate: Option<UnitQuaternion<f64>>,
    /// The field, if one came.
    pub mag: Option<&'a Vector3<f64>>,
}

/// The fit's accumulator.
#[derive(Debug, Clone)]
pub struct MotionStartFit {
    /// The start frame from the gyro frame (the first sample's), and the start frame from the
    /// body now.
    start_from_gyro: Option<UnitQuaternion<f64>>,
    r: Rotation3<f64>,
    j: Matrix3<f64>,
    mag: Normal,
    accel: Normal,
    elapsed_s: f64,
    since_mag_s: f64,
    /// The last field's direction in the start frame, and the sum and count of the squared
    /// differences of successive ones: the sensor's white noise (an uneven field changes slowly).
    last_field: Option<Vector3<f64>>,
    field_steps: (f64, f64),
    /// The squared rate integrated (rad²/s).
    rate_sq: f64,
    /// NED from the start frame, as estimated when the first known acceleration came.
    ned_from_start: Option<UnitQuaternion<f64>>,
    done: bool,
}

impl Default for MotionStartFit {
    fn default() -> Self {
        Self {
            start_from_gyro: None,
            r: Rotation3::identity(),
            j: Matrix3::zeros(),
            mag: Normal::new(),
            accel: Normal::new(),
            elapsed_s: 0.0,
            since_mag_s: 0.0,
            last_field: None,
            field_steps: (0.0, 0.0),
            rate_sq: 0.0,
            ned_from_start: None,
            done: false,
        }
    }
}

impl MotionStartFit {
    /// Whether the fit is over (taken, refused or abandoned).
    pub fn done(&self) -> bool {
        self.done
    }

    /// Stops the fit: the start was at rest.
    pub fn abandon(&mut self) {
        self.done = true;
    }

    /// Whether the fit needs the attitude estimated so far: until it has taken NED from the
    /// start frame, with the first known acceleration.
    pub fn wants_estimate(&self) -> bool {
        self.ned_from_start.is_none()
    }

    /// One sample, `dt` seconds after the previous one. Returns the fit once [`FIT_S`] have been
    /// collected and its model held.
    pub fn update(&mut self, sample: &FitSample, dt: f64) -> Option<MotionStart> {
        if self.done || dt <= 0.0 {
            return None;
        }
        // The filter's gyro frame is the gyro integrated already: the start frame is its first.
        let start_from_gyro = *self
            .start_from_gyro
            .get_or_insert_with(|| sample.gyro_frame.inverse());
        self.r = (start_from_gyro * sample.gyro_frame).to_rotation_matrix();
        self.j += self.r.matrix() * dt;
        self.rate_sq += sample.rate.norm_squared() * dt;
        self.elapsed_s += dt;
        self.since_mag_s += dt;
        // The known acceleration is taken off in the start frame through one fixed estimate of
        // NED from it (the first): its error is a constant turn of the acceleration, where the
        // estimate of each moment would carry the very drift the fit measures.
        let mut f = self.r * sample.accel;
        if let Some(a_ned) = sample.known_accel {
            if self.ned_from_start.is_none() {
                self.ned_from_start = sample
                    .estimate
                    .map(|q| q * UnitQuaternion::from_rotation_matrix(&self.r.inverse()));
            }
            if let Some(ned_from_start) = self.ned_from_start {
                f -= ned_from_start.inverse() * a_ned;
            }
        }
        // A body-fixed accelerometer bias turns with the body in the start frame, as a gyro
        // bias's drift would: it is an unknown too, or the fit takes it for one.
        if let Some(u) = unit(&f) {
            let r = *self.r.matrix();
            self.accel
                .add(3, &u, &self.j, Some(&r), dt / (SIGMA_ACCEL * SIGMA_ACCEL));
        }
        if let Some(u) = sample.mag.and_then(unit) {
            let w = std::mem::take(&mut self.since_mag_s) / (SIGMA_MAG * SIGMA_MAG);
            let u = self.r * u;
            if let Some(last) = self.last_field.replace(u) {
                self.field_steps.0 += (u - last).norm_squared();
                self.field_steps.1 += 1.0;
            }
            self.mag.add(0, &u, &self.j, None, w);
        }
        if self.elapsed_s < FIT_S {
            return None;
        }
        self.done = true;
        self.solve()
    }

    fn solve(&self) -> Option<MotionStart> {
        // A vehicle that barely turned (shaken on the ground in a wind) showed the fit little;
        // the rest detector and the bias filter serve it as they would.
        let rms_rate = (self.rate_sq / self.elapsed_s).sqrt();
        if self.mag.weight <= 0.0 || self.accel.weight <= 0.0 || rms_rate < MIN_RMS_RATE_RAD_S {
            return None;
        }
        // Priors: the gyro's correction about the bias it was integrated with (a direction the
        // motion did not show stays there), and the accelerometer's bias.
        let mut prior = Normals::zeros();
        for i in 6..9 {
            prior[(i, i)] = (SIGMA_GYRO_BIAS * SIGMA_GYRO_BIAS).recip();
        }
        for i in 9..12 {
            prior[(i, i)] = (SIGMA_ACCEL_BIAS * SIGMA_ACCEL_BIAS).recip();
        }
        let solve = |accel_scale: f64| {
            let cov = (self.mag.n + self.accel.n * accel_scale + prior).try_inverse()?;
            let x = cov * (self.mag.z + self.accel.z * accel_scale);
            Some((cov, x))
        };
        // First with the accelerometer as a vehicle's unknown accelerations make it; then as
        // its residual shows it was (a known acceleration taken off leaves little), so the
        // direction about the field, which only the tilt shows, is pinned as well as it can be.
        let (_, x) = solve(1.0)?;
        let density = (self.accel.rms_residual(&x) * ACCEL_CORRELATION_S.sqrt())
            .clamp(MIN_SIGMA_ACCEL, SIGMA_ACCEL);
        let (cov, x) = solve((SIGMA_ACCEL / density).powi(2))?;
        // Half the mean squared step of a white noise is its variance.
        let noise = self.field_steps.0 / self.field_steps.1.max(1.0) / 2.0;
        if self.mag.rms_residual(&x).powi(2) > noise + MAX_FIELD_UNEVENNESS.powi(2)
            || self.accel.rms_residual(&x) > MAX_ACCEL_RESIDUAL
        {
            return None;
        }
        let b: Vector3<f64> = x.fixed_rows::<3>(6).into();
        let up: Vector3<f64> = x.fixed_rows::<3>(3).into();
        let field: Vector3<f64> = x.fixed_rows::<3>(0).into();
        // R̃ = Exp(−J b) R.
        let start_from_body = Rotation3::new(-(self.j * b)) * self.r;
        Some(MotionStart {
            bias_correction: b,
            bias_covariance: cov.fixed_view::<3, 3>(6, 6).into(),
            start_from_body,
            up: up.try_normalize(1e-6)?,
            field: field.try_normalize(1e-6)?,
            field_samples: self.field_steps.1 + 1.0,
        })
    }
}

fn unit(v: &Vector3<f64>) -> Option<Vector3<f64>> {
    v.try_normalize(1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flies a body at `rate(t)` through a field `field(t)` (NED) under gravity for the fit's
    /// window, its gyro biased by `bias`: the fit, and the true start frame (the first sample's)
    /// from the body at the end.
    fn fly(
        rate: impl Fn(f64) -> Vector3<f64>,
        field: impl Fn(f64) -> Vector3<f64>,
        bias: Vector3<f64>,
    ) -> (Option<MotionStart>, Rotation3<f64>) {
        let dt = 0.005;
        let mut fit = MotionStartFit::default();
        let (mut truth, mut gyro_frame) = (Rotation3::identity(), UnitQuaternion::identity());
        let (mut found, mut start) = (None, None);
        for k in 0..((FIT_S / dt) as usize + 1) {
            let t = k as f64 * dt;
            truth *= Rotation3::new(rate(t) * dt);
            let measured = rate(t) + bias;
            gyro_frame *= UnitQuaternion::from_scaled_axis(measured * dt);
            let sample = FitSample {
                gyro_frame: &gyro_frame,
                rate: &measured,
                accel: &(truth.inverse() * Vector3::new(0.0, 0.0, -9.81)),
                known_accel: None,
                estimate: None,
                mag: Some(&(truth.inverse() * field(t))),
            };
            found = found.or(fit.update(&sample, dt));
            start.get_or_insert(truth);
        }
        assert!(fit.done());
        (found, start.unwrap_or(truth).inverse() * truth)
    }

    /// A body turning in a constant field under gravity, its gyro biased: the fit finds the bias
    /// and the frame, whatever the motion, within the model's linearisation: its error is of the
    /// second order in the drift `J b`, here 1.2°/s per axis over 4 s, about 8°.
    #[test]
    fn finds_the_bias_and_the_frame_of_a_turning_body() {
        let bias = Vector3::new(1.2, -1.2, 1.2).map(f64::to_radians);
        let (found, truth) = fly(
            |t| Vector3::new((1.3 * t).sin() * 0.4, (0.7 * t).cos() * 0.3, 0.5),
            |_| Vector3::new(0.155, 0.0, 0.41),
            bias,
        );
        let start = found.expect("the fit holds");
        assert!(
            (start.bias_correction - bias).norm() < 0.2f64.to_radians(),
            "{:?}",
            start.bias_correction.map(f64::to_degrees)
        );
        let angle = (start.start_from_body * truth.inverse()).angle();
        assert!(angle < 0.7f64.to_radians(), "{}", angle.to_degrees());
        // Up in the start frame: the first sample's frame, turned by its first step.
        let up = (truth * start.start_from_body.inverse()).inverse() * Vector3::new(0.0, 0.0, -1.0);
        assert!((start.up - up).norm() < 0.01, "{:?} {:?}", start.up, up);
    }

    /// A field that changes while the body turns (a magnet passing) refuses the fit.
    #[test]
    fn a_changing_field_refuses_the_fit() {
        let (found, _) = fly(
            |_| Vector3::new(0.2, -0.1, 0.5),
            |t| Vector3::new(0.155 + 0.1 * (2.0 * t).sin(), 0.05 * t, 0.41),
            Vector3::zeros(),
        );
        assert!(found.is_none());
    }

    /// A body that barely turns (shaken on the ground) is left to the rest detector.
    #[test]
    fn a_body_that_barely_turns_is_not_fitted() {
        let (found, _) = fly(
            |t| Vector3::new(0.03 * (9.0 * t).sin(), 0.03 * (7.0 * t).cos(), 0.0),
            |_| Vector3::new(0.155, 0.0, 0.41),
            Vector3::new(0.01, 0.0, 0.0),
        );
        assert!(found.is_none());
    }
}
