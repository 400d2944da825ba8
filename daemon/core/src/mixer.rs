//! Control allocation: a body wrench request → per-rotor thrust → normalised motor commands.
//!
//! The effectiveness matrix B (4 × N) maps rotor thrusts to `[F_z, M_x, M_y, M_z]` (FRD), built
//! here from the airframe geometry: column i is `[−1, −y_i, x_i, ±K_Q D/K_T]` (Lewis (4.31),
//! (4.34); docs/conventions.md signs). Allocation is the pseudo-inverse `T = B⁺ w`, which for the
//! "+" quad is Lewis's closed-form inverse (4.35)–(4.38).
//!
//! Saturation (Lewis section 7 asks which axis to give up): roll and pitch first, then collective
//! thrust, then yaw. The roll/pitch thrust pattern is kept whole (scaled down only if it cannot
//! fit at any collective), the collective is shifted as little as possible to make room, and yaw
//! gets whatever margin remains. What could not be produced is reported so the controllers stop
//! integrating it. Thrust becomes rotor speed by Lewis (4.30) and a command by the inverse motor
//! curve (6.12) with `f(u, V) = u V`.

use airframe::{Airframe, MAX_ROTORS, RotorSpec};
use nalgebra::{DMatrix, Vector3};

/// What the controllers ask for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrenchRequest {
    /// Collective thrust along body −z (N, positive = up).
    pub thrust_n: f64,
    /// Body moments (N·m, FRD).
    pub torque_frd_n_m: Vector3<f64>,
}

/// The conditions of the moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MixerInput {
    /// The request.
    pub request: WrenchRequest,
    /// Battery voltage under load (V).
    pub battery_v: f64,
    /// Air density (kg/m³).
    pub air_density: f64,
}

/// The allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MixerOutput {
    /// Normalised motor commands ∈ [0, 1] for `HIL_ACTUATOR_CONTROLS` / the ESCs.
    pub commands: [f64; MAX_ROTORS],
    /// Allocated thrust per rotor (N).
    pub thrust_n: [f64; MAX_ROTORS],
    /// Rotor speed set-points (rad/s), Lewis (4.30).
    pub speed_rad_s: [f64; MAX_ROTORS],
    /// The wrench these thrusts produce: collective (N, up) and moments (N·m).
    pub achieved: WrenchRequest,
    /// Request minus achieved: what saturation left out (feed to anti-windup).
    pub unallocated: WrenchRequest,
    /// Roll/pitch pattern scale actually applied (1 = whole).
    pub tilt_scale: f64,
    /// Fraction of the requested yaw moment applied.
    pub yaw_scale: f64,
}

/// The mixer of one airframe.
#[derive(Debug, Clone)]
pub struct Mixer {
    rotors: Vec<RotorSpec>,
    b: DMatrix<f64>,
    pinv: DMatrix<f64>,
    failed: [bool; MAX_ROTORS],
    yaw_controllable: bool,
}

/// Why a mixer cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MixerError {
    /// Rotors left cannot control thrust, roll and pitch.
    #[error("the working rotors cannot control thrust, roll and pitch (rank {0} < 3)")]
    Uncontrollable(usize),
}

impl Mixer {
    /// The mixer for `airframe` with every rotor working.
    pub fn new(airframe: &Airframe) -> Result<Self, MixerError> {
        let n = airframe.rotors.len();
        let b = DMatrix::from_fn(4, n, |row, i| {
            let r = &airframe.rotors[i];
            match row {
                0 => -1.0,
                1 => -r.position_frd_m.y,
                2 => r.position_frd_m.x,
                _ => r.spin.sign() * r.k_q * r.diameter_m / r.k_t, // c = K_Q D / K_T (4.34)
            }
        });
        let mut m = Self {
            rotors: airframe.rotors.clone(),
            pinv: DMatrix::zeros(n, 4),
            b,
            failed: [false; MAX_ROTORS],
            yaw_controllable: true,
        };
        m.rebuild()?;
        Ok(m)
    }

    /// The effectiveness matrix B (thrusts → `[F_z, M_x, M_y, M_z]`).
    pub fn effectiveness(&self) -> &DMatrix<f64> {
        &self.b
    }

    /// The allocation matrix in use (N × 4), zero rows for failed rotors.
    pub fn allocation(&self) -> &DMatrix<f64> {
        &self.pinv
    }

