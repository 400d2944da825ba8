//! `SYS_STATUS`.

use super::prelude::*;

/// `SYS_STATUS` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let t = s.t;
    let att = s.att;
    let tr = s.tr;
    let status = s.status;
    let battery_v = s.v.map_or(0.0, |v| v.battery_v);
    let battery = s.v.map(|v| v.battery).unwrap_or_default();
    let present = sensors_present();
    let mut health = present;
    if !att.is_some_and(|a| a.valid) {
        health -= MavSysStatusSensor::MAV_SYS_STATUS_AHRS;
    }
    if !tr.is_some_and(|t| t.horizontal_valid) {
        health -= MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS;
    }
    if !tr.is_some_and(|t| t.vertical_valid) {
        health -= MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE;
    }
    // Each check's own bit, from the failsafe condition that watches it.
    use MavSysStatusSensor as S;
    for (c, bits) in [
        (
            Condition::ImuLost,
            S::MAV_SYS_STATUS_SENSOR_3D_GYRO | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL,
        ),
        (Condition::MagLost, S::MAV_SYS_STATUS_SENSOR_3D_MAG),
        (
            Condition::BaroLost,
            S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE,
        ),
        (Condition::GpsLost, S::MAV_SYS_STATUS_SENSOR_GPS),
        (Condition::AttitudeInvalid, S::MAV_SYS_STATUS_AHRS),
        (
            Condition::PositionInvalid,
            S::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL,
        ),
        (
            Condition::AltitudeInvalid,
            S::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL,
        ),
        (Condition::BatteryCritical, S::MAV_SYS_STATUS_SENSOR_BATTERY),
        (
            Condition::BatteryEmergency,
            S::MAV_SYS_STATUS_SENSOR_BATTERY,
        ),
        (Condition::GeofenceBreach, S::MAV_SYS_STATUS_GEOFENCE),
        (
            Condition::MotorFailure,
            S::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS,
        ),
        (
            Condition::Crash,
            S::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION,
        ),
    ] {
        if acting(t, c) {
            health -= bits;
        }
    }
    if status.is_some_and(|s| !s.armed && s.prearm_ok) {
        health |= MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK;
    }
    // Manual control (a joystick through MANUAL_CONTROL) as PX4 reports its RC: present
    // once it has been seen, healthy while it arrives.
    let mut extra = MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK;
    if let Some(s) = status
        && s.manual_control.is_some()
    {
        extra |= MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_RC_RECEIVER;
        if s.manual_control == Some(true) {
            health |= MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_RC_RECEIVER;
        }
    }
    Some(MavMessage::SYS_STATUS(SYS_STATUS_DATA {
        onboard_control_sensors_present: present | extra,
        onboard_control_sensors_enabled: present | extra,
        onboard_control_sensors_health: health,
        voltage_battery: (battery_v * 1e3).clamp(0.0, 65534.0) as u16,
        current_battery: centiamps(battery.current_a),
        battery_remaining: percent(battery.remaining),
        // (The crate's default for these is its first flag, a recovery system.)
        onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
        onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
        onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
        ..Default::default()
    }))
}
