//! Telemetry streams, one MAVLink message per file (as PX4's `mavlink/streams/`): each builds
//! its message from the control loop's latest [`Telemetry`], a pure function of it and the
//! clock; [`build`] picks the one asked for.

use crate::modes;
use crate::telemetry::Telemetry;
use flight_core::autopilot::VehicleState;
use flight_core::commander::FlightMode;
use flight_core::core::StepOutput;
use flight_core::math::geo::LocalFrame;
use flight_core::safety::failsafe::{CONDITIONS, Condition};
use mavlink::MessageData;
use mavlink::dialects::common::*;

mod actuator_output_status;
mod altitude;
mod attitude;
mod attitude_quaternion;
mod attitude_target;
mod battery_status;
mod current_mode;
mod estimator_status;
mod extended_sys_state;
mod global_position_int;
mod gps_global_origin;
mod gps_raw_int;
mod highres_imu;
mod hil_state_quaternion;
mod home_position;
mod local_position_ned;
mod orbit_execution_status;
mod position_target_local_ned;
mod protocol_version;
mod radio_status;
mod rc_channels;
mod scaled_imu;
mod servo_output_raw;
mod sys_status;
mod system_time;
mod vfr_hud;
mod wind_cov;

/// What every stream file uses.
mod prelude {
    pub(super) use super::{
        StreamInput, acting, centiamps, e7, i16_sat, isa_pressure_hpa, percent, sensors_present,
    };
    pub(super) use crate::modes;
    pub(super) use flight_core::commander::{FlightMode, LandedState};
    pub(super) use flight_core::math::geo::LatLonAlt;
    pub(super) use flight_core::safety::failsafe::Condition;
    pub(super) use mavlink::dialects::common::*;
}

/// The latest telemetry with what most streams take from it.
#[derive(Clone, Copy)]
pub(super) struct StreamInput<'a> {
    /// The telemetry.
    pub(super) t: &'a Telemetry,
    /// Unix time (µs), for `SYSTEM_TIME`.
    pub(super) unix_usec: u64,
    /// The vehicle after its last step.
    pub(super) v: Option<&'a VehicleState>,
    /// The flight core's last output.
    pub(super) out: Option<&'a StepOutput>,
    /// Its attitude estimate.
    pub(super) att: Option<&'a flight_core::estimator::attitude::AttitudeEstimate>,
    /// Its translation estimate.
    pub(super) tr: Option<&'a flight_core::estimator::translation::TranslationEstimate>,
    /// The commander's state.
    pub(super) status: Option<&'a flight_core::commander::CommanderStatus>,
    /// The local frame of the estimate's origin, once set.
    pub(super) frame: Option<LocalFrame>,
    /// The vehicle's clock (ms, `time_boot_ms`).
    pub(super) ms: u32,
    /// The vehicle's clock (µs).
    pub(super) usec: u64,
}

/// Degrees as MAVLink's 1e7 integers.
pub(super) fn e7(deg: f64) -> i32 {
    (deg * 1e7).round() as i32
}

/// The vehicle's clock (`time_boot_ms`): its sensor time.
pub(super) fn boot_ms(t: &Telemetry) -> u32 {
    (t.link.t_s * 1e3) as u32
}

/// Whether the failsafe condition `c` is acting.
pub(super) fn acting(t: &Telemetry, c: Condition) -> bool {
    let mask = t.status().map_or(0, |s| s.failsafe_conditions);
    CONDITIONS
        .iter()
        .position(|k| *k == c)
        .is_some_and(|k| mask & (1 << k) != 0)
}

/// Percent for MAVLink's `battery_remaining` (−1: unknown).
pub(super) fn percent(remaining: Option<f64>) -> i8 {
    remaining.map_or(-1, |r| (r * 100.0).round().clamp(0.0, 100.0) as i8)
}

/// Centiamperes for MAVLink's `current_battery` (−1: not measured).
pub(super) fn centiamps(current_a: Option<f64>) -> i16 {
    current_a.map_or(-1, |i| (i * 100.0).round().clamp(0.0, 32_767.0) as i16)
}

/// The sensors and loops `SYS_STATUS` reports, all present and enabled.
pub(super) fn sensors_present() -> MavSysStatusSensor {
    MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_ACCEL
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_MAG
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_YAW_POSITION
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        | MavSysStatusSensor::MAV_SYS_STATUS_AHRS
        | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_BATTERY
        | MavSysStatusSensor::MAV_SYS_STATUS_GEOFENCE
}

/// Whether the vehicle flies itself in `mode` (PX4's AUTO modes).
pub(super) fn is_auto(mode: FlightMode) -> bool {
    matches!(
        mode,
        FlightMode::Takeoff
            | FlightMode::Loiter
            | FlightMode::Mission
            | FlightMode::Rtl
            | FlightMode::Land
            | FlightMode::Descend
            | FlightMode::FollowTarget
    )
}

/// ISA pressure (hPa) at a pressure altitude (m).
pub(super) fn isa_pressure_hpa(alt_m: f64) -> f64 {
    1013.25 * (1.0 - 2.255_77e-5 * alt_m).max(0.0).powf(5.255_88)
}

/// Saturating conversion to `i16`.
pub(super) fn i16_sat(x: f64) -> i16 {
    x.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16
}

