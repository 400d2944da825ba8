//! Sensor models: what a flight board's IMU, magnetometer, barometer, GPS and ESCs report.
//!
//! Pure and seeded: the same seed and truth give a bit-identical stream. Each sensor draws from its
//! own random stream, so turning one off or changing its rate leaves the others' noise unchanged.

use crate::environment::isa_altitude_m;
use crate::rng::Rng;
use crate::{GRAVITY_M_S2, airframe::MAX_ROTORS};
use nalgebra::{UnitQuaternion, Vector3};
use navmath::geo::{LatLonAlt, LocalFrame};
use std::collections::VecDeque;

pub use config::{SensorConfig, SensorPreset, fields};
pub use frame::{EarthField, GpsFix, SensorFrame, SensorHealth, SensorKind, Truth};

/// Most GPS solutions in flight at once (rate × latency is far below this).
const GPS_QUEUE_LIMIT: usize = 64;

struct Periodic {
    period_usec: u64,
    next_usec: u64,
}

impl Periodic {
    fn new(rate_hz: f64) -> Self {
        Self {
            period_usec: (1e6 / rate_hz.max(1e-3)).round().max(1.0) as u64,
            next_usec: 0,
        }
    }

    fn due(&mut self, t: u64) -> bool {
        if t >= self.next_usec {
            self.next_usec = self.next_usec.max(t - t % self.period_usec) + self.period_usec;
            true
        } else {
            false
        }
    }
}

/// All the sensors of one vehicle.
pub struct SensorSuite {
    cfg: SensorConfig,
    field_ned: Vector3<f64>,
    /// The local frame at home: where the GPS reads the position.
    home: LocalFrame,
    imu_position_frd_m: Vector3<f64>,
    accel_rng: Rng,
    gyro_rng: Rng,
    mag_rng: Rng,
    baro_rng: Rng,
    gps_rng: Rng,
    rpm_rng: Rng,
    accel_bias: Vector3<f64>,
    accel_scale: Vector3<f64>,
    /// The board's attitude in the body (a small roll and pitch): the IMU reads `R⁻¹ v`.
    board: UnitQuaternion<f64>,
    gyro_bias: Vector3<f64>,
    /// The weather's pressure change (Pa) and its rate of change (Pa/s).
    weather_pa: f64,
    weather_rate_pa_s: f64,
    gps_error_ned: Vector3<f64>,
    vibration_axis: [Vector3<f64>; MAX_ROTORS],
    vibration_phase: [f64; MAX_ROTORS],
    mag_due: Periodic,
    baro_due: Periodic,
    gps_due: Periodic,
    rpm_due: Periodic,
    gps_queue: VecDeque<(u64, GpsFix)>,
    last: SensorFrame,
    last_time_usec: Option<u64>,
    last_gps: Option<GpsFix>,
    /// Injected state of each sensor.
    pub health: [SensorHealth; 5],
    /// The GPS receiver runs but has no fix (fix type 1, no satellites).
    pub gps_fix_lost: bool,
    /// Extra magnetic field added in NED (gauss), to inject disturbances.
    pub mag_disturbance_ned: Vector3<f64>,
    /// The IMU's white noise and bias walk are drawn once per exchange by
    /// [`SensorSuite::exchange_imu_noise`], not at every sample.
    noise_per_exchange: bool,
}

/// sin(x) for x ∈ [−π, π] to within 1e-6: plenty for vibration, at a fraction of libm's cost.
fn fast_sin(x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    // Fold into [−π/2, π/2], where the odd degree-11 Taylor polynomial is accurate to 6e-8.
    let y = if x > FRAC_PI_2 {
        PI - x
    } else if x < -FRAC_PI_2 {
        -PI - x
    } else {
        x
    };
    let y2 = y * y;
    let series = 1.0 / 362_880.0 - y2 / 39_916_800.0;
    let series = -1.0 / 5040.0 + y2 * series;
    let series = 1.0 / 120.0 + y2 * series;
    let series = -1.0 / 6.0 + y2 * series;
    y * (1.0 + y2 * series)
}

