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

use super::relaxed_hover::RelaxedHover;
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
    air_density: f64,
}

impl Model<'_> {
    /// `ẋ` at state `x` under input `u`.
    fn derivative(&self, x: &State, u: &Vector2<f64>) -> State {
        let a = self.airframe;
        let n = self.hover.axis_frd;
        let w = n * self.hover.spin_rad_s + self.across[0] * x[0] + self.across[1] * x[1];
        let d = (n + self.across[0] * x[2] + self.across[1] * x[3]).normalize();
        let f = self.allocation * (self.trim + Vector3::new(0.0, u[0], u[1]));
        let mut moment = Vector3::zeros();
        let mut momentum_z = 0.0;
        for (k, &i) in self.working.iter().enumerate() {
            let r = &a.rotors[i];
            let p = &r.position_frd_m;
            moment += Vector3::new(-p.y, p.x, r.spin.sign() * r.yaw_moment_per_thrust_m()) * f[k];
            momentum_z -=
                r.spin.sign() * r.inertia_kg_m2 * r.speed_for_thrust_rad_s(self.air_density, f[k]);
        }
        let h = Vector3::new(0.0, 0.0, momentum_z);
        let damping = Vector3::from(a.drag.rotational_n_m_s_rad).component_mul(&w);
        let j = a.inertia_kg_m2;
        let w_dot = j.try_inverse().unwrap_or_else(Matrix3::identity)
            * (moment - damping - w.cross(&(j * w + h)));
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
    /// The controller of `hover` for `airframe`, its loop at `rate_hz`, in air of `air_density`.
    pub fn new(
        airframe: &Airframe,
        hover: RelaxedHover,
        rate_hz: f64,
        air_density: f64,
    ) -> Result<Self, ReducedAttitudeError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(ReducedAttitudeError::Rate(rate_hz));
        }
        let mut working = [0; 3];
        for (k, i) in (0..airframe.rotors.len())
            .filter(|&i| i != hover.lost)
            .take(3)
            .enumerate()
        {
            working[k] = i;
        }
        let columns = working.map(|i| {
            let p = airframe.rotors[i].position_frd_m;
            Vector3::new(1.0, -p.y, p.x)
        });
        let allocation = Matrix3::from_columns(&columns)
            .try_inverse()
            .ok_or(ReducedAttitudeError::NoAllocation)?;
        let thrusts = Vector3::from(working.map(|i| hover.thrust_n[i]));
        let trim = Matrix3::from_columns(&columns) * thrusts;
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
            air_density,
        };
        let gain = lqr_gain(&model, 1.0 / rate_hz)?;
        let max_thrust_n = working.map(|i| {
            let r = &airframe.rotors[i];
            r.thrust_n(air_density, r.max_speed_rad_s)
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
    /// primary axis toward `up_ned` (a unit vector, the direction the thrust should lift in)
    /// with `lift_n` newtons along it, for the body at attitude `q` turning at `rate_frd`.
    pub fn update(
        &self,
        up_ned: &Vector3<f64>,
        lift_n: f64,
        q: &UnitQuaternion<f64>,
        rate_frd: &Vector3<f64>,
    ) -> Vec<f64> {
        let n = self.hover.axis_frd;
        let d = q.inverse_transform_vector(up_ned);
        let e = d - n;
        let rate_error = rate_frd - n * self.hover.spin_rad_s;
        let x = State::new(
            rate_error.dot(&self.across[0]),
            rate_error.dot(&self.across[1]),
            e.dot(&self.across[0]),
            e.dot(&self.across[1]),
        );
        let u = -self.gain * x;
        // The lift along the axis is the thrust's component on it (thrust along −z).
        let collective = lift_n.max(0.0) / (-n.z).max(0.1);
        let f = self.allocation * Vector3::new(collective, self.trim.y + u[0], self.trim.z + u[1]);
        let mut out = vec![0.0; self.hover.thrust_n.len()];
        for (k, &i) in self.working.iter().enumerate() {
            out[i] = f[k].clamp(0.0, self.max_thrust_n[k]);
        }
        out
    }
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
    // Zero-order hold, to second order in dt.
    let eye = SMatrix::<f64, 4, 4>::identity();
    let ad = eye + a * dt_s + a * a * (dt_s * dt_s / 2.0);
    let bd = (eye * dt_s + a * (dt_s * dt_s / 2.0)) * b;
    // Weights: the axis direction (rad²) far above the rates ((rad/s)²); the moments (N·m)²
    // cheap.
    let q = SMatrix::<f64, 4, 4>::from_diagonal(&State::new(0.05, 0.05, 50.0, 50.0));
    let r = Matrix2::identity() * 1.0;
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
            return Ok(gain);
        }
    }
    Err(ReducedAttitudeError::NoGain)
}

#[cfg(test)]
mod tests;
