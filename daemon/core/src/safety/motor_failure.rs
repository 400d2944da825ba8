//! Motor-failure detection: which rotor stopped making thrust, within a quarter of a second.
//!
//! Two independent witnesses, either one enough:
//! - **Rotor speed** (when the ESCs or the simulator report rpm): a motor turning at less than
//!   half the speed it was told to reach — the set-point passed through the motor's own lag,
//!   so a spin-up is not a failure — while it was told to turn fast enough to matter.
//! - **Thrust imbalance** (ArduPilot's thrust-balance idea, made model-based): the wrench the
//!   mixer believes the rotors make, `B T` (Lewis (4.31), (4.34)), `T` the thrust of each speed
//!   set-point passed through the motor's lag (thrust as the speed squared), against the wrench the body
//!   shows: collective from the accelerometer (`m f_z`) and moments from the gyro through Euler's
//!   equation `J ω̇ + ω × J ω` (Castillo (58), without the small rotor terms). A rotor that makes
//!   `ΔT` less than believed leaves a deficit `ΔT b_i` — its own column of `B`: a thrust loss
//!   *and* a moment about its own arm, in proportion. Each rotor's loss is fitted to the deficit
//!   (least squares, moments counted per metre of mean arm so both parts weigh alike); the rotor
//!   whose column explains it (residual under 35 %) and lost more than half of its thrust is the
//!   suspect. A wind torque, a gust's lift or a ground contact each fit no single column.
//!
//! Both the belief and the measurement go through the same first-order filter (30 ms), whose
//! derivative of the gyro is exact: `d/dt ω_f = (ω − ω_f)/τ`. A suspect must stay one for
//! `FD_ACT_MOT_TOUT` before the failure is declared (and latched until [`MotorFailureDetector::reset`]);
//! a rotor's own low speed only two ESC readings in a row, or one the imbalance agrees with; a
//! quad's rotor that stops (the deficit its column's alone, and with the filter's lag undone
//! most of its thrust) only for 8 ms, unless a fresh ESC reading shows it turning as told: found
//! about 0.04 s after it stops. A quad on three rotors cannot wait: every 10 ms costs about 5°
//! more tilt in the spin-up.
//! The thrust check runs only in the air: on the ground the ground carries what the rotors do not.

use airframe::{Airframe, MAX_ROTORS};
use nalgebra::{Matrix3, Vector3};

/// Filter time constant of both the believed and the measured wrench (s).
const FILTER_TAU_S: f64 = 0.03;
/// Fraction of a rotor's thrust (or speed) that must be missing.
const LOST_FRACTION: f64 = 0.5;
/// Largest share of the deficit one rotor's column may leave unexplained.
const RESIDUAL_FRACTION: f64 = 0.35;
/// Rotors told less than this share of their top thrust are not judged (they make too little to
/// tell).
const MIN_THRUST_SHARE: f64 = 0.05;
/// Rotors told less than this share of their top speed are not judged by rpm.
const MIN_SPEED_SHARE: f64 = 0.2;
/// A single rotor cannot lose more than its whole thrust: a fit beyond this (with margin for
/// noise) is several rotors, or no rotor at all.
const MAX_LOST_FRACTION: f64 = 1.4;
/// A rotor's own speed is direct evidence: this many ESC readings in a row far below its
/// set-point confirm it (40 ms at 50 Hz), or one that the thrust imbalance agrees with, or
/// `FD_ACT_MOT_TOUT` of them if sooner. One reading alone is never enough (a telemetry glitch);
/// a quad cannot wait longer: every 10 ms its dead rotor's side tips faster (about 5° more at
/// the worst of the spin-up).
const RPM_CONFIRM_READINGS: u32 = 2;
/// ESC telemetry comes slower than the control loop (50 Hz in the simulator): a reading is
/// judged until this old (s).
const RPM_MAX_AGE_S: f64 = 0.1;