/// The mean thrust fraction of the rotors, `(ω/ω_max)²`.
fn thrust_fraction(t: &Truth) -> f64 {
    let rotors = t.rotor_speed_rad_s.iter().zip(t.rotor_max_speed_rad_s);
    let (sum, n) = rotors.fold((0.0, 0usize), |(sum, n), (&w, &max)| {
        (sum + (w / max.max(1e-9)).powi(2), n + 1)
    });
    if n == 0 { 0.0 } else { sum / n as f64 }
}

fn kind_index(k: SensorKind) -> usize {
    match k {
        SensorKind::Imu => 0,
        SensorKind::Mag => 1,
        SensorKind::Baro => 2,
        SensorKind::Gps => 3,
        SensorKind::Rpm => 4,
    }
}

impl SensorSuite {
    /// Sensors with parameters `cfg`, seeded by `seed`; `home` anchors the local NED origin.
    pub fn new(
        cfg: SensorConfig,
        field: EarthField,
        home: LatLonAlt,
        imu_position_frd_m: Vector3<f64>,
        seed: u64,
    ) -> Self {
        let mut accel_rng = Rng::stream(seed, 1);
        let mut gyro_rng = Rng::stream(seed, 2);
        let mut vib_rng = Rng::stream(seed, 7);
        let accel_bias = accel_rng.normal3(cfg.accel_bias_sigma);
        let accel_scale = accel_rng.normal3(cfg.accel_scale_sigma);
        let gyro_bias = gyro_rng.normal3(cfg.gyro_bias_sigma);
        // Its own stream: a tilt added to a preset leaves every other draw as it was.
        let mut board_rng = Rng::stream(seed, 9);
        let tilt = cfg.board_tilt_sigma_deg.to_radians();
        let board = UnitQuaternion::from_euler_angles(
            tilt * board_rng.normal(),
            tilt * board_rng.normal(),
            0.0,
        );
        let mut vibration_axis = [Vector3::zeros(); MAX_ROTORS];
        let mut vibration_phase = [0.0; MAX_ROTORS];
        for i in 0..MAX_ROTORS {
            // Mostly in the rotor plane, where imbalance shakes the frame.
            let v = Vector3::new(vib_rng.normal(), vib_rng.normal(), 0.5 * vib_rng.normal());
            vibration_axis[i] = v / v.norm().max(1e-9);
            vibration_phase[i] = (vib_rng.uniform() - 0.5) * std::f64::consts::TAU;
        }
        let (mag_due, baro_due, gps_due, rpm_due) = (
            Periodic::new(cfg.mag_rate_hz),
            Periodic::new(cfg.baro_rate_hz),
            Periodic::new(cfg.gps_rate_hz),
            Periodic::new(cfg.rpm_rate_hz),
        );
        Self {
            field_ned: field.ned(),
            home: LocalFrame::new(home),
            imu_position_frd_m,
            accel_rng,
            gyro_rng,
            mag_rng: Rng::stream(seed, 3),
            baro_rng: Rng::stream(seed, 4),
            gps_rng: Rng::stream(seed, 5),
            rpm_rng: Rng::stream(seed, 6),
            accel_bias,
            accel_scale,
            board,
            gyro_bias,
            weather_pa: 0.0,
            weather_rate_pa_s: 0.0,
            gps_error_ned: Vector3::zeros(),
            vibration_axis,
            vibration_phase,
            mag_due,
            baro_due,
            gps_due,
            rpm_due,
            gps_queue: VecDeque::with_capacity(16),
            last: SensorFrame {
                time_usec: 0,
                accel_frd_m_s2: Vector3::zeros(),
                gyro_frd_rad_s: Vector3::zeros(),
                mag_frd_gauss: Vector3::zeros(),
                abs_pressure_hpa: 0.0,
                pressure_alt_m: 0.0,
                temperature_c: 0.0,
                fields_updated: 0,
                gps: None,
                rotor_rpm: None,
            },
            last_time_usec: None,
            last_gps: None,
            health: [SensorHealth::Ok; 5],
            gps_fix_lost: false,
            mag_disturbance_ned: Vector3::zeros(),
            noise_per_exchange: false,
            cfg,
        }
    }

    /// From now on the IMU's samples carry no white noise and its biases hold between
    /// exchanges: [`SensorSuite::exchange_imu_noise`] draws both once per exchange for the
    /// average the autopilot is sent. The same statistics — the mean of n samples of white
    /// noise of density N at interval Δt has σ = N / √(n Δt), and a random walk sampled at
    /// the exchanges is the same walk —, a quarter of the Gaussian draws at 1 kHz physics
    /// and 250 Hz exchanges.
    pub fn draw_imu_noise_per_exchange(&mut self) {
        self.noise_per_exchange = true;
    }

