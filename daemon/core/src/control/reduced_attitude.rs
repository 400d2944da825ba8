//! Reduced-attitude control of a quad spinning in its relaxed hover (Mueller & D'Andrea, ICRA
//! 2014, Sec. IV): only the direction of the primary axis `n̄` is controlled, toward the thrust
//! direction the position loop asks for; the spin about it is left free (the body's damping
//! holds it). Three rotors give the collective thrust and the two tilting moments; the yaw
//! moment is whatever those leave.
//!
//! The state is the body rate across `n̄` (the spin about it is left out: it is held at `ω̄`
//! in the linearisation, as Mueller's) and the desired direction seen in the body, `d = Rᵀ
//! n_d`, departing from `n̄` (two components across `n̄`): four states, two inputs (the moments
//! about body x and y beyond the equilibrium's). The dynamics, `J ω̇ = M(f)
//! − D ω − ω × (J ω + h)` and `ḋ = −ω × d` (Mueller (2), (10)), are linearised about the relaxed
//! hover numerically and the gain is the discrete LQR's, by iterating the Riccati equation.

use super::relaxed_hover::{RelaxedHover, arm_m, net_torque};
use airframe::Airframe;
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, UnitQuaternion, Vector2, Vector3};

type State = SVector<f64, 4>;
type Gain = SMatrix<f64, 2, 4>;

/// Why the controller could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReducedAttitudeError {
    /// The three working rotors cannot set thrust and both tilting moments independently.
    #[error("the working rotors cannot set the thrust and both tilting moments")]
    NoAllocation,
    /// The Riccati iteration did not settle.
    #[error("no LQR gain: the Riccati iteration did not converge")]
    NoGain,
    /// The loop rate is not a positive number.
    #[error("the loop rate must be positive, got {0} Hz")]
    Rate(f64),
    /// The hover is not one of this airframe's: not a quad, or the rotors differ.
    #[error("the relaxed hover is not this airframe's (a quad's, one thrust per rotor)")]
    NotThisAirframe,
    /// The body's inertia has no inverse.
    #[error("the airframe's inertia is singular")]
    Inertia,
    /// The hover's thrusts do not hold the body still in turn (its state is not an
    /// equilibrium of this airframe in this air).
    #[error("the relaxed hover is not an equilibrium of this airframe ({0:.3} rad/s² off)")]
    NotAnEquilibrium(f64),
    /// The loop with the gain would not be stable.
    #[error("the LQR loop is not stable (spectral radius {0:.4})")]
    Unstable(f64),
}

/// The controller of one relaxed hover.
#[derive(Debug, Clone)]
pub struct ReducedAttitude {
    hover: RelaxedHover,
    /// The working rotors, in the allocation's order.
    working: [usize; 3],
    /// `[Σf, M_x, M_y]` to the working rotors' thrusts.
    allocation: Matrix3<f64>,
    /// The equilibrium's `[Σf, M_x, M_y]`.
    trim: Vector3<f64>,
    /// Two unit vectors across `n̄` (FRD): the coordinates of `d − n̄`.
    across: [Vector3<f64>; 2],
    gain: Gain,
    max_thrust_n: [f64; 3],
}

/// The rotational model about the relaxed hover, for its linearisation.
struct Model<'a> {
    airframe: &'a Airframe,
    working: [usize; 3],
    allocation: Matrix3<f64>,
    trim: Vector3<f64>,
    hover: &'a RelaxedHover,
    across: [Vector3<f64>; 2],
    inertia_inverse: Matrix3<f64>,
}

impl Model<'_> {
    /// `ẋ` at state `x` under input `u`.
    fn derivative(&self, x: &State, u: &Vector2<f64>) -> State {
        let n = self.hover.axis_frd;
        let w = n * self.hover.spin_rad_s + self.across[0] * x[0] + self.across[1] * x[1];
        let d = (n + self.across[0] * x[2] + self.across[1] * x[3]).normalize();
        let f = self.allocation * (self.trim + Vector3::new(0.0, u[0], u[1]));
        let torque = net_torque(
            self.airframe,
            &self.working,
            f.as_slice(),
            &w,
            self.hover.air_density,
        );
        let w_dot = self.inertia_inverse * torque;
        let d_dot = -w.cross(&d);
        State::new(
            w_dot.dot(&self.across[0]),
            w_dot.dot(&self.across[1]),
            d_dot.dot(&self.across[0]),
            d_dot.dot(&self.across[1]),
        )
    }
}