/// A quad's rotor that stops is judged faster (it cannot fly on the others' allocation and every
/// 10 ms costs about 5° of tilt) when the deficit is its column's alone: a residual under this
/// share ...
const STOP_RESIDUAL_FRACTION: f64 = 0.15;
/// ... a loss above this share of its thrust ...
const STOP_SEEN_FRACTION: f64 = 0.3;
/// ... held this long (s: three samples 4 ms apart at 250 Hz) ...
const STOP_CONFIRM_S: f64 = 0.008;
/// ... and then the loss the filter's input shows above this share: its output with the lag
/// undone, `x + τ ẋ`, `ẋ` the mean slope since the fit turned clean. That slope overstates the
/// present one on the filter's rise after a step, so a sudden loss of about 70 % passes too; a
/// rotor that keeps a third of its thrust or more is left to `FD_ACT_MOT_TOUT` (60 % lost: found
/// by it; 40 %: flown on by the controllers).
const STOP_PROJECTED_FRACTION: f64 = 0.8;
/// A rotor whose fresh ESC reading is within this share of its lagged set-point speed turns as
/// told: the quick stop judgement does not overrule it. (A stopping rotor's speed leaves this
/// band within a reading: its ESC tells before the imbalance could.)
const TURNING_FRACTION: f64 = 0.1;
/// Airframes with at most this many rotors have no spare for a lost one: the quads.
const NO_SPARE_ROTORS: usize = 4;

/// How a failure was seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Detection {
    /// The rotor's reported speed fell far below its set-point.
    RotorSpeed,
    /// The body's motion showed this rotor's thrust missing.
    ThrustImbalance,
}

/// A rotor declared failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorFailure {
    /// Rotor index (0-based, the airframe's order).
    pub rotor: usize,
    /// Which witness saw it.
    pub by: Detection,
    /// Fraction of the rotor's thrust (or speed) found missing, at most 1 (a quad's stopping
    /// rotor: the loss projected with the filter's lag undone, where the filtered one still
    /// lags).
    pub lost_fraction: f64,
}

/// Settings (from `FD_ACT_EN`, `FD_ACT_MOT_TOUT`, `CA_FAILURE_MODE`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorFailureParams {
    /// Detection on.
    pub enabled: bool,
    /// Time a suspect must stay one (s).
    pub timeout_s: f64,
    /// Re-allocate without the failed rotor on detection.
    pub reallocate: bool,
}

impl Default for MotorFailureParams {
    fn default() -> Self {
        Self {
            enabled: true,
            timeout_s: 0.1,
            reallocate: true,
        }
    }
}

/// What the detector sees each step.
#[derive(Debug, Clone, Copy)]
pub struct DetectorInput<'a> {
    /// Time since the last step (s).
    pub dt: f64,
    /// Gyro rate, FRD (rad/s).
    pub gyro: Vector3<f64>,
    /// Specific force, FRD (m/s²).
    pub accel: Vector3<f64>,
    /// Rotor speed set-points the mixer gave (rad/s).
    pub speed_setpoint: &'a [f64],
    /// Rotor thrusts the mixer allocated (N).
    pub thrust_setpoint: &'a [f64],
    /// Rotor speeds reported by the ESCs (rad/s), when fresh.
    pub measured_speed: Option<&'a [f64]>,
    /// Flying (not touching the ground).
    pub in_air: bool,
}

/// The detector of one airframe.
#[derive(Debug, Clone)]
pub struct MotorFailureDetector {
    params: MotorFailureParams,
    n: usize,
    /// Columns of B restricted to `[F_z, M_x/L, M_y/L]`.
    columns: [Vector3<f64>; MAX_ROTORS],
    mean_arm_m: f64,
    motor_tau_s: [f64; MAX_ROTORS],
    max_speed: [f64; MAX_ROTORS],
    max_thrust: [f64; MAX_ROTORS],
    inertia: Matrix3<f64>,
    mass_kg: f64,
    /// The speed set-points through the motor lag.
    speed_lag: [f64; MAX_ROTORS],
    /// Each rotor's thrust over its speed squared, from the mixer's last set-point (N s²).
    thrust_per_speed_sq: [f64; MAX_ROTORS],
    /// Believed `[F_z, M_x, M_y]`, filtered.
    believed: Vector3<f64>,
    /// Gyro and `m f_z`, filtered.
    rate_f: Vector3<f64>,
    force_f: f64,
    primed: bool,
    /// Last reported rotor speeds and their age (s).
    rpm: [f64; MAX_ROTORS],
    rpm_age_s: f64,
    rpm_suspect_s: [f64; MAX_ROTORS],
    /// Fresh ESC readings in a row far below the set-point.
    rpm_low_readings: [u32; MAX_ROTORS],
    imbalance_suspect_s: [f64; MAX_ROTORS],
    /// How long each rotor has looked like a quad's stopping one (s), and the share lost when
    /// it began to.
    stop_seen: [Option<(f64, f64)>; MAX_ROTORS],
    failed: [bool; MAX_ROTORS],
}