    /// The IMU's noise over an exchange of `interval_s` added to its average (`accel`, `gyro`,
    /// board axes, clamped to the ranges), and the biases walked on for the next exchange.
    /// Nothing while the IMU is not healthy (a stuck IMU repeats itself exactly).
    pub fn exchange_imu_noise(
        &mut self,
        interval_s: f64,
        accel: &mut Vector3<f64>,
        gyro: &mut Vector3<f64>,
    ) {
        if !self.noise_per_exchange || interval_s <= 0.0 || self.health[0] != SensorHealth::Ok {
            return;
        }
        let (a, g) = self.imu_white_noise(interval_s);
        let c = &self.cfg;
        *accel = (*accel + a).map(|x| x.clamp(-c.accel_range, c.accel_range));
        *gyro = (*gyro + g).map(|x| x.clamp(-c.gyro_range, c.gyro_range));
        self.walk_imu_biases(interval_s);
    }

    /// The accelerometer's and gyro's white noise over an interval of `dt` (or the mean of
    /// samples spanning it): σ = N √(1/Δt) for band-limited white noise.
    fn imu_white_noise(&mut self, dt: f64) -> (Vector3<f64>, Vector3<f64>) {
        let rate_noise = 1.0 / dt.sqrt();
        (
            self.accel_rng
                .normal3(self.cfg.accel_noise_density * rate_noise),
            self.gyro_rng
                .normal3(self.cfg.gyro_noise_density * rate_noise),
        )
    }

    /// The accelerometer's and gyro's biases walked on by `dt`.
    fn walk_imu_biases(&mut self, dt: f64) {
        self.accel_bias += self.accel_rng.normal3(self.cfg.accel_bias_walk * dt.sqrt());
        self.gyro_bias += self.gyro_rng.normal3(self.cfg.gyro_bias_walk * dt.sqrt());
    }

    /// The injected state of one sensor.
    pub fn health_of(&self, kind: SensorKind) -> SensorHealth {
        self.health[kind_index(kind)]
    }

    /// Sets the injected state of one sensor.
    pub fn set_health(&mut self, kind: SensorKind, health: SensorHealth) {
        self.health[kind_index(kind)] = health;
    }

    /// The true gyro bias (rad/s), for scoring an estimator.
    pub fn gyro_bias(&self) -> Vector3<f64> {
        self.gyro_bias
    }

    /// The GPS's current position error (m, NED): its correlated wander, which an autopilot
    /// holding position on GPS follows (tests separate it from the autopilot's own error).
    pub fn gps_error_ned(&self) -> Vector3<f64> {
        self.gps_error_ned
    }

    /// The true accelerometer bias (m/s², in the board's axes).
    pub fn accel_bias(&self) -> Vector3<f64> {
        self.accel_bias
    }

    /// The true accelerometer scale errors (fractions, in the board's axes).
    pub fn accel_scale_error(&self) -> Vector3<f64> {
        self.accel_scale
    }

    /// The board's mounting error: its roll and pitch in the body (rad).
    pub fn board_tilt_rad(&self) -> (f64, f64) {
        let (roll, pitch, _) = self.board.euler_angles();
        (roll, pitch)
    }

    /// Samples every sensor at the truth `t`. Call once per physics step.
    pub fn sample(&mut self, t: &Truth) -> &SensorFrame {
        let dt = match self.last_time_usec {
            Some(prev) if t.time_usec > prev => (t.time_usec - prev) as f64 * 1e-6,
            _ => 1e-3,
        };
        self.last_time_usec = Some(t.time_usec);
        let q_inv = t.q_ned_from_frd.inverse();
        let mut updated = self.sample_imu(t, &q_inv, dt);
        updated |= self.sample_mag(t, &q_inv);
        updated |= self.sample_baro(t);
        self.sample_gps(t);
        self.deliver_gps(t);
        self.sample_rpm(t);
        self.last.time_usec = t.time_usec;
        self.last.fields_updated = updated;
        if self.last.gps.is_some() {
            self.last_gps = self.last.gps;
        }
        &self.last
    }

