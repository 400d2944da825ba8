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
use airframe::{Airframe, MAX_ROTORS};
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
    /// No moments hold the axis still at this spin (rad/s) on the way up to the hover's.
    #[error("no trim holds the axis at a spin of {0:.1} rad/s")]
    NoTrim(f64),
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
    /// `[Σf, M_x, M_y]` to the working rotors' thrusts, and back.
    allocation: Matrix3<f64>,
    to_wrench: Matrix3<f64>,
    /// The mean arm (m).
    arm_m: f64,
    /// Two unit vectors across `n̄` (FRD): the coordinates of `d − n̄`.
    across: [Vector3<f64>; 2],
    /// The gains and trims from no spin (index 0) to the hover's (the last), evenly spaced.
    schedule: Vec<Scheduled>,
    max_thrust_n: [f64; 3],
}

/// The LQR's weight on the rates across the axis ((rad/s)⁻²) with no spin and at the hover's,
/// geometric in between (the axis's own is 50 rad⁻²).
const RATE_WEIGHT: (f64, f64) = (5.0, 0.05);

/// Spins between none and the hover's at which the loop is linearised (intervals).
const SCHEDULE_INTERVALS: usize = 8;

/// The loop at one spin about `n̄`: the trim that holds the axis still there and the LQR gain
/// about it.
#[derive(Debug, Clone)]
struct Scheduled {
    /// `[Σf, M_x, M_y]` that leave no turning across `n̄` at this spin.
    trim: Vector3<f64>,
    gain: Gain,
}

/// The rotational model about the relaxed hover's axis at one spin, for its linearisation.
#[derive(Clone, Copy)]
struct Model<'a> {
    airframe: &'a Airframe,
    working: [usize; 3],
    allocation: Matrix3<f64>,
    trim: Vector3<f64>,
    hover: &'a RelaxedHover,
    /// The spin about `n̄` (rad/s).
    spin: f64,
    across: [Vector3<f64>; 2],
    inertia_inverse: Matrix3<f64>,
}

impl Model<'_> {
    /// `ẋ` at state `x` under input `u`.
    fn derivative(&self, x: &State, u: &Vector2<f64>) -> State {
        let n = self.hover.axis_frd;
        let w = n * self.spin + self.across[0] * x[0] + self.across[1] * x[1];
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

    /// The same model at `spin`, its moments trimmed (Newton's method) so that the axis does
    /// not turn there: the spin up from none is not an equilibrium (the yaw torque speeds it),
    /// but across the axis the body can be held still at every spin on the way.
    fn at_spin(&self, spin: f64) -> Option<Self> {
        let mut m = Self { spin, ..*self };
        for _ in 0..50 {
            let r = m.derivative(&State::zeros(), &Vector2::zeros());
            let residual = Vector2::new(r[0], r[1]);
            if residual.norm() < 1e-9 {
                return Some(m);
            }
            let h = 1e-6;
            let column = |j: usize| {
                let mut du = Vector2::zeros();
                du[j] = h;
                let (a, b) = (
                    m.derivative(&State::zeros(), &du),
                    m.derivative(&State::zeros(), &-du),
                );
                Vector2::new(a[0] - b[0], a[1] - b[1]) / (2.0 * h)
            };
            let jacobian = Matrix2::from_columns(&[column(0), column(1)]);
            let step = jacobian.try_inverse()? * residual;
            m.trim.y -= step.x;
            m.trim.z -= step.y;
        }
        None
    }
}

/// The spin a quad on three rotors is held within (rad/s): 80 % of the ±2000°/s range of the
/// common MEMS gyro, so that the wobble on top of it stays inside the range.
pub const MAX_SPIN_RAD_S: f64 = 0.8 * 2000.0 * std::f64::consts::PI / 180.0;

/// The loop rate the gains are computed for (Hz): the simulator's sample rate. A board whose
/// loop runs faster samples the same law more often.
pub const LOOP_RATE_HZ: f64 = 250.0;

