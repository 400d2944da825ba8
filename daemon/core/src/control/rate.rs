//! The rate (inner) loop, per body axis: body-rate reference → control input.
//!
//! **LADRC** (Castillo (69)–(73)): the axis is modelled as `ẋ₁ = x₂ + b̄ u`, `x₁ = Ω_b − Ω_r`,
//! with everything unknown (disturbances, coupling, the error in b̄) lumped into the extended
//! state x₂. A reduced-order ESO of bandwidth β estimates it (70):
//! `ż₂ = −β z₂ − β² x₁ − β b̄ u`, `x̂₂ = z₂ + β x₁`; the feedback (72) cancels it,
//! `u = (−k_d x₁ − x̂₂)/b̄`, so the error follows `ẋ₁* = −k_d x₁*` (71). A tracking differentiator
//! (73) smooths the reference with a bounded slope `|v̇₁| ≤ r`.
//!
//! **PID**: derivative on the measurement through a first-order low-pass, integrator frozen while
//! the mixer saturates in the direction that would wind it up, and a rate feed-forward.
//!
//! Both take the input actually applied after mixer saturation (`applied`), so neither the ESO nor
//! the integrator winds up against a limit. With `b̄ = 1/I` the input u is a torque (N·m).

/// LADRC parameters for one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LadrcParams {
    /// Estimate b̄ of the input gain (rad/s² per unit of u); `1/I` makes u a torque.
    pub b_bar: f64,
    /// Feedback gain k_d (1/s) of (71)–(72).
    pub k_d: f64,
    /// ESO bandwidth β (1/s) of (70); also the TD's derivative filter.
    pub beta: f64,
    /// TD slope limit r (rad/s²) of (73); infinite disables the TD.
    pub td_limit: f64,
    /// Largest |u|.
    pub u_max: f64,
}

/// LADRC state for one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LadrcAxis {
    /// Its parameters.
    pub params: LadrcParams,
    z2: f64,
    v1: f64,
    v2: f64,
    last_ref: f64,
    u_applied: f64,
    started: bool,
    /// The last TD control action u_TD, |u_TD| ≤ r.
    pub last_u_td: f64,
    /// The last disturbance estimate x̂₂ (rad/s²).
    pub disturbance: f64,
}

impl LadrcAxis {
    /// A fresh axis.
    pub fn new(params: LadrcParams) -> Self {
        Self {
            params,
            z2: 0.0,
            v1: 0.0,
            v2: 0.0,
            last_ref: 0.0,
            u_applied: 0.0,
            started: false,
            last_u_td: 0.0,
            disturbance: 0.0,
        }
    }

    /// Forgets the state (on disarm and mode change).
    pub fn reset(&mut self) {
        *self = Self::new(self.params);
    }

    /// The input the actuators really delivered for the last output (after mixer saturation).
    pub fn applied(&mut self, u: f64) {
        if u.is_finite() {
            self.u_applied = u;
        }
    }

    /// One step: reference `omega_ref`, measured rate `omega`, sample time `h`. Returns u.
    /// A reference that is not a number is taken as the last one: once in the observer's
    /// state it would stay there and the axis would never be controlled again.
    pub fn update(&mut self, omega_ref: f64, omega: f64, h: f64) -> f64 {
        let omega_ref = if omega_ref.is_finite() {
            omega_ref
        } else {
            self.last_ref
        };
        let p = &self.params;
        if !self.started {
            self.v1 = omega_ref;
            self.v2 = 0.0;
            self.last_ref = omega_ref;
        }
        // Tracking differentiator (73), with Ω̇_r by difference as the paper prescribes.
        let ref_rate = (omega_ref - self.last_ref) / h;
        self.last_ref = omega_ref;
        if p.td_limit.is_finite() {
            let u_td = (-p.k_d * (self.v1 - omega_ref) + self.v2).clamp(-p.td_limit, p.td_limit);
            self.v1 += h * u_td;
            let a = (-p.beta * h).exp();
            self.v2 = a * self.v2 + (1.0 - a) * ref_rate;
            self.last_u_td = u_td;
        } else {
            self.v1 = omega_ref;
        }
        let x1 = omega - self.v1; // (69)
        if !self.started {
            self.z2 = -p.beta * x1; // x̂₂(0) = 0
            self.started = true;
        } else {
            // RLESO (70), exact for the input held over the step.
            let a = (-p.beta * h).exp();
            let forcing = -p.beta * p.beta * x1 - p.beta * p.b_bar * self.u_applied;
            self.z2 = a * self.z2 + (1.0 - a) / p.beta * forcing;
        }
        let x2_hat = self.z2 + p.beta * x1;
        self.disturbance = x2_hat;
        let u = ((-p.k_d * x1 - x2_hat) / p.b_bar).clamp(-p.u_max, p.u_max); // (72)
        self.u_applied = u;
        u
    }
}

/// PID parameters for one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidParams {
    /// Proportional gain.
    pub k_p: f64,
    /// Integral gain (1/s).
    pub k_i: f64,
    /// Derivative gain (s), on the measurement.
    pub k_d: f64,
    /// Feed-forward gain on the rate reference.
    pub k_ff: f64,
    /// Derivative low-pass cut-off (Hz).
    pub d_cutoff_hz: f64,
    /// Largest |integral contribution|.
    pub i_limit: f64,
    /// Largest |u|.
    pub u_max: f64,
}