    /// The accelerometer and gyro (noise, bias walk, scale, vibration, mounting, range); the
    /// fields updated.
    fn sample_imu(&mut self, t: &Truth, q_inv: &UnitQuaternion<f64>, dt: f64) -> u32 {
        let mut updated = 0u32;
        let c = &self.cfg;
        // IMU: the specific force at the IMU's lever arm, Zabunov (50)–(54) with a rigid mount
        // (no relative velocity, so no Coriolis term).
        let r = self.imu_position_frd_m;
        let w = t.rate_frd_rad_s;
        let gravity = Vector3::new(0.0, 0.0, GRAVITY_M_S2);
        let specific = q_inv * (t.accel_ned_m_s2 - gravity)
            + t.ang_accel_frd_rad_s2.cross(&r) // Euler (54)
            + w.cross(&w.cross(&r)); // centripetal (53)
        let mut vib = Vector3::zeros();
        if c.accel_vibration > 0.0 {
            // One sinusoid per rotor at its own speed (imbalance), phase kept in [−π, π).
            let rotors = t.rotor_speed_rad_s.iter().zip(t.rotor_max_speed_rad_s);
            for (i, (&speed, &max)) in rotors.enumerate() {
                let mut phase = self.vibration_phase[i] + speed * dt;
                while phase >= std::f64::consts::PI {
                    phase -= std::f64::consts::TAU;
                }
                self.vibration_phase[i] = phase;
                let ratio = speed / max;
                let amp = c.accel_vibration * ratio * ratio;
                vib += self.vibration_axis[i] * (amp * fast_sin(phase));
            }
        }
        // White noise and the biases' walk here, or once per exchange.
        let (accel_noise, gyro_noise) = if self.noise_per_exchange {
            (Vector3::zeros(), Vector3::zeros())
        } else {
            self.walk_imu_biases(dt);
            self.imu_white_noise(dt)
        };
        let c = &self.cfg;
        match self.health[0] {
            SensorHealth::Ok => {
                // In the board's axes, which the mounting error tilts from the body's.
                let specific = self.board.inverse_transform_vector(&specific);
                let accel = specific.component_mul(&(Vector3::repeat(1.0) + self.accel_scale))
                    + self.accel_bias
                    + self.board.inverse_transform_vector(&vib)
                    + accel_noise;
                let gyro = self.board.inverse_transform_vector(&w) + self.gyro_bias + gyro_noise;
                self.last.accel_frd_m_s2 = accel.map(|x| x.clamp(-c.accel_range, c.accel_range));
                self.last.gyro_frd_rad_s = gyro.map(|x| x.clamp(-c.gyro_range, c.gyro_range));
                updated |= fields::ACCEL | fields::GYRO;
            }
            SensorHealth::Stuck => updated |= fields::ACCEL | fields::GYRO,
            SensorHealth::Off => {}
        }
        updated
    }

    /// The magnetometer when due; the fields updated.
    fn sample_mag(&mut self, t: &Truth, q_inv: &UnitQuaternion<f64>) -> u32 {
        let mut updated = 0u32;
        let c = &self.cfg;
        if self.mag_due.due(t.time_usec) {
            match self.health[1] {
                SensorHealth::Ok => {
                    let mut body = q_inv * (self.field_ned + self.mag_disturbance_ned);
                    if c.mag_motor_field != Vector3::zeros() {
                        body += c.mag_motor_field * thrust_fraction(t);
                    }
                    self.last.mag_frd_gauss = c.mag_soft_iron * body
                        + c.mag_hard_iron
                        + self.mag_rng.normal3(c.mag_noise);
                    updated |= fields::MAG;
                }
                SensorHealth::Stuck => updated |= fields::MAG,
                SensorHealth::Off => {}
            }
        }
        updated
    }