impl ReducedAttitude {
    /// The controller of `hover` (of `airframe`, in the air it was solved for), its loop at
    /// `rate_hz`.
    pub fn new(
        airframe: &Airframe,
        hover: RelaxedHover,
        rate_hz: f64,
    ) -> Result<Self, ReducedAttitudeError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(ReducedAttitudeError::Rate(rate_hz));
        }
        let rotors = airframe.rotors.len();
        if rotors != 4 || hover.thrust_n.len() != rotors || hover.lost >= rotors {
            return Err(ReducedAttitudeError::NotThisAirframe);
        }
        let mut working = [0; 3];
        for (k, i) in (0..rotors).filter(|&i| i != hover.lost).enumerate() {
            working[k] = i;
        }
        // Rows 0–2 of the effectiveness (Σf, M_x, M_y) for the working rotors, Σf positive.
        let b = airframe.effectiveness();
        let columns = working.map(|i| Vector3::new(-b[(0, i)], b[(1, i)], b[(2, i)]));
        let to_wrench = Matrix3::from_columns(&columns);
        let allocation = to_wrench
            .try_inverse()
            .ok_or(ReducedAttitudeError::NoAllocation)?;
        let trim = to_wrench * Vector3::from(working.map(|i| hover.thrust_n[i]));
        let inertia_inverse = airframe
            .inertia_kg_m2
            .try_inverse()
            .ok_or(ReducedAttitudeError::Inertia)?;
        let n = hover.axis_frd;
        let first = if n.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = (first - n * n.dot(&first)).normalize();
        let across = [e1, n.cross(&e1)];
        let model = Model {
            airframe,
            working,
            allocation,
            trim,
            hover: &hover,
            across,
            inertia_inverse,
        };
        let still = model.derivative(&State::zeros(), &Vector2::zeros()).norm();
        if still.is_nan() || still >= 1e-3 {
            return Err(ReducedAttitudeError::NotAnEquilibrium(still));
        }
        let gain = lqr_gain(&model, 1.0 / rate_hz)?;
        let max_thrust_n = working.map(|i| {
            let r = &airframe.rotors[i];
            r.thrust_n(hover.air_density, r.max_speed_rad_s)
        });
        Ok(Self {
            hover,
            working,
            allocation,
            trim,
            across,
            gain,
            max_thrust_n,
        })
    }

    /// The relaxed hover it flies about.
    pub fn hover(&self) -> &RelaxedHover {
        &self.hover
    }

    /// Each rotor's thrust (N, the airframe's order, zero for the lost one) that turns the
    /// primary axis toward `up_ned` (the direction the thrust should lift in) with `lift_n`
    /// newtons along it, for the body at attitude `q` turning at `rate_frd`. Inputs that are
    /// not numbers hold the hover's own thrusts.
    pub fn update(
        &self,
        up_ned: &Vector3<f64>,
        lift_n: f64,
        q: &UnitQuaternion<f64>,
        rate_frd: &Vector3<f64>,
    ) -> Vec<f64> {
        let finite =
            lift_n.is_finite() && rate_frd.iter().chain(up_ned.iter()).all(|x| x.is_finite());
        let (Some(up), true) = (up_ned.try_normalize(1e-9), finite) else {
            return self.hover.thrust_n.clone();
        };
        let n = self.hover.axis_frd;
        let d = q.inverse_transform_vector(&up);
        let rate_error = rate_frd - n * self.hover.spin_rad_s;
        let e = axis_error(&n, &d, &self.across);
        let x = State::new(
            rate_error.dot(&self.across[0]),
            rate_error.dot(&self.across[1]),
            e.dot(&self.across[0]),
            e.dot(&self.across[1]),
        );
        let u = -self.gain * x;
        // The lift along the axis is the thrust's component on it (thrust along −z).
        let collective = lift_n.max(0.0) / (-n.z).max(0.1);
        let moments = Vector3::new(0.0, self.trim.y + u[0], self.trim.z + u[1]);
        let f = self.saturate(collective, &moments);
        let mut out = vec![0.0; self.hover.thrust_n.len()];
        for (k, &i) in self.working.iter().enumerate() {
            out[i] = f[k];
        }
        out
    }

    /// Thrusts for `collective` and `moments` within each rotor's range, the moments kept
    /// first (PX4's and the mixer's priority): the collective moved as little as it must, and
    /// only when no collective fits, the moments scaled down (by halving the excess).
    fn saturate(&self, collective: f64, moments: &Vector3<f64>) -> Vector3<f64> {
        let per_newton = self.allocation * Vector3::x();
        let fit = |k: f64| -> Option<f64> {
            let m = self.allocation * (moments * k);
            let (mut lo, mut hi) = (0.0_f64, f64::INFINITY);
            for i in 0..3 {
                let (v, top) = (per_newton[i], self.max_thrust_n[i]);
                if v.abs() < 1e-9 {
                    if !(0.0..=top).contains(&m[i]) {
                        return None;
                    }
                } else {
                    let (a, b) = (-m[i] / v, (top - m[i]) / v);
                    lo = lo.max(a.min(b));
                    hi = hi.min(a.max(b));
                }
            }
            (lo <= hi).then(|| collective.clamp(lo, hi))
        };
        let (k, total) = match fit(1.0) {
            Some(total) => (1.0, total),
            None => {
                let (mut good, mut bad) = (0.0, 1.0);
                for _ in 0..20 {
                    let mid = 0.5 * (good + bad);
                    if fit(mid).is_some() {
                        good = mid;
                    } else {
                        bad = mid;
                    }
                }
                (good, fit(good).unwrap_or(0.0))
            }
        };
        let f = self.allocation * (Vector3::new(total, 0.0, 0.0) + moments * k);
        Vector3::from_fn(|i, _| f[i].clamp(0.0, self.max_thrust_n[i]))
    }
}