/// What one step shows of all rotors, for each one's judgement.
struct Seen {
    /// The thrust and moments the set-points mean, less what the body shows (N, as forces).
    deficit: Vector3<f64>,
    /// A rotor-speed reading recent enough to judge by, and whether one arrived this step.
    rpm_fresh: bool,
    new_reading: bool,
    /// In the air (a rotor's share of the imbalance is judged only there).
    in_air: bool,
    /// The step (s).
    dt: f64,
}

impl MotorFailureDetector {
    /// A detector for `airframe`.
    pub fn new(airframe: &Airframe, params: MotorFailureParams) -> Self {
        let n = airframe.rotors.len();
        let mean_arm_m = airframe
            .rotors
            .iter()
            .map(|r| r.position_frd_m.xy().norm())
            .sum::<f64>()
            / n.max(1) as f64;
        let arm = mean_arm_m.max(1e-3);
        let mut columns = [Vector3::zeros(); MAX_ROTORS];
        let (mut motor_tau_s, mut max_speed, mut max_thrust) =
            ([0.03; MAX_ROTORS], [0.0; MAX_ROTORS], [0.0; MAX_ROTORS]);
        for (i, r) in airframe.rotors.iter().enumerate() {
            // Lewis (4.31): thrust −T along z, moments (−y T, x T).
            columns[i] = Vector3::new(-1.0, -r.position_frd_m.y / arm, r.position_frd_m.x / arm);
            motor_tau_s[i] = r.time_constant_s.max(1e-3);
            max_speed[i] = r.max_speed_rad_s;
            max_thrust[i] = r.thrust_n(crate::SEA_LEVEL_AIR_DENSITY_KG_M3, r.max_speed_rad_s);
        }
        Self {
            params,
            n,
            columns,
            mean_arm_m: arm,
            motor_tau_s,
            max_speed,
            max_thrust,
            inertia: airframe.inertia_kg_m2,
            mass_kg: airframe.mass_kg,
            speed_lag: [0.0; MAX_ROTORS],
            thrust_per_speed_sq: std::array::from_fn(|r| {
                max_thrust[r] / (max_speed[r] * max_speed[r]).max(1e-9)
            }),
            believed: Vector3::zeros(),
            rate_f: Vector3::zeros(),
            force_f: 0.0,
            primed: false,
            rpm: [0.0; MAX_ROTORS],
            rpm_age_s: f64::INFINITY,
            rpm_suspect_s: [0.0; MAX_ROTORS],
            rpm_low_readings: [0; MAX_ROTORS],
            imbalance_suspect_s: [0.0; MAX_ROTORS],
            stop_seen: [None; MAX_ROTORS],
            failed: [false; MAX_ROTORS],
        }
    }

    /// The settings.
    pub fn params(&self) -> &MotorFailureParams {
        &self.params
    }

    /// Changes the settings (kept state).
    pub fn set_params(&mut self, params: MotorFailureParams) {
        self.params = params;
    }

    /// Rotors declared failed.
    pub fn failed(&self) -> &[bool] {
        &self.failed[..self.n]
    }

    /// Declares `rotor` failed (reported by the board or injected).
    pub fn declare(&mut self, rotor: usize) {
        if rotor < self.n {
            self.failed[rotor] = true;
        }
    }

    /// Forgets every declared failure and suspicion (at disarm: a new flight judges afresh).
    pub fn reset(&mut self) {
        self.failed = [false; MAX_ROTORS];
        self.rpm_suspect_s = [0.0; MAX_ROTORS];
        self.rpm_low_readings = [0; MAX_ROTORS];
        self.imbalance_suspect_s = [0.0; MAX_ROTORS];
        self.stop_seen = [None; MAX_ROTORS];
        self.primed = false;
        self.rpm_age_s = f64::INFINITY;
    }

