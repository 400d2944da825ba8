//! Parameters of the flight core.
//!
//! Each module declares its own group next to its code (`AttitudeParams` in
//! `estimator/attitude.rs`, the others through the `param_group!` macro): a serde struct with defaults
//! (`deny_unknown_fields`), a metadata table (MAVLink name of at most 16 characters, unit, range,
//! description) for the ground-station parameter protocol and the generated reference, and
//! `validate()` returning every violation. This module holds the shared pieces and
//! [`FlightParams`], the whole set as in `params/flight.toml`.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Deserialize;

/// One parameter's metadata.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamMeta {
    /// MAVLink name, at most 16 characters, stable, never reused.
    pub name: &'static str,
    /// Key in the TOML group.
    pub key: &'static str,
    /// Value type on the MAVLink parameter protocol.
    pub kind: ParamKind,
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

/// How a parameter travels on the MAVLink parameter protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamKind {
    /// `MAV_PARAM_TYPE_REAL32`.
    Real32,
    /// `MAV_PARAM_TYPE_INT32` (byte-wise encoded).
    Int32,
}

/// The MAVLink type of a parameter field's Rust type.
pub trait ParamValue {
    /// Its kind.
    const KIND: ParamKind;
}

impl ParamValue for f64 {
    const KIND: ParamKind = ParamKind::Real32;
}

impl ParamValue for u32 {
    const KIND: ParamKind = ParamKind::Int32;
}

impl ParamValue for i32 {
    const KIND: ParamKind = ParamKind::Int32;
}

/// A rejected parameter value.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamViolation {
    /// Key in the TOML group, e.g. `attitude.observer_gain`.
    pub key: String,
    /// Why, with the allowed range.
    pub reason: String,
}

pub(crate) fn check(
    out: &mut Vec<ParamViolation>,
    group: &str,
    meta: &[ParamMeta],
    key: &str,
    value: f64,
) {
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

/// The rotation matrix of a rotation vector (a helper for calibration tests and tools).
pub fn rotation_matrix(rotation_vector: &Vector3<f64>) -> Matrix3<f64> {
    *Rotation3::from_scaled_axis(*rotation_vector).matrix()
}

/// Declares a parameter group once: the serde struct (defaults, unknown keys refused), its
/// `Default`, the metadata table (MAVLink name, unit, range, description) and `validate()`.
macro_rules! param_group_impl {
    (
        $(#[$doc:meta])* $name:ident, $group:literal, $meta:ident {
            $( $(#[$fdoc:meta])* $field:ident : $ty:ty = $default:expr,
               $mav:literal, $unit:literal, [$min:expr, $max:expr], $desc:literal; )*
        }
    ) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
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
        pub const $meta: &[$crate::params::ParamMeta] = &[
            $( $crate::params::ParamMeta { name: $mav, key: stringify!($field), kind: <$ty as $crate::params::ParamValue>::KIND, unit: $unit, default: $default as f64, min: $min, max: $max, description: $desc }, )*
        ];

        impl $name {
            /// The value of the field `key`, if there is one.
            pub fn get(&self, key: &str) -> Option<f64> {
                match key {
                    $( stringify!($field) => Some(self.$field as f64), )*
                    _ => None,
                }
            }

            /// Sets the field `key` (unchecked: see `validate`); false if there is none.
            pub fn set(&mut self, key: &str, value: f64) -> bool {
                match key {
                    $( stringify!($field) => { self.$field = value as $ty; true } )*
                    _ => false,
                }
            }

            /// Every out-of-range value, with its key and range.
            pub fn validate(&self) -> Vec<$crate::params::ParamViolation> {
                let mut v = Vec::new();
                $( $crate::params::check(&mut v, $group, $meta, stringify!($field), self.$field as f64); )*
                v
            }
        }
    };
}
pub(crate) use param_group_impl as param_group;

pub use crate::commander::rc_input::{RC_META, RcGroup};
pub use crate::commander::{COMMANDER_META, CommanderParams};
pub use crate::control::attitude::{ATTITUDE_CONTROL_META, AttitudeControlGroup};
pub use crate::control::motor::{MOTOR_META, MotorGroup};
pub use crate::control::position::{POSITION_META, PositionGroup};
pub use crate::control::rate::{RATE_META, RateGroup};
pub use crate::estimator::attitude::{ATTITUDE_META, AttitudeParams};
pub use crate::estimator::translation::{TRANSLATION_META, TranslationGroup};
pub use crate::logger_params::{LOGGER_META, LoggerGroup};
pub use crate::safety::failsafe::{SAFETY_META, SafetyParams};
pub use crate::sensors::battery::{BATTERY_META, BatteryGroup};
pub use crate::sensors::imu_correction::{IMU_META, ImuCalParams};

/// Each group's title in the parameter reference, in [`FlightParams::metadata`]'s order.
const GROUP_TITLES: [(&str, &str); 12] = [
    ("attitude", "Attitude estimator"),
    ("translation", "Position and velocity estimator"),
    ("position", "Position loops"),
    ("attitude_control", "Attitude loop"),
    ("rate", "Rate loop"),
    ("motor", "Rotor-speed loop"),
    ("commander", "Commander: take-off, landing, return"),
    ("safety", "Failsafes and arming checks"),
    ("battery", "Flight battery"),
    ("imu", "IMU calibration and board mounting"),
    ("rc", "RC transmitter: sticks, switches, calibration"),
    ("logger", "Logs: runs kept, free space left"),
];

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
    /// Commander: take-off, landing, return.
    pub commander: CommanderParams,
    /// Failsafes and arming checks.
    pub safety: SafetyParams,
    /// The flight battery.
    pub battery: BatteryGroup,
    /// The gyro and accelerometer calibrations and the board's mounting angles.
    pub imu: ImuCalParams,
    /// The RC transmitter's sticks, switches and calibration.
    pub rc: RcGroup,
    /// The logs' share of their disk.
    pub logger: LoggerGroup,
}

