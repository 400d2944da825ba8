//! The relaxed hover of a quadrotor that lost a rotor (Mueller & D'Andrea, ICRA 2014; IJRR
//! 2015): the body spins at a constant rate `ω̄` about a primary axis `n̄` fixed in the body and
//! pointing up, and the thrust of the three working rotors, tilted from `n̄`, holds the weight
//! on average while its tilting moments balance the spinning body's gyroscopic moments. The yaw
//! moment the rotors leave unbalanced is what spins it; the body's rotational drag sets the rate.
//!
//! Solved here from the airframe alone (rotor positions and spins, `K_T`, `K_Q`, the rotors'
//! inertia, the body's inertia and rotational damping), so any quad airframe has its own. In the
//! body frame (FRD), with the working rotors' thrusts `f`, the body rate `ω = ω̄ n̄`, the
//! rotors' angular momentum `h(f)` and the damping `D`:
//!
//! - moments: `B_M f − D ω − ω × (J ω + h) = 0` (Castillo (58), Mueller (2));
//! - weight: the thrust along `n̄` is the weight, `−(Σ f) n̄_z = m g` (thrust along −z);
//! - `|n̄| = 1`.
//!
//! That leaves two degrees of freedom, chosen as Mueller's: the rotor opposite the lost one makes
//! `share` times the mean of the other two (Mueller's `ρ`), and `n̄` stays in the vertical plane
//! through the lost rotor's diagonal. A larger `share` spins the body slower (the yaw moments of
//! the two rotor pairs come closer to balance) but tilts `n̄` further from the thrust.

use airframe::Airframe;
use nalgebra::{DMatrix, DVector, Vector3};

/// A relaxed-hover equilibrium.
#[derive(Debug, Clone, PartialEq)]
pub struct RelaxedHover {
    /// The primary axis `n̄` (FRD, unit), up in hover: the body spins about it.
    pub axis_frd: Vector3<f64>,
    /// Spin rate `ω̄` about `n̄` (rad/s, signed): the body rate is `ω̄ n̄`.
    pub spin_rad_s: f64,
    /// Each rotor's thrust (N) in the airframe's order; zero for the lost one.
    pub thrust_n: Vec<f64>,
    /// The lost rotor.
    pub lost: usize,
    /// The rotor opposite it (the farthest).
    pub opposite: usize,
    /// The opposite rotor's thrust over the mean of the other two.
    pub share: f64,
    /// The air density it was solved for (kg/m³).
    pub air_density: f64,
}

impl RelaxedHover {
    /// Angle between `n̄` and the thrust axis (body up, −z), deg.
    pub fn tilt_deg(&self) -> f64 {
        (-self.axis_frd.z).clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// Why no equilibrium was found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RelaxedHoverError {
    /// Only a quadrotor's single loss is solved here.
    #[error("a relaxed hover is solved for a quadrotor that lost one rotor, not {rotors} rotors")]
    NotAQuad {
        /// Rotors of the airframe.
        rotors: usize,
    },
    /// The lost rotor's index is not the airframe's.
    #[error("rotor {0} is not one of the airframe's")]
    NoSuchRotor(usize),
    /// `share` outside [0, 4].
    #[error("the opposite rotor's share must be within [0, 4], got {0}")]
    Share(f64),
    /// The air density is not a positive number.
    #[error("the air density must be positive, got {0} kg/m³")]
    AirDensity(f64),
    /// The equations have no solution from any start tried.
    #[error("no relaxed hover: the equations did not converge")]
    NoSolution,
    /// No share keeps the spin under the limit asked.
    #[error(
        "no relaxed hover spins under {limit_rad_s:.1} rad/s: the least found is {least_rad_s:.1} rad/s"
    )]
    SpinLimit {
        /// The limit asked (rad/s).
        limit_rad_s: f64,
        /// The slowest spin of the shares tried (rad/s).
        least_rad_s: f64,
    },
    /// A solution that asks a rotor for negative thrust or more than its most.
    #[error("the relaxed hover needs rotor {rotor} at {thrust_n:.2} N, outside 0 to {max_n:.2} N")]
    BeyondRotor {
        /// Rotor index.
        rotor: usize,
        /// Thrust needed (N).
        thrust_n: f64,
        /// The rotor's largest thrust (N).
        max_n: f64,
    },
}

/// The equations of the relaxed hover of `airframe` without rotor `lost`.
struct Equations<'a> {
    airframe: &'a Airframe,
    /// The three working rotors; the last is the one opposite the lost rotor.
    working: [usize; 3],
    /// Unit vector (FRD, in the rotors' plane) normal to the vertical plane through the lost
    /// rotor's diagonal: `n̄ · across = 0` keeps the axis in that plane.
    across: Vector3<f64>,
    share: f64,
    air_density: f64,
}