/// Largest axis error the controller acts on (rad): beyond it the turn is asked at this size.
const MAX_AXIS_ERROR_RAD: f64 = 0.7;

/// The turn from `n` to `d` as a vector across `n` (rad, its length the angle, at most
/// [`MAX_AXIS_ERROR_RAD`]): `d − n` for small angles, and still pointing the way to turn when
/// `d` is behind `n` (where `d − n` across `n` would shrink to nothing).
fn axis_error(n: &Vector3<f64>, d: &Vector3<f64>, across: &[Vector3<f64>; 2]) -> Vector3<f64> {
    let side = d - n * n.dot(d);
    let angle = side.norm().atan2(n.dot(d));
    let way = side.try_normalize(1e-9).unwrap_or(across[0]);
    way * angle.min(MAX_AXIS_ERROR_RAD)
}

/// The discrete LQR gain of `model` linearised about its hover, sampled every `dt_s`.
fn lqr_gain(model: &Model<'_>, dt_s: f64) -> Result<Gain, ReducedAttitudeError> {
    // Numerical Jacobians about the equilibrium (central differences).
    let (x0, u0) = (State::zeros(), Vector2::zeros());
    let mut a = SMatrix::<f64, 4, 4>::zeros();
    let mut b = SMatrix::<f64, 4, 2>::zeros();
    let h = 1e-6;
    for j in 0..4 {
        let mut dx = State::zeros();
        dx[j] = h;
        a.set_column(
            j,
            &((model.derivative(&(x0 + dx), &u0) - model.derivative(&(x0 - dx), &u0)) / (2.0 * h)),
        );
    }
    for j in 0..2 {
        let mut du = Vector2::zeros();
        du[j] = h;
        b.set_column(
            j,
            &((model.derivative(&x0, &(u0 + du)) - model.derivative(&x0, &(u0 - du))) / (2.0 * h)),
        );
    }
    // Zero-order hold: exp([[A, B], [0, 0]] dt) = [[A_d, B_d], [0, I]].
    let mut m = SMatrix::<f64, 6, 6>::zeros();
    m.fixed_view_mut::<4, 4>(0, 0).copy_from(&(a * dt_s));
    m.fixed_view_mut::<4, 2>(0, 4).copy_from(&(b * dt_s));
    let e = expm(&m);
    let ad: SMatrix<f64, 4, 4> = e.fixed_view::<4, 4>(0, 0).into();
    let bd: SMatrix<f64, 4, 2> = e.fixed_view::<4, 2>(0, 4).into();
    // Weights: the axis direction (rad²) far above the rates across it ((rad/s)²); the moments
    // in units of a third of the weight on the mean arm.
    let q = SMatrix::<f64, 4, 4>::from_diagonal(&State::new(0.05, 0.05, 50.0, 50.0));
    let moment_unit = model.airframe.weight_n() * arm_m(model.airframe) / 3.0;
    let r = Matrix2::identity() / (moment_unit * moment_unit);
    let mut p = q;
    for _ in 0..20_000 {
        let bt_p = bd.transpose() * p;
        let k = (r + bt_p * bd)
            .try_inverse()
            .ok_or(ReducedAttitudeError::NoGain)?
            * bt_p
            * ad;
        let next = q + ad.transpose() * p * (ad - bd * k);
        let change = (next - p).norm() / next.norm().max(1e-12);
        p = next;
        if change < 1e-10 {
            let bt_p = bd.transpose() * p;
            let gain = (r + bt_p * bd)
                .try_inverse()
                .ok_or(ReducedAttitudeError::NoGain)?
                * bt_p
                * ad;
            let radius = (ad - bd * gain)
                .complex_eigenvalues()
                .iter()
                .map(|z| z.norm())
                .fold(0.0, f64::max);
            if radius.is_nan() || radius >= 1.0 {
                return Err(ReducedAttitudeError::Unstable(radius));
            }
            return Ok(gain);
        }
    }
    Err(ReducedAttitudeError::NoGain)
}

/// The exponential of `m` (scaling and squaring over a Taylor series).
fn expm(m: &SMatrix<f64, 6, 6>) -> SMatrix<f64, 6, 6> {
    let norm = m.abs().row_sum().max();
    let squarings = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let scaled = m / 2f64.powi(squarings);
    let mut term = SMatrix::<f64, 6, 6>::identity();
    let mut sum = term;
    for k in 1..=12 {
        term = term * scaled / f64::from(k);
        sum += term;
    }
    for _ in 0..squarings {
        sum = sum * sum;
    }
    sum
}

#[cfg(test)]
mod tests;