    /// Whether yaw is still controlled (false after failures that leave rank 3).
    pub fn yaw_controllable(&self) -> bool {
        self.yaw_controllable
    }

    /// Marks rotors failed (true) or working, and recomputes the allocation without the failed
    /// ones; if the rest cannot hold yaw, yaw is given up and thrust, roll and pitch kept.
    pub fn set_failed(&mut self, failed: &[bool]) -> Result<(), MixerError> {
        for (f, &x) in self.failed.iter_mut().zip(failed) {
            *f = x;
        }
        self.rebuild()
    }

    fn rebuild(&mut self) -> Result<(), MixerError> {
        let n = self.rotors.len();
        let mut masked = self.b.clone();
        for i in 0..n {
            if self.failed[i] {
                masked.column_mut(i).fill(0.0);
            }
        }
        let rank4 = masked.rank(1e-9);
        self.yaw_controllable = rank4 == 4;
        let rows = if self.yaw_controllable { 4 } else { 3 };
        let sub = masked.rows(0, rows).into_owned();
        let rank = sub.rank(1e-9);
        if rank < 3 {
            return Err(MixerError::Uncontrollable(rank));
        }
        // Full row rank: the pseudo-inverse is the right inverse Bᵀ(BBᵀ)⁻¹, exact to rounding
        // (nalgebra's iterative SVD is only good to ~1e-9 here).
        let gram = &sub * sub.transpose();
        let p = sub.transpose() * gram.try_inverse().ok_or(MixerError::Uncontrollable(rank))?;
        self.pinv = DMatrix::zeros(n, 4);
        self.pinv.columns_mut(0, rows).copy_from(&p);
        Ok(())
    }

    /// Rotor `i`'s top thrust (N) at air density `rho` and battery voltage `v_batt`: zero when
    /// failed, else at the lower of its top speed and what the voltage drives.
    pub fn max_thrust(&self, i: usize, rho: f64, v_batt: f64) -> f64 {
        if self.failed[i] {
            return 0.0;
        }
        let r = &self.rotors[i];
        let top = r.max_speed_rad_s.min(r.motor_gain_rad_s_per_v * v_batt);
        r.thrust_n(rho, top)
    }

    /// Allocates one request. Allocation-free: fixed-size arrays throughout.
    pub fn mix(&self, input: &MixerInput) -> MixerOutput {
        let n = self.rotors.len();
        let rho = input.air_density.max(0.1);
        let req = &input.request;
        let sanitize = |x: f64| if x.is_finite() { x } else { 0.0 };
        let thrust_req = sanitize(req.thrust_n).max(0.0);
        let t = req.torque_frd_n_m.map(sanitize);
        // Thrust pattern per unit of each wrench component (F_z = −thrust), and the limits.
        let mut c_f = [0.0; MAX_ROTORS];
        let mut rp = [0.0; MAX_ROTORS];
        let mut c_yaw = [0.0; MAX_ROTORS];
        let mut t_max = [0.0; MAX_ROTORS];
        for i in 0..n {
            c_f[i] = -self.pinv[(i, 0)];
            rp[i] = self.pinv[(i, 1)] * t.x + self.pinv[(i, 2)] * t.y;
            c_yaw[i] = self.pinv[(i, 3)];
            t_max[i] = self.max_thrust(i, rho, input.battery_v);
        }
        let working = |i: usize| !self.failed[i] && c_f[i] > 1e-12;
        // Range of collective s with 0 ≤ α·rp + s·c_F ≤ T_max on every working rotor.
        let fits = |alpha: f64| -> Option<(f64, f64)> {
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for i in (0..n).filter(|&i| working(i)) {
                lo = lo.max(-alpha * rp[i] / c_f[i]);
                hi = hi.min((t_max[i] - alpha * rp[i]) / c_f[i]);
            }
            (lo <= hi).then_some((lo, hi))
        };
        // 1. Roll/pitch whole if possible; otherwise scaled down (bisection) until it fits.
        let mut tilt_scale = 1.0;
        let (lo, hi) = match fits(1.0) {
            Some(r) => r,
            None => {
                let (mut a, mut b) = (0.0, 1.0);
                for _ in 0..24 {
                    let mid = 0.5 * (a + b);
                    if fits(mid).is_some() {
                        a = mid
                    } else {
                        b = mid
                    }
                }
                tilt_scale = a;
                fits(a).unwrap_or((0.0, 0.0))
            }
        };
        // 2. The collective closest to the request that leaves the roll/pitch pattern whole.
        let collective = thrust_req.clamp(lo, hi);
        let mut thrust = [0.0; MAX_ROTORS];
        for i in 0..n {
            thrust[i] = tilt_scale * rp[i] + collective * c_f[i];
        }
        // 3. Yaw with the margin left, never moving the collective.
        let mut yaw_scale: f64 = if self.yaw_controllable { 1.0 } else { 0.0 };
        if t.z != 0.0 && self.yaw_controllable {
            for i in 0..n {
                let d = c_yaw[i] * t.z;
                if self.failed[i] || d.abs() < 1e-15 {
                    continue;
                }
                let room = if d > 0.0 {
                    t_max[i] - thrust[i]
                } else {
                    thrust[i]
                };
                yaw_scale = yaw_scale.min((room / d.abs()).max(0.0));
            }
            for i in 0..n {
                thrust[i] += c_yaw[i] * t.z * yaw_scale;
            }
        }
        let request = WrenchRequest {
            thrust_n: thrust_req,
            torque_frd_n_m: t,
        };
        let mut out = self.output(&thrust, &t_max, &request, rho, input.battery_v);
        out.tilt_scale = tilt_scale;
        out.yaw_scale = yaw_scale;
        out
    }