    /// One step; a newly declared failure, if any (at most one per step).
    pub fn step(&mut self, i: &DetectorInput) -> Option<MotorFailure> {
        if !i.dt.is_finite() {
            // A step without a time is not judged (nor let into the filters).
            return None;
        }
        let dt = i.dt.clamp(1e-4, 0.1);
        let n = self
            .n
            .min(i.speed_setpoint.len())
            .min(i.thrust_setpoint.len());
        let k = (dt / FILTER_TAU_S).min(1.0);
        let clean = |x: f64| if x.is_finite() { x.max(0.0) } else { 0.0 };
        // The set-points through each motor's lag: what a healthy rotor is doing now. A motor
        // lags in speed and its thrust goes as the speed squared, so the thrust is that of the
        // lagged speed (the thrust set-point lagged instead runs ahead of a rotor speeding up
        // from slow: a deficit on its column where none is).
        let mut believed = Vector3::zeros();
        for r in 0..n {
            let lag = 1.0 - (-dt / self.motor_tau_s[r]).exp();
            let speed = clean(i.speed_setpoint[r]);
            if speed > 1e-3 * self.max_speed[r] {
                self.thrust_per_speed_sq[r] = clean(i.thrust_setpoint[r]) / (speed * speed);
            }
            self.speed_lag[r] += lag * (speed - self.speed_lag[r]);
            believed += self.columns[r] * self.thrust_lag(r);
        }
        let new_reading = match i.measured_speed {
            Some(m) if m.len() >= n => {
                self.rpm[..n].copy_from_slice(&m[..n]);
                self.rpm_age_s = 0.0;
                true
            }
            _ => {
                self.rpm_age_s += dt;
                false
            }
        };
        let rpm_fresh = self.rpm_age_s <= RPM_MAX_AGE_S;
        let gyro = i.gyro.map(|x| if x.is_finite() { x } else { 0.0 });
        let force = if i.accel.z.is_finite() {
            self.mass_kg * i.accel.z
        } else {
            self.force_f
        };
        if !self.primed {
            self.believed = believed;
            self.rate_f = gyro;
            self.force_f = force;
            self.primed = true;
            return None;
        }
        // The derivative of the filtered rate is exact: (ω − ω_f)/τ.
        let rate_dot_f = (gyro - self.rate_f) / FILTER_TAU_S;
        self.rate_f += (gyro - self.rate_f) * k;
        self.force_f += (force - self.force_f) * k;
        self.believed += (believed - self.believed) * k;
        if !self.params.enabled {
            return None;
        }
        // Euler's equation (Castillo (58)): the moment the body shows.
        let moment = self.inertia * rate_dot_f + self.rate_f.cross(&(self.inertia * self.rate_f));
        let shown = Vector3::new(
            self.force_f,
            moment.x / self.mean_arm_m,
            moment.y / self.mean_arm_m,
        );
        let deficit = self.believed - shown;
        let seen = Seen {
            deficit,
            rpm_fresh,
            new_reading,
            in_air: i.in_air,
            dt,
        };
        let mut found = None;
        for r in 0..n {
            if !self.failed[r] {
                let judged = self.judge(r, &seen);
                found = found.or(judged);
            }
        }
        if let Some(f) = found {
            self.failed[f.rotor] = true;
        }
        found
    }