impl Equations<'_> {
    /// Residuals at `x = [f_a, f_b, f_o, n̄_x, n̄_y, n̄_z, ω̄]`, each scaled to about one for a
    /// unit error (moments by the weight times the arm, thrust by the weight).
    fn residual(&self, x: &DVector<f64>) -> DVector<f64> {
        let a = self.airframe;
        let n = Vector3::new(x[3], x[4], x[5]);
        let moment = net_torque(
            a,
            &self.working,
            &[x[0], x[1], x[2]],
            &(n * x[6]),
            self.air_density,
        );
        let weight = a.weight_n();
        let arm = arm_m(a);
        let total: f64 = x.rows(0, 3).sum();
        DVector::from_vec(vec![
            moment.x / (weight * arm),
            moment.y / (weight * arm),
            moment.z / (weight * arm),
            (-total * n.z - weight) / weight,
            n.norm_squared() - 1.0,
            (x[2] - self.share * 0.5 * (x[0] + x[1])) / weight,
            n.dot(&self.across),
        ])
    }

    /// Newton's method with a numerical Jacobian and a halving step, from `x`.
    fn solve_from(&self, mut x: DVector<f64>) -> Option<DVector<f64>> {
        let mut r = self.residual(&x);
        for _ in 0..60 {
            if r.norm() < 1e-11 {
                return Some(x);
            }
            let mut jac = DMatrix::zeros(7, 7);
            for j in 0..7 {
                let h = 1e-7 * x[j].abs().max(1.0);
                let (mut up, mut down) = (x.clone(), x.clone());
                up[j] += h;
                down[j] -= h;
                jac.set_column(
                    j,
                    &((self.residual(&up) - self.residual(&down)) / (2.0 * h)),
                );
            }
            let step = jac.lu().solve(&(-&r))?;
            let mut scale = 1.0;
            loop {
                let next = &x + &step * scale;
                let rn = self.residual(&next);
                if !rn.norm().is_finite() {
                    return None;
                }
                if rn.norm() < r.norm() || scale < 1e-4 {
                    x = next;
                    r = rn;
                    break;
                }
                scale *= 0.5;
            }
        }
        (r.norm() < 1e-9).then_some(x)
    }
}

/// Mean distance of the rotors from the centre (m).
pub(crate) fn arm_m(airframe: &Airframe) -> f64 {
    let rotors = &airframe.rotors;
    let sum: f64 = rotors.iter().map(|r| r.position_frd_m.xy().norm()).sum();
    (sum / rotors.len().max(1) as f64).max(1e-3)
}

/// The torque on the body (FRD, N·m) of the rotors `working` making `thrusts_n`, the body
/// turning at `rate_frd`: the thrusts' moments and the rotors' reaction torques (Lewis
/// (4.31)–(4.34)), less the damping and the gyroscopic torque of the body and its rotors
/// (Castillo (58)), as the simulator's powertrain and body have them.
pub(crate) fn net_torque(
    airframe: &Airframe,
    working: &[usize],
    thrusts_n: &[f64],
    rate_frd: &Vector3<f64>,
    air_density: f64,
) -> Vector3<f64> {
    let mut moment = Vector3::zeros();
    let mut momentum_z = 0.0;
    for (&i, &f) in working.iter().zip(thrusts_n) {
        let r = &airframe.rotors[i];
        let p = &r.position_frd_m;
        // Thrust along −z at the hub; the reaction to the rotor's drag torque.
        moment += Vector3::new(-p.y, p.x, r.spin.sign() * r.yaw_moment_per_thrust_m()) * f;
        // A ccw rotor spins about −z.
        momentum_z -= r.spin.sign() * r.inertia_kg_m2 * r.speed_for_thrust_rad_s(air_density, f);
    }
    let damping = Vector3::from(airframe.drag.rotational_n_m_s_rad).component_mul(rate_frd);
    let h = Vector3::new(0.0, 0.0, momentum_z);
    moment - damping - rate_frd.cross(&(airframe.inertia_kg_m2 * rate_frd + h))
}

/// Refuses what `solve` cannot be asked: not a quad, no such rotor, a share outside [0, 4], an
/// air density not positive.
fn check_request(
    airframe: &Airframe,
    lost: usize,
    share: f64,
    air_density: f64,
) -> Result<(), RelaxedHoverError> {
    let rotors = &airframe.rotors;
    if rotors.len() != 4 {
        return Err(RelaxedHoverError::NotAQuad {
            rotors: rotors.len(),
        });
    }
    if lost >= rotors.len() {
        return Err(RelaxedHoverError::NoSuchRotor(lost));
    }
    if !(0.0..=4.0).contains(&share) {
        return Err(RelaxedHoverError::Share(share));
    }
    if !(air_density.is_finite() && air_density > 0.0) {
        return Err(RelaxedHoverError::AirDensity(air_density));
    }
    Ok(())
}

