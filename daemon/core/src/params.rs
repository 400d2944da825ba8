//! Parameters of the flight core, declared next to the algorithms that use them.
//!
//! Each group is a serde struct with defaults (`deny_unknown_fields`), loaded from TOML under
//! `params/`, with `validate()` returning every violation. Each parameter also has a metadata row
//! (MAVLink name of at most 16 characters, unit, range, description) for the ground-station
//! parameter protocol and the generated reference.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Deserialize;

/// One parameter's metadata.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamMeta {
    /// MAVLink name, at most 16 characters, stable, never reused.
    pub name: &'static str,
    /// Key in the TOML group.
    pub key: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Default value.
    pub default: f64,
    /// Smallest accepted value.
    pub min: f64,
    /// Largest accepted value.
    pub max: f64,
    /// What it does.
    pub description: &'static str,
}

/// A rejected parameter value.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamViolation {
    /// Key in the TOML group, e.g. `attitude.observer_gain`.
    pub key: String,
    /// Why, with the allowed range.
    pub reason: String,
}

fn check(out: &mut Vec<ParamViolation>, group: &str, meta: &[ParamMeta], key: &str, value: f64) {
    if let Some(m) = meta.iter().find(|m| m.key == key)
        && !(value.is_finite() && value >= m.min && value <= m.max)
    {
        out.push(ParamViolation {
            key: format!("{group}.{key}"),
            reason: format!(
                "must be within [{}, {}] {}, got {value}",
                m.min, m.max, m.unit
            ),
        });
    }
}

/// Attitude estimator parameters (Castillo (80)–(105) and the safeguards around them).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttitudeParams {
    /// Observer gain k of (105).
    pub observer_gain: f64,
    /// Bias gain of (102).
    pub bias_gain: f64,
    /// Bound on the gyro-bias estimate.
    pub bias_limit_rad_s: f64,
    /// Wahba weight of the accelerometer vector.
    pub accel_weight: f64,
    /// Wahba weight of the magnetometer vector.
    pub mag_weight: f64,
    /// |a| deviation (in g) from the expected specific force where the accelerometer weight starts
    /// to fall.
    pub accel_deweight_g: f64,
    /// |a| deviation (in g) beyond which the accelerometer is not used.
    pub accel_gate_g: f64,
    /// IMU samples averaged for the initial alignment at rest.
    pub align_samples: u32,
    /// Longest time without a measurement correction before the estimate is invalid (s).
    pub max_uncorrected_s: f64,
    /// Magnetic inclination at the site (deg, positive down).
    pub mag_inclination_deg: f64,
    /// Magnetic declination at the site (deg, positive east).
    pub mag_declination_deg: f64,
    /// Hard-iron offset, Castillo (75).
    pub mag_offset: [f64; 3],
    /// Ellipsoid scale E = diag(mag_scale), Castillo (75).
    pub mag_scale: [f64; 3],
    /// Ellipsoid rotation R of Castillo (75) as a rotation vector (rad).
    pub mag_rotation_rad: [f64; 3],
}

impl Default for AttitudeParams {
    fn default() -> Self {
        Self {
            observer_gain: 4.0, // Castillo 5.x: k = 4
            bias_gain: 0.5,
            bias_limit_rad_s: 0.1,
            accel_weight: 1.0,
            mag_weight: 0.1,
            accel_deweight_g: 0.05,
            accel_gate_g: 0.3,
            align_samples: 250,
            max_uncorrected_s: 0.5,
            mag_inclination_deg: 63.3,
            mag_declination_deg: 3.0,
            mag_offset: [0.0; 3],
            mag_scale: [1.0; 3],
            mag_rotation_rad: [0.0; 3],
        }
    }
}