/// Why a parameter value was refused (for the operator, `STATUSTEXT`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ParamRejection {
    /// No parameter has that name.
    Unknown(String),
    /// The value is NaN or infinite, not an integer for an integer parameter, out of its
    /// range, or inconsistent with another parameter.
    Invalid(String),
}

impl std::fmt::Display for ParamRejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Unknown(name) => write!(f, "no parameter {name}"),
            Self::Invalid(why) => f.write_str(why),
        }
    }
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
        v.extend(self.commander.validate());
        v.extend(self.safety.validate());
        v.extend(self.battery.validate());
        v.extend(self.imu.validate());
        v.extend(self.rc.validate());
        v.extend(self.logger.validate());
        v.extend(
            self.battery
                .inconsistencies()
                .into_iter()
                .map(|reason| ParamViolation {
                    key: "battery.v_empty".into(),
                    reason,
                }),
        );
        v.extend(
            self.safety
                .inconsistencies()
                .into_iter()
                .map(|reason| ParamViolation {
                    key: "safety.battery_low".into(),
                    reason,
                }),
        );
        v
    }

    /// The number of parameters in [`FlightParams::metadata`].
    pub fn count() -> usize {
        Self::metadata().count()
    }

    /// The index (in [`FlightParams::metadata`]'s order, stable for a build), group and
    /// metadata of the parameter called `name` on MAVLink.
    pub fn find(name: &str) -> Option<(usize, &'static str, &'static ParamMeta)> {
        Self::metadata()
            .enumerate()
            .find(|(_, (_, m))| m.name == name)
            .map(|(i, (g, m))| (i, g, m))
    }

    /// The value of `key` in `group`.
    pub fn get(&self, group: &str, key: &str) -> Option<f64> {
        match group {
            "attitude" => self.attitude.get(key),
            "translation" => self.translation.get(key),
            "position" => self.position.get(key),
            "attitude_control" => self.attitude_control.get(key),
            "rate" => self.rate.get(key),
            "motor" => self.motor.get(key),
            "commander" => self.commander.get(key),
            "safety" => self.safety.get(key),
            "battery" => self.battery.get(key),
            "imu" => self.imu.get(key),
            "rc" => self.rc.get(key),
            "logger" => self.logger.get(key),
            _ => None,
        }
    }

    fn set_field(&mut self, group: &str, key: &str, value: f64) -> bool {
        match group {
            "attitude" => self.attitude.set(key, value),
            "translation" => self.translation.set(key, value),
            "position" => self.position.set(key, value),
            "attitude_control" => self.attitude_control.set(key, value),
            "rate" => self.rate.set(key, value),
            "motor" => self.motor.set(key, value),
            "commander" => self.commander.set(key, value),
            "safety" => self.safety.set(key, value),
            "battery" => self.battery.set(key, value),
            "imu" => self.imu.set(key, value),
            "rc" => self.rc.set(key, value),
            "logger" => self.logger.set(key, value),
            _ => false,
        }
    }

    /// The value of the parameter called `name` on MAVLink.
    pub fn value(&self, name: &str) -> Option<f64> {
        let (_, group, m) = Self::find(name)?;
        self.get(group, m.key)
    }

    /// Sets the parameter called `name` on MAVLink, if `value` is finite, an integer for an
    /// integer parameter, within the parameter's range and consistent with the others;
    /// otherwise nothing changes and the rejection says why.
    pub fn set(&mut self, name: &str, value: f64) -> Result<(), ParamRejection> {
        self.set_many(&[(name, value)])
    }

    /// Sets several parameters together (a calibration's result), each checked as by
    /// [`FlightParams::set`] and the consistency once, after all: all of them change, or none.
    pub fn set_many(&mut self, values: &[(&str, f64)]) -> Result<(), ParamRejection> {
        let mut next = self.clone();
        for &(name, value) in values {
            let (_, group, m) =
                Self::find(name).ok_or_else(|| ParamRejection::Unknown(name.into()))?;
            let invalid = |why: String| Err(ParamRejection::Invalid(format!("{name}: {why}")));
            if !value.is_finite() {
                return invalid(format!("{value} is not a number"));
            }
            if m.kind == ParamKind::Int32 && value.fract() != 0.0 {
                return invalid(format!("{value} is not an integer"));
            }
            if !(m.min..=m.max).contains(&value) {
                return invalid(format!(
                    "{value} is outside [{}, {}] {}",
                    m.min, m.max, m.unit
                ));
            }
            next.set_field(group, m.key, value);
        }
        if let Some(v) = next.validate().into_iter().next() {
            let names: Vec<&str> = values.iter().map(|(n, _)| *n).collect();
            return Err(ParamRejection::Invalid(format!(
                "{}: {}",
                names.join(", "),
                v.reason
            )));
        }
        *self = next;
        Ok(())
    }

    /// A group's title (`position`: "Position loops").
    pub fn group_title(group: &str) -> &str {
        GROUP_TITLES
            .iter()
            .find(|(name, _)| *name == group)
            .map_or(group, |(_, t)| t)
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
            ("commander", COMMANDER_META),
            ("safety", SAFETY_META),
            ("battery", BATTERY_META),
            ("imu", IMU_META),
            ("rc", RC_META),
            ("logger", LOGGER_META),
        ]
        .into_iter()
        .flat_map(|(g, m)| m.iter().map(move |p| (g, p)))
    }

    /// `params/README.md`: every parameter's MAVLink name, TOML key, type, unit, default, range
    /// and description, group by group, from [`FlightParams::metadata`] (a test keeps the file
    /// in step).
    pub fn reference_markdown() -> String {
        use std::fmt::Write;
        let mut md = String::from(
            "# Parameter reference\n\n\
             Generated from the parameter metadata in `daemon/core/src` (regenerate with\n\
             `UPDATE_PARAM_REFERENCE=1 cargo test -p flight-core parameter_reference`; a test fails\n\
             when this file is stale). Each parameter is set on MAVLink by its name (QGroundControl's\n\
             parameter editor, `param set` in MAVProxy, `PARAM_SET`) or in `params/flight.toml` by its\n\
             group and key. Values out of range, NaN, or not an integer for an INT32 are refused.\n",
        );
        let mut group = "";
        for (g, m) in Self::metadata() {
            if g != group {
                group = g;
                let title = Self::group_title(g);
                let _ = write!(
                    md,
                    "\n## {title} (`[{g}]`)\n\n\
                     | Name | Key | Type | Unit | Default | Range | Description |\n\
                     |---|---|---|---|---|---|---|\n"
                );
            }
            let kind = match m.kind {
                ParamKind::Real32 => "REAL32",
                ParamKind::Int32 => "INT32",
            };
            let _ = writeln!(
                md,
                "| `{}` | `{}` | {kind} | {} | {} | {} … {} | {} |",
                m.name,
                m.key,
                m.unit,
                m.default,
                m.min,
                m.max,
                m.description.replace('|', "\\|")
            );
        }
        md
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
mod tests;