impl ReducedAttitude {
    /// The controller of `airframe` without rotor `lost`, about its relaxed hover in sea-level
    /// air that spins within [`MAX_SPIN_RAD_S`], at [`LOOP_RATE_HZ`]; `None` when the airframe has
    /// no such hover or no stable loop (not a quad, or rotors too weak).
    pub fn for_lost_rotor(airframe: &Airframe, lost: usize) -> Option<Self> {
        let hover = super::relaxed_hover::solve_within_spin(
            airframe,
            lost,
            MAX_SPIN_RAD_S,
            crate::SEA_LEVEL_AIR_DENSITY_KG_M3,
        )
        .ok()?;
        Self::new(airframe, hover, LOOP_RATE_HZ).ok()
    }

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
            spin: hover.spin_rad_s,
            across,
            inertia_inverse,
        };
        let still = model.derivative(&State::zeros(), &Vector2::zeros()).norm();
        if still.is_nan() || still >= 1e-3 {
            return Err(ReducedAttitudeError::NotAnEquilibrium(still));
        }
        // Mueller's LQR about the relaxed hover, and the same about the axis at lower spins
        // (scheduled on the spin measured): after a rotor stops the body spins up from none
        // over seconds, and a gain made for the full spin turns the moments the wrong way
        // (the gyroscopic coupling it counts on is not there yet).
        let mut schedule = Vec::with_capacity(SCHEDULE_INTERVALS + 1);
        for k in 0..=SCHEDULE_INTERVALS {
            let spin = hover.spin_rad_s * k as f64 / SCHEDULE_INTERVALS as f64;
            let at = if k == SCHEDULE_INTERVALS {
                model
            } else {
                model
                    .at_spin(spin)
                    .ok_or(ReducedAttitudeError::NoTrim(spin))?
            };
            // The rates across the axis damped hard at no spin (the rate a rotor's loss leaves
            // is what tips the body while it spins up), lightly at the full spin (where turning
            // the axis is a precession: a rate across it is how it moves).
            let rate_weight = RATE_WEIGHT.0
                * (RATE_WEIGHT.1 / RATE_WEIGHT.0).powf(k as f64 / SCHEDULE_INTERVALS as f64);
            schedule.push(Scheduled {
                trim: at.trim,
                gain: lqr_gain(&at, 1.0 / rate_hz, rate_weight)?,
            });
        }
        let max_thrust_n = working.map(|i| {
            let r = &airframe.rotors[i];
            r.thrust_n(hover.air_density, r.max_speed_rad_s)
        });
        Ok(Self {
            hover,
            working,
            allocation,
            to_wrench,
            arm_m: arm_m(airframe),
            across,
            schedule,
            max_thrust_n,
        })
    }

    /// The relaxed hover it flies about.
    pub fn hover(&self) -> &RelaxedHover {
        &self.hover
    }

    /// The hover's thrusts (N), the airframe's order.
    fn hover_thrusts(&self) -> [f64; MAX_ROTORS] {
        let mut out = [0.0; MAX_ROTORS];
        for (o, &t) in out.iter_mut().zip(&self.hover.thrust_n) {
            *o = t;
        }
        out
    }

    /// Each rotor's thrust (N, the airframe's order, zero for the lost one) that turns the
    /// primary axis toward `up_ned` (the direction the thrust should lift in) with `lift_n`
    /// newtons along it, for the body at attitude `q` turning at `rate_frd`, each rotor within
    /// its top thrust in sea-level air. Inputs that are not numbers hold the hover's own thrusts.
    pub fn update(
        &self,
        up_ned: &Vector3<f64>,
        lift_n: f64,
        q: &UnitQuaternion<f64>,
        rate_frd: &Vector3<f64>,
    ) -> [f64; MAX_ROTORS] {
        let mut top = [0.0; MAX_ROTORS];
        for (k, &i) in self.working.iter().enumerate() {
            top[i] = self.max_thrust_n[k];
        }
        self.update_within(up_ned, lift_n, q, rate_frd, &top)
    }

    /// [`ReducedAttitude::update`] with each rotor's top thrust now (N, the airframe's order:
    /// the mixer's, for the battery's voltage and the air's density), so that the moments keep
    /// their priority when the rotors are weaker than at sea level on a full pack.
    pub fn update_within(
        &self,
        up_ned: &Vector3<f64>,
        lift_n: f64,
        q: &UnitQuaternion<f64>,
        rate_frd: &Vector3<f64>,
        top_thrust_n: &[f64; MAX_ROTORS],
    ) -> [f64; MAX_ROTORS] {
        let finite = lift_n.is_finite()
            && rate_frd
                .iter()
                .chain(up_ned.iter())
                .chain(q.coords.iter())
                .all(|x| x.is_finite());
        let (Some(up), true) = (up_ned.try_normalize(1e-9), finite) else {
            return self.hover_thrusts();
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
        let (gain, trim) = self.scheduled(rate_frd.dot(&n));
        let u = -gain * x;
        // The lift along the axis is the thrust's component on it (thrust along −z).
        let collective = lift_n.max(0.0) / (-n.z).max(0.1);
        let moments = Vector3::new(0.0, trim.y + u[0], trim.z + u[1]);
        // A top that is not a number is the sea-level one.
        let top = Vector3::from_fn(|k, _| {
            let t = top_thrust_n[self.working[k]];
            if t.is_finite() {
                t.max(0.0)
            } else {
                self.max_thrust_n[k]
            }
        });
        let f = self.saturate(collective, &moments, &top);
        let mut out = [0.0; MAX_ROTORS];
        for (k, &i) in self.working.iter().enumerate() {
            out[i] = f[k];
        }
        out
    }

    /// The gain and trim at `spin` (rad/s about `n̄`): interpolated between the nearest two
    /// scheduled, held at either end beyond them.
    fn scheduled(&self, spin: f64) -> (Gain, Vector3<f64>) {
        let top = self.hover.spin_rad_s;
        let at = if top.abs() > 1e-9 {
            (spin / top).clamp(0.0, 1.0) * SCHEDULE_INTERVALS as f64
        } else {
            SCHEDULE_INTERVALS as f64
        };
        let k = (at.floor() as usize).min(SCHEDULE_INTERVALS - 1);
        let w = at - k as f64;
        let (a, b) = (&self.schedule[k], &self.schedule[k + 1]);
        (
            a.gain * (1.0 - w) + b.gain * w,
            a.trim * (1.0 - w) + b.trim * w,
        )
    }

    /// Thrusts for `collective` and `moments` within each rotor's range, the moments kept
    /// first: the bounded least-squares fit of `[Σf, M_x, M_y]`, the moments weighted
    /// [`MOMENT_PRIORITY`] times the collective (per mean-arm weight). Found by trying each
    /// rotor free, at zero or at its top (27 cases): a moment one way that only a negative
    /// thrust would give (after a rotor's loss the opposite rotor can only push) is given up
    /// alone, the rest of the moment kept.
    fn saturate(
        &self,
        collective: f64,
        moments: &Vector3<f64>,
        top: &Vector3<f64>,
    ) -> Vector3<f64> {
        let wanted = Vector3::new(collective, moments.y, moments.z);
        let to_wrench = self.to_wrench;
        let weight = Vector3::new(
            1.0,
            MOMENT_PRIORITY / self.arm_m,
            MOMENT_PRIORITY / self.arm_m,
        );
        let cost = |f: &Vector3<f64>| {
            (to_wrench * f - wanted)
                .component_mul(&weight)
                .norm_squared()
        };
        let unbounded = self.allocation * wanted;
        if (0..3).all(|i| (0.0..=top[i]).contains(&unbounded[i])) {
            return unbounded;
        }
        // Every rotor at zero fits: the fallback should no case be a number (never, with the
        // inputs checked).
        let mut best = (f64::INFINITY, Vector3::zeros());
        for case in 0..27usize {
            // Each rotor: 0 free, 1 at zero, 2 at its top.
            let state = [case % 3, case / 3 % 3, case / 9];
            let mut f = Vector3::zeros();
            let mut free = [false; 3];
            for i in 0..3 {
                match state[i] {
                    0 => free[i] = true,
                    1 => f[i] = 0.0,
                    _ => f[i] = top[i],
                }
            }
            if free.contains(&true) {
                // Weighted least squares over the free rotors: (W A)ᵀ(W A) x = (W A)ᵀ W r, the
                // fixed rotors' columns zero and their rows of the normal matrix the identity.
                let rest = (wanted - to_wrench * f).component_mul(&weight);
                let a = Matrix3::from_fn(|r, c| {
                    if free[c] {
                        to_wrench[(r, c)] * weight[r]
                    } else {
                        0.0
                    }
                });
                let mut normal = a.transpose() * a;
                for (i, &is_free) in free.iter().enumerate() {
                    if !is_free {
                        normal[(i, i)] = 1.0;
                    }
                }
                let Some(x) = normal.try_inverse().map(|inv| inv * a.transpose() * rest) else {
                    continue;
                };
                for i in (0..3).filter(|&i| free[i]) {
                    f[i] = x[i];
                }
                if (0..3).any(|i| free[i] && !(0.0..=top[i]).contains(&f[i])) {
                    continue;
                }
            }
            let c = cost(&f);
            if c < best.0 {
                best = (c, f);
            }
        }
        best.1
    }
}

/// How much more a moment's error counts than the collective's, per mean-arm weight.
const MOMENT_PRIORITY: f64 = 10.0;

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

/// The discrete LQR gain of `model` linearised about its hover, sampled every `dt_s`, the rates
/// across the axis weighted `rate_weight` ((rad/s)⁻², against 50 rad⁻² on the axis).
fn lqr_gain(model: &Model<'_>, dt_s: f64, rate_weight: f64) -> Result<Gain, ReducedAttitudeError> {
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
    // Weights: the axis direction and the rates across it as given; the moments in units of a
    // third of the weight on the mean arm.
    let q = SMatrix::<f64, 4, 4>::from_diagonal(&State::new(rate_weight, rate_weight, 50.0, 50.0));
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