/// PID state for one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidAxis {
    /// Its parameters.
    pub params: PidParams,
    integral: f64,
    last_meas: Option<f64>,
    d_filtered: f64,
    saturated: f64,
}

impl PidAxis {
    /// A fresh axis.
    pub fn new(params: PidParams) -> Self {
        Self {
            params,
            integral: 0.0,
            last_meas: None,
            d_filtered: 0.0,
            saturated: 0.0,
        }
    }

    /// Forgets the state.
    pub fn reset(&mut self) {
        *self = Self::new(self.params);
    }

    /// The mixer's verdict on the last output: +1 saturated high, −1 low, 0 free.
    pub fn saturation(&mut self, direction: f64) {
        self.saturated = direction.signum() * (direction != 0.0) as u8 as f64;
    }

    /// One step. Returns u. A reference that is not a number flies zero error (it would stay
    /// in the integral for ever).
    pub fn update(&mut self, omega_ref: f64, omega: f64, h: f64) -> f64 {
        let p = &self.params;
        let omega_ref = if omega_ref.is_finite() {
            omega_ref
        } else {
            omega
        };
        let error = omega_ref - omega;
        // Anti-windup: integrate only when that does not push further into saturation.
        if !(self.saturated != 0.0 && error.signum() == self.saturated) {
            self.integral = (self.integral + p.k_i * error * h).clamp(-p.i_limit, p.i_limit);
        }
        // Derivative on the measurement (no kick on reference steps), low-passed.
        let raw_d = self.last_meas.map_or(0.0, |m| -(omega - m) / h);
        self.last_meas = Some(omega);
        let alpha = 1.0 - (-std::f64::consts::TAU * p.d_cutoff_hz * h).exp();
        self.d_filtered += alpha * (raw_d - self.d_filtered);
        (p.k_p * error + self.integral + p.k_d * self.d_filtered + p.k_ff * omega_ref)
            .clamp(-p.u_max, p.u_max)
    }
}

crate::params::param_group! {
    /// Rate loop: LADRC (Castillo (69)-(73)) or PID.
    RateGroup, "rate", RATE_META {
        /// 0: LADRC; 1: PID.
        controller: u32 = 0, "MC_RATE_CTRL", "", [0.0, 1.0], "Rate controller: 0 LADRC (Castillo), 1 PID";
        /// LADRC feedback gain, roll and pitch.
        adrc_kd_rp: f64 = 12.0, "ADRC_RP_KD", "1/s", [0.5, 100.0], "LADRC feedback gain k_d (71)-(72), roll and pitch";
        /// LADRC feedback gain, yaw.
        adrc_kd_y: f64 = 6.0, "ADRC_Y_KD", "1/s", [0.5, 100.0], "LADRC feedback gain k_d, yaw";
        /// ESO bandwidth.
        adrc_beta: f64 = 30.0, "ADRC_BETA", "1/s", [5.0, 1000.0], "LADRC observer bandwidth beta (70); 60 flies lockstep as well but loses the loop to one 4 ms exchange of actuator delay, 30 keeps a margin";
        /// TD slope limit (0: no TD).
        adrc_td_limit: f64 = 0.0, "ADRC_TD_R", "rad/s^2", [0.0, 10000.0], "Tracking-differentiator slope limit r (73); 0 turns the TD off";
        /// b̄ as a fraction of 1/I.
        adrc_b_scale: f64 = 1.0, "ADRC_B_SCALE", "", [0.1, 10.0], "LADRC input-gain estimate b-bar as a multiple of 1/I";
        /// PID proportional gain, roll and pitch (per unit inertia).
        pid_p_rp: f64 = 12.0, "MC_RP_RATE_P", "1/s", [0.0, 200.0], "PID proportional gain, roll and pitch, per kg m^2 of inertia";
        /// PID integral gain, roll and pitch.
        pid_i_rp: f64 = 20.0, "MC_RP_RATE_I", "1/s^2", [0.0, 500.0], "PID integral gain, roll and pitch, per kg m^2 of inertia";
        /// PID derivative gain, roll and pitch.
        pid_d_rp: f64 = 0.0, "MC_RP_RATE_D", "", [0.0, 5.0], "PID derivative gain (on the measurement), roll and pitch, per kg m^2";
        /// PID proportional gain, yaw.
        pid_p_y: f64 = 6.0, "MC_YAWRATE_P", "1/s", [0.0, 200.0], "PID proportional gain, yaw, per kg m^2 of inertia";
        /// PID integral gain, yaw.
        pid_i_y: f64 = 4.0, "MC_YAWRATE_I", "1/s^2", [0.0, 500.0], "PID integral gain, yaw, per kg m^2 of inertia";
        /// PID integral bound, roll and pitch (per unit inertia).
        pid_imax_rp: f64 = 60.0, "MC_RP_RATE_IMAX", "rad/s^2", [0.0, 500.0], "PID integral bound, roll and pitch, as an angular acceleration (x I: N m); PX4's MC_RR_INT_LIM 0.3 of a 450 quad's authority";
        /// PID integral bound, yaw (per unit inertia).
        pid_imax_y: f64 = 16.0, "MC_Y_RATE_IMAX", "rad/s^2", [0.0, 500.0], "PID integral bound, yaw, as an angular acceleration (x I: N m)";
        /// PID derivative low-pass cut-off.
        pid_d_cutoff_hz: f64 = 30.0, "MC_DTERM_CUTOFF", "Hz", [1.0, 500.0], "PID derivative low-pass cut-off";
    }
}

#[cfg(test)]
mod tests;
