//! The flight core's configuration: which loops fly, with which gains, from a parameter set and
//! an airframe.

use crate::control::attitude::{KinematicParams, TiltYawPdParams};
use crate::control::motor::MotorLoopParams;
use crate::control::position::PositionParams;
use crate::control::rate::{LadrcParams, PidParams};
use crate::estimator::translation::TranslationParams;
use crate::params::{AttitudeControlGroup, AttitudeParams, FlightParams, RateGroup};
use crate::safety::motor_failure::MotorFailureParams;
use airframe::Airframe;
use nalgebra::Vector3;

/// Which inner loop flies the rates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RateLoopParams {
    /// Castillo's LADRC, one set of parameters per axis.
    Ladrc([LadrcParams; 3]),
    /// The PID alternative.
    Pid([PidParams; 3]),
}

/// Which attitude law flies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AttitudeLaw {
    /// Castillo's kinematic law (63) feeding the rate loop.
    Kinematic(KinematicParams),
    /// Lewis's tilt/yaw PD (4.19)–(4.21): moments directly, no rate loop.
    TiltYawPd(TiltYawPdParams),
}

/// Everything the flight core needs to know.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightCoreConfig {
    /// Attitude estimator.
    pub attitude: AttitudeParams,
    /// Translation estimator.
    pub translation: TranslationParams,
    /// Position loop.
    pub position: PositionParams,
    /// Period of the position loop (s): it runs on the first sample at least this long after
    /// its last run and its attitude set-point holds in between. The estimators, the attitude
    /// law and the rate loop run on every sample.
    pub position_period_s: f64,
    /// Attitude loop.
    pub attitude_law: AttitudeLaw,
    /// Rate loop.
    pub rate: RateLoopParams,
    /// Rotor-speed loop (used when the ESCs report rpm).
    pub motor: MotorLoopParams,
    /// Motor-failure detection and re-allocation.
    pub motor_failure: MotorFailureParams,
}

impl FlightCoreConfig {
    /// Defaults for an airframe (`params/flight.toml`'s values), with the PID rate loop if
    /// `use_pid`.
    pub fn for_airframe(a: &Airframe, use_pid: bool) -> Self {
        let mut p = FlightParams::default();
        p.rate.controller = use_pid as u32;
        Self::from_params(&p, a)
    }

    /// The configuration a parameter set gives for an airframe: b̄ = 1/I per axis (so the rate
    /// loop's output is a torque); gains given "per unit inertia" are scaled by I; mass and thrust
    /// limits from the airframe.
    pub fn from_params(p: &FlightParams, a: &Airframe) -> Self {
        let inertia = a.inertia_kg_m2.diagonal();
        let max_thrust: f64 = a
            .rotors
            .iter()
            .map(|r| r.thrust_n(crate::SEA_LEVEL_AIR_DENSITY_KG_M3, r.max_speed_rad_s))
            .sum();
        let rate = rate_loop(&p.rate, &inertia);
        let attitude_law = attitude_law(&p.attitude_control, &inertia);
        let (t, q, m) = (&p.translation, &p.position, &p.motor);
        Self {
            attitude: p.attitude.clone(),
            translation: TranslationParams {
                tau_xy_s: t.tau_xy_s,
                tau_z_s: t.tau_z_s,
                tau_vel_s: t.tau_vel_s,
                gps_delay_s: t.gps_delay_s,
                gps_p_noise_m: t.gps_p_noise_m,
                gps_v_noise_m_s: t.gps_v_noise_m_s,
                gps_max_h_acc_m: t.gps_max_h_acc_m,
                gps_timeout_s: t.gps_timeout_s,
                baro_timeout_s: t.baro_timeout_s,
                accel_bias_limit: t.accel_bias_limit,
                gps_hgt_tau_s: t.gps_hgt_tau_s,
            },
            position: PositionParams {
                mass_kg: a.mass_kg,
                k_pos: Vector3::new(q.k_pos_xy, q.k_pos_xy, q.k_pos_z),
                k_vel: Vector3::new(q.k_vel_xy, q.k_vel_xy, q.k_vel_z),
                k_vel_i: Vector3::new(q.k_vel_i_xy, q.k_vel_i_xy, q.k_vel_i_z),
                max_speed_h: q.max_speed_h,
                max_speed_up: q.max_speed_up,
                max_speed_down: q.max_speed_down,
                max_accel_h: q.max_accel_h,
                max_accel_v: q.max_accel_v,
                max_tilt: q.max_tilt_deg.to_radians(),
                max_thrust_n: max_thrust,
                i_limit: q.i_limit,
                k_disturbance_ff: q.k_disturbance_ff,
                disturbance_tau_s: q.disturbance_tau_s,
            },
            position_period_s: 1.0 / q.loop_hz,
            attitude_law,
            rate,
            motor: MotorLoopParams {
                k_p: m.k_p,
                k_i: m.k_i,
                k_g: m.k_g,
                i_limit: m.i_limit,
                gain_range: m.gain_range,
            },
            motor_failure: MotorFailureParams {
                enabled: p.safety.motor_failure_detection != 0,
                timeout_s: p.safety.motor_failure_timeout_ms as f64 * 1e-3,
                reallocate: p.safety.motor_failure_mode != 0,
            },
        }
    }
}

/// The rate loop's gains from the parameters, scaled by the inertia about each axis (kg·m²).
fn rate_loop(r: &RateGroup, inertia: &Vector3<f64>) -> RateLoopParams {
    if r.controller == 1 {
        RateLoopParams::Pid([0, 1, 2].map(|i| {
            let j = inertia[i];
            let (kp, ki, kd, imax) = if i < 2 {
                (r.pid_p_rp, r.pid_i_rp, r.pid_d_rp, r.pid_imax_rp)
            } else {
                (r.pid_p_y, r.pid_i_y, 0.0, r.pid_imax_y)
            };
            PidParams {
                k_p: kp * j,
                k_i: ki * j,
                k_d: kd * j,
                k_ff: 0.0,
                d_cutoff_hz: r.pid_d_cutoff_hz,
                i_limit: imax * j,
                u_max: 1e3,
            }
        }))
    } else {
        RateLoopParams::Ladrc([0, 1, 2].map(|i| LadrcParams {
            b_bar: r.adrc_b_scale / inertia[i],
            k_d: if i < 2 { r.adrc_kd_rp } else { r.adrc_kd_y },
            beta: r.adrc_beta,
            td_limit: if r.adrc_td_limit > 0.0 {
                r.adrc_td_limit
            } else {
                f64::INFINITY
            },
            u_max: 1e3,
        }))
    }
}

/// The attitude law and its gains from the parameters, scaled by the inertia (kg·m²).
fn attitude_law(c: &AttitudeControlGroup, inertia: &Vector3<f64>) -> AttitudeLaw {
    if c.law == 1 {
        let tilt_inertia = inertia.x.max(inertia.y);
        AttitudeLaw::TiltYawPd(TiltYawPdParams {
            k_p_tilt: c.pd_k_p_tilt * tilt_inertia,
            k_d_tilt: c.pd_k_d_tilt * tilt_inertia,
            k_p_yaw: c.pd_k_p_yaw * inertia.z,
            k_d_yaw: c.pd_k_d_yaw * inertia.z,
        })
    } else {
        AttitudeLaw::Kinematic(KinematicParams {
            k_k: c.k_k,
            yaw_weight: c.yaw_weight,
            max_tilt_rate: c.max_tilt_rate_deg_s.to_radians(),
            max_yaw_rate: c.max_yaw_rate_deg_s.to_radians(),
        })
    }
}