    /// Rotor `r` judged on what the body and the rotor speeds show: its failure, if one of the
    /// witnesses confirms it now.
    fn judge(&mut self, r: usize, now: &Seen) -> Option<MotorFailure> {
        let mut found = None;
        // Rotor speed well below the lagged set-point, or turning as told.
        let w = self.rpm[r];
        let speed_judged = now.rpm_fresh
            && self.speed_lag[r] > MIN_SPEED_SHARE * self.max_speed[r]
            && w.is_finite();
        let rpm_low = speed_judged && w < (1.0 - LOST_FRACTION) * self.speed_lag[r];
        let speed_says_turning = speed_judged && w >= (1.0 - TURNING_FRACTION) * self.speed_lag[r];
        if !rpm_low {
            self.rpm_low_readings[r] = 0;
        } else if now.new_reading {
            self.rpm_low_readings[r] += 1;
        }
        // This rotor's column explains the deficit, and the loss is most of its thrust.
        let t = self.thrust_lag(r);
        let fit = (now.in_air && t > MIN_THRUST_SHARE * self.max_thrust[r]).then(|| {
            let b = &self.columns[r];
            let lost = b.dot(&now.deficit) / b.norm_squared();
            let residual = (now.deficit - b * lost).norm() / now.deficit.norm().max(1e-12);
            (lost / t, residual)
        });
        let imbalance = fit
            .filter(|&(f, res)| {
                res <= RESIDUAL_FRACTION && f > LOST_FRACTION && f < MAX_LOST_FRACTION
            })
            .map(|(f, _)| f);
        // The quick stop judgement stands in for ESC telemetry: a fresh reading of the
        // rotor turning as told overrules it (a lost propeller is left to the timeout).
        let stopping = self.judge_stop(r, fit.filter(|_| !speed_says_turning), now.dt);
        // Two low readings in a row, or one that the body's motion agrees with (the other
        // witness suspects the same rotor): two pieces of evidence either way.
        let readings_confirm = self.rpm_low_readings[r] >= RPM_CONFIRM_READINGS
            || (self.rpm_low_readings[r] >= 1 && imbalance.is_some());
        let rpm_fraction = 1.0 - w / self.speed_lag[r].max(1e-9);
        // Each witness: its suspicion's time, whether it sees a loss now, whether its own
        // evidence confirms it before `FD_ACT_MOT_TOUT`, and the share lost.
        for (suspect, seen, early, by, fraction) in [
            (
                &mut self.rpm_suspect_s[r],
                rpm_low,
                rpm_low && readings_confirm,
                Detection::RotorSpeed,
                rpm_fraction,
            ),
            (
                &mut self.imbalance_suspect_s[r],
                imbalance.is_some(),
                stopping.is_some(),
                Detection::ThrustImbalance,
                stopping.or(imbalance).unwrap_or(0.0),
            ),
        ] {
            *suspect = if seen { *suspect + now.dt } else { 0.0 };
            let confirmed = *suspect >= self.params.timeout_s || early;
            if found.is_none() && confirmed {
                found = Some(MotorFailure {
                    rotor: r,
                    by,
                    lost_fraction: fraction.clamp(0.0, 1.0),
                });
            }
        }
        found
    }

    /// Rotor `r`'s thrust at its lagged speed set-point (N): what a healthy rotor makes now.
    fn thrust_lag(&self, r: usize) -> f64 {
        self.thrust_per_speed_sq[r] * self.speed_lag[r].powi(2)
    }

    /// Whether rotor `r` of a quad is stopping, from this step's fit of the deficit to its
    /// column, `(lost share of its thrust, unexplained share)`: a clean fit held for
    /// [`STOP_CONFIRM_S`], whose loss with the filter's lag undone (see
    /// [`STOP_PROJECTED_FRACTION`]) is most of the thrust. That loss, when it is.
    fn judge_stop(&mut self, r: usize, fit: Option<(f64, f64)>, dt: f64) -> Option<f64> {
        let clean = fit.filter(|&(lost, unexplained)| {
            self.n <= NO_SPARE_ROTORS
                && unexplained <= STOP_RESIDUAL_FRACTION
                && lost > STOP_SEEN_FRACTION
                && lost < MAX_LOST_FRACTION
        });
        let Some((lost, _)) = clean else {
            self.stop_seen[r] = None;
            return None;
        };
        let (held_s, first) = self.stop_seen[r].map_or((0.0, lost), |(h, f)| (h + dt, f));
        self.stop_seen[r] = Some((held_s, first));
        // The first-order filter's input from its output: u = x + τ ẋ, ẋ over the hold.
        let projected = lost + FILTER_TAU_S * (lost - first) / held_s.max(dt);
        (held_s >= STOP_CONFIRM_S - 1e-9 && projected > STOP_PROJECTED_FRACTION)
            .then_some(projected)
    }
}

#[cfg(test)]
mod tests;