/// Metadata of the attitude parameters.
pub const ATTITUDE_META: &[ParamMeta] = &[
    ParamMeta {
        name: "ATT_OBS_K",
        key: "observer_gain",
        unit: "1/s",
        default: 4.0,
        min: 0.05,
        max: 50.0,
        description: "Observer gain k of Castillo (105): how fast the estimate follows the q-method measurement",
    },
    ParamMeta {
        name: "ATT_BIAS_K",
        key: "bias_gain",
        unit: "1/s",
        default: 0.5,
        min: 0.0,
        max: 5.0,
        description: "Gyro-bias gain of Castillo (102)",
    },
    ParamMeta {
        name: "ATT_BIAS_MAX",
        key: "bias_limit_rad_s",
        unit: "rad/s",
        default: 0.1,
        min: 0.001,
        max: 1.0,
        description: "Bound on the gyro-bias estimate",
    },
    ParamMeta {
        name: "ATT_W_ACC",
        key: "accel_weight",
        unit: "",
        default: 1.0,
        min: 0.001,
        max: 100.0,
        description: "Wahba weight of the accelerometer vector, Castillo (80)",
    },
    ParamMeta {
        name: "ATT_W_MAG",
        key: "mag_weight",
        unit: "",
        default: 0.1,
        min: 0.001,
        max: 100.0,
        description: "Wahba weight of the magnetometer vector, Castillo (80)",
    },
    ParamMeta {
        name: "ATT_ACC_SOFT",
        key: "accel_deweight_g",
        unit: "g",
        default: 0.05,
        min: 0.0,
        max: 2.0,
        description: "Specific-force error where the accelerometer weight starts to fall",
    },
    ParamMeta {
        name: "ATT_ACC_GATE",
        key: "accel_gate_g",
        unit: "g",
        default: 0.3,
        min: 0.01,
        max: 3.0,
        description: "Specific-force error beyond which the accelerometer is not used",
    },
    ParamMeta {
        name: "ATT_ALIGN_N",
        key: "align_samples",
        unit: "samples",
        default: 250.0,
        min: 1.0,
        max: 10000.0,
        description: "IMU samples averaged for the initial alignment at rest",
    },
    ParamMeta {
        name: "ATT_MAX_DR_T",
        key: "max_uncorrected_s",
        unit: "s",
        default: 0.5,
        min: 0.01,
        max: 60.0,
        description: "Longest gyro-only propagation before the attitude is flagged invalid",
    },
    ParamMeta {
        name: "ATT_MAG_INC",
        key: "mag_inclination_deg",
        unit: "deg",
        default: 63.3,
        min: -90.0,
        max: 90.0,
        description: "Magnetic inclination at the flying site",
    },
    ParamMeta {
        name: "ATT_MAG_DEC",
        key: "mag_declination_deg",
        unit: "deg",
        default: 3.0,
        min: -180.0,
        max: 180.0,
        description: "Magnetic declination at the flying site",
    },
];

impl AttitudeParams {
    /// Every out-of-range value.
    pub fn validate(&self) -> Vec<ParamViolation> {
        let mut v = Vec::new();
        let m = ATTITUDE_META;
        check(&mut v, "attitude", m, "observer_gain", self.observer_gain);
        check(&mut v, "attitude", m, "bias_gain", self.bias_gain);
        check(
            &mut v,
            "attitude",
            m,
            "bias_limit_rad_s",
            self.bias_limit_rad_s,
        );
        check(&mut v, "attitude", m, "accel_weight", self.accel_weight);
        check(&mut v, "attitude", m, "mag_weight", self.mag_weight);
        check(
            &mut v,
            "attitude",
            m,
            "accel_deweight_g",
            self.accel_deweight_g,
        );
        check(&mut v, "attitude", m, "accel_gate_g", self.accel_gate_g);
        check(
            &mut v,
            "attitude",
            m,
            "align_samples",
            self.align_samples as f64,
        );
        check(
            &mut v,
            "attitude",
            m,
            "max_uncorrected_s",
            self.max_uncorrected_s,
        );
        check(
            &mut v,
            "attitude",
            m,
            "mag_inclination_deg",
            self.mag_inclination_deg,
        );
        check(
            &mut v,
            "attitude",
            m,
            "mag_declination_deg",
            self.mag_declination_deg,
        );
        if self.accel_deweight_g >= self.accel_gate_g {
            v.push(ParamViolation {
                key: "attitude.accel_deweight_g".into(),
                reason: format!("must be below accel_gate_g ({})", self.accel_gate_g),
            });
        }
        for (k, arr) in [
            ("mag_offset", &self.mag_offset),
            ("mag_rotation_rad", &self.mag_rotation_rad),
        ] {
            if arr.iter().any(|x| !x.is_finite()) {
                v.push(ParamViolation {
                    key: format!("attitude.{k}"),
                    reason: "must be finite".into(),
                });
            }
        }
        if self.mag_scale.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            v.push(ParamViolation {
                key: "attitude.mag_scale".into(),
                reason: "every scale must be > 0".into(),
            });
        }
        v
    }

    /// The magnetometer calibration these parameters describe.
    pub fn mag_calibration(&self) -> crate::estimator::attitude::MagCalibration {
        let r = Rotation3::from_scaled_axis(Vector3::from(self.mag_rotation_rad));
        crate::estimator::attitude::MagCalibration::from_ellipsoid(
            Vector3::from(self.mag_offset),
            r.matrix(),
            &Vector3::from(self.mag_scale),
        )
    }

    /// Unit Earth-field direction in NED from inclination and declination.
    pub fn earth_field_ned(&self) -> Vector3<f64> {
        let (si, ci) = self.mag_inclination_deg.to_radians().sin_cos();
        let (sd, cd) = self.mag_declination_deg.to_radians().sin_cos();
        Vector3::new(ci * cd, ci * sd, si)
    }
}