/// The relaxed hover of the quad `airframe` without rotor `lost`, the opposite rotor making
/// `share` times the mean of the other two, in air of `air_density` (kg/m³).
pub fn solve(
    airframe: &Airframe,
    lost: usize,
    share: f64,
    air_density: f64,
) -> Result<RelaxedHover, RelaxedHoverError> {
    check_request(airframe, lost, share, air_density)?;
    let rotors = &airframe.rotors;
    let at = |i: usize| rotors[i].position_frd_m;
    let opposite = (0..4)
        .filter(|&i| i != lost)
        .max_by(|&i, &j| {
            let (di, dj) = ((at(i) - at(lost)).norm(), (at(j) - at(lost)).norm());
            di.total_cmp(&dj)
        })
        .unwrap_or(lost);
    let mut others = (0..4).filter(|&i| i != lost && i != opposite);
    let (Some(a), Some(b)) = (others.next(), others.next()) else {
        return Err(RelaxedHoverError::NoSolution);
    };
    let diagonal = Vector3::new(
        at(opposite).x - at(lost).x,
        at(opposite).y - at(lost).y,
        0.0,
    );
    let along = diagonal.try_normalize(1e-9).unwrap_or_else(Vector3::x);
    let eq = Equations {
        airframe,
        working: [a, b, opposite],
        across: Vector3::z().cross(&along),
        share,
        air_density,
    };
    // Starts: the weight shared as `share` asks, the axis tilted toward the opposite rotor (or
    // away), the spin the yaw moment would reach against the damping alone.
    let weight = airframe.weight_n();
    let yaw_damping = airframe.drag.rotational_n_m_s_rad[2].max(1e-4);
    let max_n = eq
        .working
        .map(|i| rotors[i].thrust_n(air_density, rotors[i].max_speed_rad_s));
    // A rotor the solution leaves idle may come out a rounding error below zero.
    let beyond = |x: &DVector<f64>| {
        (0..3)
            .find(|&k| !(-1e-9..=max_n[k]).contains(&x[k]))
            .map(|k| RelaxedHoverError::BeyondRotor {
                rotor: eq.working[k],
                thrust_n: x[k],
                max_n: max_n[k],
            })
    };
    let mut refusal = RelaxedHoverError::NoSolution;
    let mut solution = None;
    for tilt in [0.1_f64, -0.1, 0.4, -0.4] {
        let f = weight / ((2.0 + share) * tilt.cos());
        let thrusts = [f, f, share * f];
        let yaw: f64 = eq
            .working
            .iter()
            .zip(thrusts)
            .map(|(&i, t)| rotors[i].spin.sign() * rotors[i].yaw_moment_per_thrust_m() * t)
            .sum();
        let n = along * tilt.sin() - Vector3::z() * tilt.cos();
        let spin = yaw / yaw_damping / n.z;
        let x0 = DVector::from_vec(vec![f, f, share * f, n.x, n.y, n.z, spin]);
        let Some(x) = eq.solve_from(x0).filter(|x| x[5] < 0.0) else {
            continue;
        };
        match beyond(&x) {
            Some(why) => refusal = why,
            None => {
                solution = Some(x);
                break;
            }
        }
    }
    let solution = solution.ok_or(refusal)?;
    let mut thrust_n = vec![0.0; 4];
    for (k, &i) in eq.working.iter().enumerate() {
        thrust_n[i] = solution[k].max(0.0);
    }
    Ok(RelaxedHover {
        axis_frd: Vector3::new(solution[3], solution[4], solution[5]),
        spin_rad_s: solution[6],
        thrust_n,
        lost,
        opposite,
        share,
        air_density,
    })
}

/// The relaxed hover that spins no faster than `max_spin_rad_s` with the least share for the
/// opposite rotor (the least tilt from the thrust): Mueller's `ρ` searched on [0, 4], in steps
/// of 0.05 then halved down to 0.001.
pub fn solve_within_spin(
    airframe: &Airframe,
    lost: usize,
    max_spin_rad_s: f64,
    air_density: f64,
) -> Result<RelaxedHover, RelaxedHoverError> {
    let fitting = |share: f64| {
        solve(airframe, lost, share, air_density)
            .ok()
            .filter(|h| h.spin_rad_s.abs() <= max_spin_rad_s)
    };
    let mut below = 0.0;
    for k in 0..=80 {
        let share = f64::from(k) * 0.05;
        if let Some(mut best) = fitting(share) {
            let mut above = share;
            while above - below > 1e-3 {
                let mid = 0.5 * (above + below);
                match fitting(mid) {
                    Some(h) => {
                        above = mid;
                        best = h;
                    }
                    None => below = mid,
                }
            }
            return Ok(best);
        }
        below = share;
    }
    let least_rad_s = (0..=80)
        .filter_map(|k| solve(airframe, lost, f64::from(k) * 0.05, air_density).ok())
        .map(|h| h.spin_rad_s.abs())
        .min_by(f64::total_cmp)
        .ok_or(RelaxedHoverError::NoSolution)?;
    Err(RelaxedHoverError::SpinLimit {
        limit_rad_s: max_spin_rad_s,
        least_rad_s,
    })
}

#[cfg(test)]
mod tests;