    /// The output for thrusts chosen elsewhere (the reduced-attitude controller of a quad
    /// spinning on three rotors): each within its rotor's range, then speeds, commands and the
    /// wrench they make, as [`Mixer::mix`] does with its own.
    pub fn for_thrusts(&self, thrust_n: &[f64], input: &MixerInput) -> MixerOutput {
        let rho = input.air_density.max(0.1);
        let mut thrust = [0.0; MAX_ROTORS];
        let mut t_max = [0.0; MAX_ROTORS];
        for i in 0..self.rotors.len() {
            t_max[i] = self.max_thrust(i, rho, input.battery_v);
            thrust[i] = thrust_n
                .get(i)
                .copied()
                .filter(|x| x.is_finite())
                .unwrap_or(0.0);
        }
        let mut out = self.output(&thrust, &t_max, &input.request, rho, input.battery_v);
        out.yaw_scale = 0.0;
        out
    }

    /// Thrusts (clamped to `[0, t_max]`, zero on failed rotors) → speeds (Lewis (4.30)),
    /// commands (Lewis (6.12): `u = f⁻¹(Ω/a, V)` with `f(u, V) = u V`) and the wrench made.
    fn output(
        &self,
        thrust: &[f64; MAX_ROTORS],
        t_max: &[f64; MAX_ROTORS],
        request: &WrenchRequest,
        rho: f64,
        battery_v: f64,
    ) -> MixerOutput {
        let mut out = MixerOutput {
            commands: [0.0; MAX_ROTORS],
            thrust_n: [0.0; MAX_ROTORS],
            speed_rad_s: [0.0; MAX_ROTORS],
            achieved: WrenchRequest {
                thrust_n: 0.0,
                torque_frd_n_m: Vector3::zeros(),
            },
            unallocated: WrenchRequest {
                thrust_n: 0.0,
                torque_frd_n_m: Vector3::zeros(),
            },
            tilt_scale: 1.0,
            yaw_scale: 1.0,
        };
        let mut w = [0.0; 4];
        for i in 0..self.rotors.len() {
            let ti = if self.failed[i] {
                0.0
            } else {
                thrust[i].clamp(0.0, t_max[i])
            };
            out.thrust_n[i] = ti;
            let r = &self.rotors[i];
            out.speed_rad_s[i] = r.speed_for_thrust_rad_s(rho, ti);
            out.commands[i] = (out.speed_rad_s[i]
                / (r.motor_gain_rad_s_per_v * battery_v.max(1.0)))
            .clamp(0.0, 1.0);
            for (k, wk) in w.iter_mut().enumerate() {
                *wk += self.b[(k, i)] * ti;
            }
        }
        out.achieved = WrenchRequest {
            thrust_n: -w[0],
            torque_frd_n_m: Vector3::new(w[1], w[2], w[3]),
        };
        out.unallocated = WrenchRequest {
            thrust_n: request.thrust_n - out.achieved.thrust_n,
            torque_frd_n_m: request.torque_frd_n_m - out.achieved.torque_frd_n_m,
        };
        out
    }
}

#[cfg(test)]
mod tests;