/// The rotation matrix of a rotation vector (a helper for calibration tests and tools).
pub fn rotation_matrix(rotation_vector: &Vector3<f64>) -> Matrix3<f64> {
    *Rotation3::from_scaled_axis(*rotation_vector).matrix()
}

/// Declares a parameter group once: the serde struct (defaults, unknown keys refused), its
/// `Default`, the metadata table (MAVLink name, unit, range, description) and `validate()`.
macro_rules! param_group {
    (
        $(#[$doc:meta])* $name:ident, $group:literal, $meta:ident {
            $( $(#[$fdoc:meta])* $field:ident : $ty:ty = $default:expr,
               $mav:literal, $unit:literal, [$min:expr, $max:expr], $desc:literal; )*
        }
    ) => {
        $(#[$doc])*
        #[derive(Debug, Clone, PartialEq, Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct $name {
            $( $(#[$fdoc])* pub $field: $ty, )*
        }

        impl Default for $name {
            fn default() -> Self {
                Self { $( $field: $default, )* }
            }
        }

        /// Metadata of this group.
        pub const $meta: &[ParamMeta] = &[
            $( ParamMeta { name: $mav, key: stringify!($field), unit: $unit, default: $default as f64, min: $min, max: $max, description: $desc }, )*
        ];

        impl $name {
            /// Every out-of-range value, with its key and range.
            pub fn validate(&self) -> Vec<ParamViolation> {
                let mut v = Vec::new();
                $( check(&mut v, $group, $meta, stringify!($field), self.$field as f64); )*
                v
            }
        }
    };
}

param_group! {
    /// Translation estimator (position and velocity from accelerometer, GPS and barometer).
    TranslationGroup, "translation", TRANSLATION_META {
        /// Horizontal time constant.
        tau_xy_s: f64 = 2.5, "EST_XY_TAU", "s", [0.2, 30.0], "Horizontal complementary-filter time constant: larger trusts the accelerometer longer";
        /// Vertical time constant.
        tau_z_s: f64 = 1.0, "EST_Z_TAU", "s", [0.2, 30.0], "Vertical (barometer) complementary-filter time constant";
        /// GPS velocity correction time constant.
        tau_vel_s: f64 = 0.5, "EST_VEL_TAU", "s", [0.05, 30.0], "GPS velocity correction time constant";
        /// GPS latency.
        gps_delay_s: f64 = 0.1, "EST_GPS_DELAY", "s", [0.0, 0.5], "Age of a GPS solution when it arrives";
        /// Worst GPS accuracy accepted.
        gps_max_h_acc_m: f64 = 5.0, "EST_GPS_MAX_ACC", "m", [0.1, 100.0], "Worst horizontal accuracy accepted from the GPS";
        /// GPS timeout.
        gps_timeout_s: f64 = 1.0, "EST_GPS_TOUT", "s", [0.1, 10.0], "Local position is invalid after this long without GPS";
        /// Barometer timeout.
        baro_timeout_s: f64 = 0.5, "EST_BARO_TOUT", "s", [0.05, 10.0], "Altitude is invalid after this long without the barometer";
        /// Accelerometer bias bound.
        accel_bias_limit: f64 = 1.0, "EST_ACC_B_MAX", "m/s^2", [0.0, 5.0], "Bound on the accelerometer bias estimate";
    }
}

param_group! {
    /// Position, velocity and altitude loops.
    PositionGroup, "position", POSITION_META {
        /// Horizontal position gain.
        k_pos_xy: f64 = 0.95, "MPC_XY_P", "1/s", [0.0, 5.0], "Horizontal position gain";
        /// Vertical position gain.
        k_pos_z: f64 = 1.0, "MPC_Z_P", "1/s", [0.0, 5.0], "Vertical position gain";
        /// Horizontal velocity gain.
        k_vel_xy: f64 = 1.8, "MPC_XY_VEL_P_ACC", "1/s", [0.0, 10.0], "Horizontal velocity proportional gain";
        /// Horizontal velocity integral gain.
        k_vel_i_xy: f64 = 0.4, "MPC_XY_VEL_I_ACC", "1/s^2", [0.0, 10.0], "Horizontal velocity integral gain";
        /// Vertical velocity gain.
        k_vel_z: f64 = 4.0, "MPC_Z_VEL_P_ACC", "1/s", [0.0, 20.0], "Vertical velocity proportional gain";
        /// Vertical velocity integral gain.
        k_vel_i_z: f64 = 2.0, "MPC_Z_VEL_I_ACC", "1/s^2", [0.0, 20.0], "Vertical velocity integral gain";
        /// Horizontal speed limit.
        max_speed_h: f64 = 5.0, "MPC_XY_VEL_MAX", "m/s", [0.5, 30.0], "Largest horizontal speed";
        /// Climb rate limit.
        max_speed_up: f64 = 3.0, "MPC_Z_VEL_MAX_UP", "m/s", [0.3, 10.0], "Largest climb rate";
        /// Descent rate limit.
        max_speed_down: f64 = 1.0, "MPC_Z_VEL_MAX_DN", "m/s", [0.3, 10.0], "Largest descent rate";
        /// Horizontal acceleration limit.
        max_accel_h: f64 = 4.0, "MPC_ACC_HOR_MAX", "m/s^2", [0.5, 15.0], "Largest horizontal acceleration";
        /// Vertical acceleration limit.
        max_accel_v: f64 = 4.0, "MPC_ACC_UP_MAX", "m/s^2", [0.5, 15.0], "Largest vertical acceleration";
        /// Tilt limit.
        max_tilt_deg: f64 = 35.0, "MPC_TILTMAX_AIR", "deg", [5.0, 80.0], "Largest tilt in position and altitude modes";
        /// Integral bound.
        i_limit: f64 = 3.0, "MPC_I_MAX", "m/s^2", [0.0, 10.0], "Bound on the velocity integral";
    }
}

param_group! {
    /// Attitude loop (Castillo's kinematic law (63) or Lewis's tilt/yaw PD).
    AttitudeControlGroup, "attitude_control", ATTITUDE_CONTROL_META {
        /// 0: Castillo's kinematic law over the rate loop; 1: Lewis's tilt/yaw PD moments.
        law: u32 = 0, "MC_ATT_LAW", "", [0.0, 1.0], "Attitude law: 0 Castillo kinematic (63) + rate loop, 1 Lewis tilt/yaw PD (4.19)-(4.21)";
        /// Castillo's k_k.
        k_k: f64 = 6.0, "MC_ATT_KK", "1/s", [0.1, 30.0], "Gain k_k of Castillo's kinematic law (63)";
        /// Yaw weight relative to tilt.
        yaw_weight: f64 = 0.4, "MC_YAW_WEIGHT", "", [0.0, 1.0], "Weight of the yaw error relative to tilt";
        /// Roll/pitch rate limit.
        max_tilt_rate_deg_s: f64 = 200.0, "MC_ROLLRATE_MAX", "deg/s", [10.0, 1800.0], "Largest roll and pitch rate reference";
        /// Yaw rate limit.
        max_yaw_rate_deg_s: f64 = 90.0, "MC_YAWRATE_MAX", "deg/s", [5.0, 1800.0], "Largest yaw rate reference";
        /// Lewis K_PH per unit inertia.
        pd_k_p_tilt: f64 = 36.0, "MC_PD_TILT_P", "1/s^2", [0.0, 500.0], "Lewis tilt proportional gain K_PH, per kg m^2 of inertia";
        /// Lewis K_DH per unit inertia.
        pd_k_d_tilt: f64 = 10.0, "MC_PD_TILT_D", "1/s", [0.0, 100.0], "Lewis tilt derivative gain K_DH, per kg m^2 of inertia";
        /// Lewis K_Pz per unit inertia.
        pd_k_p_yaw: f64 = 9.0, "MC_PD_YAW_P", "1/s^2", [0.0, 500.0], "Lewis yaw proportional gain K_Pz, per kg m^2 of inertia";
        /// Lewis K_Dz per unit inertia.
        pd_k_d_yaw: f64 = 5.0, "MC_PD_YAW_D", "1/s", [0.0, 100.0], "Lewis yaw derivative gain K_Dz, per kg m^2 of inertia";
    }
}

param_group! {
    /// Rate loop: LADRC (Castillo (69)-(73)) or PID.
    RateGroup, "rate", RATE_META {
        /// 0: LADRC; 1: PID.
        controller: u32 = 0, "MC_RATE_CTRL", "", [0.0, 1.0], "Rate controller: 0 LADRC (Castillo), 1 PID";
        /// LADRC feedback gain, roll and pitch.
        adrc_kd_rp: f64 = 12.0, "ADRC_RP_KD", "1/s", [0.5, 100.0], "LADRC feedback gain k_d (71)-(72), roll and pitch";
        /// LADRC feedback gain, yaw.
        adrc_kd_y: f64 = 6.0, "ADRC_Y_KD", "1/s", [0.5, 100.0], "LADRC feedback gain k_d, yaw";
        /// ESO bandwidth.
        adrc_beta: f64 = 60.0, "ADRC_BETA", "1/s", [5.0, 1000.0], "LADRC observer bandwidth beta (70); keep beta x sample time below ~1";
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
        /// PID derivative low-pass cut-off.
        pid_d_cutoff_hz: f64 = 30.0, "MC_DTERM_CUTOFF", "Hz", [1.0, 500.0], "PID derivative low-pass cut-off";
    }
}

param_group! {
    /// Rotor-speed loop (Lewis (4.40)-(4.41), (6.13)) when ESCs report rpm.
    MotorGroup, "motor", MOTOR_META {
        /// Speed PI proportional gain.
        k_p: f64 = 2e-4, "MOT_SPD_P", "1/(rad/s)", [0.0, 0.01], "Rotor-speed PI proportional gain (4.41)";
        /// Speed PI integral gain.
        k_i: f64 = 2e-3, "MOT_SPD_I", "1/rad", [0.0, 0.1], "Rotor-speed PI integral gain (4.40)-(4.41)";
        /// Gain-estimation rate.
        k_g: f64 = 2.0, "MOT_GAIN_KG", "1/s", [0.0, 20.0], "Motor-gain estimation rate K_g (6.13)";
        /// Integral bound.
        i_limit: f64 = 0.2, "MOT_SPD_IMAX", "", [0.0, 1.0], "Bound on the speed-loop integral (command)";
        /// Gain correction range.
        gain_range: f64 = 0.3, "MOT_GAIN_RANGE", "", [0.0, 0.9], "Largest relative correction of the motor gain";
    }
}

/// Every flight-core parameter, as in `params/flight.toml`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlightParams {
    /// Attitude estimator.
    pub attitude: AttitudeParams,
    /// Translation estimator.
    pub translation: TranslationGroup,
    /// Position loops.
    pub position: PositionGroup,
    /// Attitude loop.
    pub attitude_control: AttitudeControlGroup,
    /// Rate loop.
    pub rate: RateGroup,
    /// Rotor-speed loop.
    pub motor: MotorGroup,
}

impl FlightParams {
    /// Every out-of-range value of every group.
    pub fn validate(&self) -> Vec<ParamViolation> {
        let mut v = self.attitude.validate();
        v.extend(self.translation.validate());
        v.extend(self.position.validate());
        v.extend(self.attitude_control.validate());
        v.extend(self.rate.validate());
        v.extend(self.motor.validate());
        v
    }

    /// Every parameter's metadata, group by group.
    pub fn metadata() -> impl Iterator<Item = (&'static str, &'static ParamMeta)> {
        [
            ("attitude", ATTITUDE_META),
            ("translation", TRANSLATION_META),
            ("position", POSITION_META),
            ("attitude_control", ATTITUDE_CONTROL_META),
            ("rate", RATE_META),
            ("motor", MOTOR_META),
        ]
        .into_iter()
        .flat_map(|(g, m)| m.iter().map(move |p| (g, p)))
    }

    /// Reads and validates a parameter file; errors name the file, the key and the range.
    pub fn load(path: &std::path::Path) -> Result<Self, airframe::ConfigError> {
        let p: Self = airframe::config::read_toml(path)?;
        p.check(&path.display().to_string())
    }

    /// Parses and validates parameter TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, airframe::ConfigError> {
        let p: Self = airframe::config::parse_toml(text, origin)?;
        p.check(origin)
    }

    fn check(self, file: &str) -> Result<Self, airframe::ConfigError> {
        let violations = self.validate();
        if violations.is_empty() {
            Ok(self)
        } else {
            Err(airframe::ConfigError::Invalid {
                file: file.to_owned(),
                violations: violations
                    .into_iter()
                    .map(|v| airframe::Violation {
                        key: v.key,
                        reason: v.reason,
                    })
                    .collect(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_names_fit_mavlink() {
        assert!(AttitudeParams::default().validate().is_empty());
        for m in ATTITUDE_META {
            assert!(m.name.len() <= 16, "{}", m.name);
            assert!(m.min <= m.default && m.default <= m.max, "{}", m.name);
        }
    }

    #[test]
    fn every_parameter_has_a_unique_mavlink_name_that_fits_and_a_valid_default() {
        let mut names = std::collections::HashSet::new();
        let mut count = 0;
        for (group, m) in FlightParams::metadata() {
            assert!(
                m.name.len() <= 16 && !m.name.is_empty(),
                "{group}.{}: {}",
                m.key,
                m.name
            );
            assert!(names.insert(m.name), "duplicate MAVLink name {}", m.name);
            assert!(
                m.min <= m.default && m.default <= m.max,
                "{group}.{}",
                m.key
            );
            count += 1;
        }
        assert!(count >= 40, "{count}");
        assert!(FlightParams::default().validate().is_empty());
    }

    #[test]
    fn the_shipped_parameter_file_loads_and_bad_files_are_refused_naming_the_key() {
        let path =
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/flight.toml");
        assert_eq!(
            FlightParams::load(&path).unwrap(),
            FlightParams::default(),
            "params/flight.toml holds the defaults"
        );
        let err = FlightParams::from_toml_str("[position]\nmax_tilt_deg = 95.0\n", "f.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("f.toml: `position.max_tilt_deg`: must be within [5, 80] deg, got 95"),
            "{err}"
        );
        let err = FlightParams::from_toml_str("[rate]\nadrc_betta = 50.0\n", "f.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("adrc_betta"), "{err}");
        let err = FlightParams::from_toml_str("[motor]\nk_p = \"high\"\n", "f.toml")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("f.toml:") && err.contains("k_p"), "{err}");
    }

    #[test]
    fn every_violation_is_reported_with_its_range() {
        let p: AttitudeParams = toml::from_str(
            "observer_gain = -1.0\naccel_gate_g = 0.01\nmag_scale = [1.0, 0.0, 1.0]\n",
        )
        .unwrap();
        let v = p.validate();
        let keys: Vec<&str> = v.iter().map(|x| x.key.as_str()).collect();
        assert_eq!(
            keys,
            [
                "attitude.observer_gain",
                "attitude.accel_deweight_g",
                "attitude.mag_scale"
            ]
        );
        assert!(v[0].reason.contains("[0.05, 50] 1/s, got -1"));
        assert!(
            toml::from_str::<AttitudeParams>("observer_k = 1.0").is_err(),
            "unknown keys are refused"
        );
    }
}