/// The message with id `id` from the latest telemetry, if there is data for it.
pub fn build(id: u32, t: &Telemetry, unix_usec: u64) -> Option<MavMessage> {
    let v = t.vehicle.as_ref();
    let out = v.and_then(|v| v.estimate.as_ref());
    let tr = out.map(|o| &o.translation);
    let s = StreamInput {
        t,
        unix_usec,
        v,
        out,
        att: out.and_then(|o| o.attitude.as_ref()),
        tr,
        status: v.map(|v| &v.status),
        frame: tr.and_then(|tr| tr.origin).map(LocalFrame::new),
        ms: boot_ms(t),
        usec: (t.link.t_s * 1e6) as u64,
    };
    match id {
        SYS_STATUS_DATA::ID => sys_status::message(&s),
        EXTENDED_SYS_STATE_DATA::ID => extended_sys_state::message(&s),
        ATTITUDE_DATA::ID => attitude::message(&s),
        ATTITUDE_QUATERNION_DATA::ID => attitude_quaternion::message(&s),
        LOCAL_POSITION_NED_DATA::ID => local_position_ned::message(&s),
        GLOBAL_POSITION_INT_DATA::ID => global_position_int::message(&s),
        GPS_RAW_INT_DATA::ID => gps_raw_int::message(&s),
        VFR_HUD_DATA::ID => vfr_hud::message(&s),
        BATTERY_STATUS_DATA::ID => battery_status::message(&s),
        HOME_POSITION_DATA::ID => home_position::message(&s),
        ALTITUDE_DATA::ID => altitude::message(&s),
        SYSTEM_TIME_DATA::ID => system_time::message(&s),
        CURRENT_MODE_DATA::ID => current_mode::message(&s),
        HIGHRES_IMU_DATA::ID => highres_imu::message(&s),
        SCALED_IMU_DATA::ID => scaled_imu::message(&s),
        ESTIMATOR_STATUS_DATA::ID => estimator_status::message(&s),
        SERVO_OUTPUT_RAW_DATA::ID => servo_output_raw::message(&s),
        ACTUATOR_OUTPUT_STATUS_DATA::ID => actuator_output_status::message(&s),
        ATTITUDE_TARGET_DATA::ID => attitude_target::message(&s),
        POSITION_TARGET_LOCAL_NED_DATA::ID => position_target_local_ned::message(&s),
        HIL_STATE_QUATERNION_DATA::ID => hil_state_quaternion::message(&s),
        GPS_GLOBAL_ORIGIN_DATA::ID => gps_global_origin::message(&s),
        PROTOCOL_VERSION_DATA::ID => protocol_version::message(&s),
        ORBIT_EXECUTION_STATUS_DATA::ID => orbit_execution_status::message(&s),
        WIND_COV_DATA::ID => wind_cov::message(&s),
        RC_CHANNELS_DATA::ID => rc_channels::message(&s),
        RADIO_STATUS_DATA::ID => radio_status::message(&s),
        _ => None,
    }
}

/// Messages sent only when asked for (`REQUEST_MESSAGE`, or a rate through
/// `SET_MESSAGE_INTERVAL`): sensor, estimator and output detail, and SITL's truth.
pub const ON_REQUEST: [u32; 8] = [
    GPS_GLOBAL_ORIGIN_DATA::ID,
    PROTOCOL_VERSION_DATA::ID,
    HIGHRES_IMU_DATA::ID,
    SCALED_IMU_DATA::ID,
    ESTIMATOR_STATUS_DATA::ID,
    SERVO_OUTPUT_RAW_DATA::ID,
    ACTUATOR_OUTPUT_STATUS_DATA::ID,
    HIL_STATE_QUATERNION_DATA::ID,
];

/// The vehicle as `HEARTBEAT` shows it.
pub fn heartbeat(t: &Telemetry, mav_type: MavType) -> MavMessage {
    let status = t.status();
    let armed = status.is_some_and(|s| s.armed);
    let mode = status.map_or(FlightMode::Loiter, |s| s.mode);
    let mut base_mode = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    if armed {
        base_mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    if mode != FlightMode::Manual {
        base_mode |= MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
    }
    if is_auto(mode) {
        base_mode |=
            MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED;
    }
    let system_status = match status {
        None => MavState::MAV_STATE_BOOT,
        Some(s) if s.failsafe => MavState::MAV_STATE_CRITICAL,
        Some(s) if s.armed => MavState::MAV_STATE_ACTIVE,
        Some(_) => MavState::MAV_STATE_STANDBY,
    };
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: modes::custom_mode(mode),
        mavtype: mav_type,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode,
        system_status,
        mavlink_version: 3,
    })
}

/// `AVAILABLE_MODES` for the mode at `index` (1-based) of [`modes::SELECTABLE`].
pub fn available_mode(index: usize) -> Option<MavMessage> {
    let mode = *modes::SELECTABLE.get(index.checked_sub(1)?)?;
    let mut properties = MavModeProperty::empty();
    if matches!(mode, FlightMode::Manual | FlightMode::Stabilized) {
        properties |= MavModeProperty::MAV_MODE_PROPERTY_ADVANCED;
    }
    if is_auto(mode) {
        properties |= MavModeProperty::MAV_MODE_PROPERTY_AUTO_MODE;
    }
    Some(MavMessage::AVAILABLE_MODES(AVAILABLE_MODES_DATA {
        custom_mode: modes::custom_mode(mode),
        properties,
        number_modes: modes::SELECTABLE.len() as u8,
        mode_index: index as u8,
        standard_mode: modes::standard_mode(mode),
        mode_name: mode.name().into(),
    }))
}