    /// The barometer when due (drift and noise drawn whatever its health); the fields updated.
    fn sample_baro(&mut self, t: &Truth) -> u32 {
        let mut updated = 0u32;
        let c = &self.cfg;
        if self.baro_due.due(t.time_usec) {
            let period = self.baro_due.period_usec as f64 * 1e-6;
            // The weather: a Gauss–Markov rate of change, integrated and returning to zero.
            let a = (-period / c.weather_rate_tau_s).exp();
            self.weather_rate_pa_s = self.weather_rate_pa_s * a
                + c.weather_rate_pa_s * (1.0 - a * a).sqrt() * self.baro_rng.normal();
            self.weather_pa +=
                (self.weather_rate_pa_s - self.weather_pa / c.weather_tau_s) * period;
            let noise = c.baro_noise_pa * self.baro_rng.normal();
            match self.health[2] {
                SensorHealth::Ok => {
                    let p = t.air.pressure_pa + self.weather_pa + noise;
                    self.last.abs_pressure_hpa = p * 0.01;
                    self.last.pressure_alt_m = isa_altitude_m(p);
                    self.last.temperature_c = t.air.temperature_k - 273.15;
                    updated |= fields::BARO;
                }
                SensorHealth::Stuck => updated |= fields::BARO,
                SensorHealth::Off => {}
            }
        }
        updated
    }

    /// A GPS fix when due (its correlated error and velocity noise), queued for its latency.
    fn sample_gps(&mut self, t: &Truth) {
        let c = &self.cfg;
        if self.gps_due.due(t.time_usec) {
            let period = self.gps_due.period_usec as f64 * 1e-6;
            // First-order Gauss–Markov position error with the configured stationary σ.
            let a = (-period / c.gps_correlation_s).exp();
            let k = (1.0 - a * a).sqrt();
            let n = self.gps_rng.normal3(1.0);
            self.gps_error_ned = self.gps_error_ned * a
                + Vector3::new(
                    c.gps_h_sigma * k * n.x,
                    c.gps_h_sigma * k * n.y,
                    c.gps_v_sigma * k * n.z,
                );
            let vel_noise = self.gps_rng.normal3(c.gps_vel_sigma);
            let fix = if self.gps_fix_lost {
                GpsFix {
                    time_usec: t.time_usec,
                    fix_type: 1,
                    position: self.home.origin(),
                    vel_ned_m_s: Vector3::zeros(),
                    h_acc_m: 999.0,
                    v_acc_m: 999.0,
                    s_acc_m_s: 999.0,
                    satellites: 0,
                }
            } else {
                GpsFix {
                    time_usec: t.time_usec,
                    fix_type: 3,
                    position: self.home.to_geodetic(&(t.pos_ned_m + self.gps_error_ned)),
                    vel_ned_m_s: t.vel_ned_m_s + vel_noise,
                    h_acc_m: c.gps_h_sigma.max(0.05),
                    v_acc_m: c.gps_v_sigma.max(0.05),
                    s_acc_m_s: c.gps_vel_sigma.max(0.05),
                    satellites: c.gps_satellites,
                }
            };
            let deliver = t.time_usec + (c.gps_latency_s * 1e6).round() as u64;
            if self.gps_queue.len() < GPS_QUEUE_LIMIT {
                self.gps_queue.push_back((deliver, fix));
            }
        }
    }

    /// The fixes whose latency has passed, as the GPS's health lets them through.
    fn deliver_gps(&mut self, t: &Truth) {
        self.last.gps = None;
        while let Some(&(deliver, fix)) = self.gps_queue.front() {
            if deliver > t.time_usec {
                break;
            }
            self.gps_queue.pop_front();
            match self.health[3] {
                SensorHealth::Ok => self.last.gps = Some(fix),
                SensorHealth::Stuck => {
                    if let Some(prev) = self.last_gps {
                        self.last.gps = Some(GpsFix {
                            time_usec: fix.time_usec,
                            ..prev
                        });
                    }
                }
                SensorHealth::Off => {}
            }
        }
    }

    /// The rotor speeds from the ESCs when due.
    fn sample_rpm(&mut self, t: &Truth) {
        let c = &self.cfg;
        self.last.rotor_rpm = None;
        if self.rpm_due.due(t.time_usec) && self.health[4] != SensorHealth::Off {
            let mut rpm = [0.0; MAX_ROTORS];
            for (i, &s) in t.rotor_speed_rad_s.iter().enumerate() {
                rpm[i] = (s * 60.0 / std::f64::consts::TAU
                    * (1.0 + c.rpm_noise * self.rpm_rng.normal()))
                .max(0.0);
            }
            self.last.rotor_rpm = Some(rpm);
        }
    }
}

mod config;
mod frame;
#[cfg(test)]
mod tests;
