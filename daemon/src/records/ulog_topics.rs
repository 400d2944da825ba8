//! The topics of the ULog flight log: PX4's uORB names and fields where the same quantity
//! exists (so Flight Review's and PlotJuggler's PX4 layouts show the flight), in the order of
//! their message ids, and the rate each is logged at.

use crate::records::ulog::{Field, Format, Scalar::*, array, field};
use flight_core::commander::FlightMode;

const fn topic(name: &'static str, fields: &'static [Field]) -> Format {
    Format { name, fields }
}

pub(super) const SENSOR_COMBINED: Format = topic(
    "sensor_combined",
    &[
        field(U64, "timestamp"),
        array(F32, 3, "gyro_rad"),
        field(U32, "gyro_integral_dt"),
        field(I32, "accelerometer_timestamp_relative"),
        array(F32, 3, "accelerometer_m_s2"),
        field(U32, "accelerometer_integral_dt"),
    ],
);
pub(super) const VEHICLE_ATTITUDE: Format = topic(
    "vehicle_attitude",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        array(F32, 4, "q"),
    ],
);
pub(super) const VEHICLE_ANGULAR_VELOCITY: Format = topic(
    "vehicle_angular_velocity",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        array(F32, 3, "xyz"),
    ],
);
pub(super) const VEHICLE_RATES_SETPOINT: Format = topic(
    "vehicle_rates_setpoint",
    &[
        field(U64, "timestamp"),
        field(F32, "roll"),
        field(F32, "pitch"),
        field(F32, "yaw"),
        array(F32, 3, "thrust_body"),
    ],
);
pub(super) const VEHICLE_ATTITUDE_SETPOINT: Format = topic(
    "vehicle_attitude_setpoint",
    &[
        field(U64, "timestamp"),
        field(F32, "yaw_sp_move_rate"),
        array(F32, 4, "q_d"),
        array(F32, 3, "thrust_body"),
    ],
);
/// PX4's `actuator_motors` holds 12 motors.
pub(super) const MOTORS: usize = 12;
/// And `actuator_outputs` 16 outputs.
pub(super) const OUTPUTS: usize = 16;
pub(super) const ACTUATOR_MOTORS: Format = topic(
    "actuator_motors",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        array(F32, MOTORS, "control"),
        field(U16, "reversible_flags"),
    ],
);
pub(super) const ACTUATOR_OUTPUTS: Format = topic(
    "actuator_outputs",
    &[
        field(U64, "timestamp"),
        array(F32, OUTPUTS, "output"),
        field(U32, "noutputs"),
    ],
);
pub(super) const VEHICLE_LOCAL_POSITION: Format = topic(
    "vehicle_local_position",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        field(U64, "ref_timestamp"),
        field(F64, "ref_lat"),
        field(F64, "ref_lon"),
        field(F32, "x"),
        field(F32, "y"),
        field(F32, "z"),
        field(F32, "vx"),
        field(F32, "vy"),
        field(F32, "vz"),
        field(F32, "ax"),
        field(F32, "ay"),
        field(F32, "az"),
        field(F32, "heading"),
        field(F32, "ref_alt"),
        field(Bool, "xy_valid"),
        field(Bool, "z_valid"),
        field(Bool, "v_xy_valid"),
        field(Bool, "v_z_valid"),
        field(Bool, "xy_global"),
        field(Bool, "z_global"),
    ],
);
pub(super) const VEHICLE_GLOBAL_POSITION: Format = topic(
    "vehicle_global_position",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        field(F64, "lat"),
        field(F64, "lon"),
        field(F32, "alt"),
        field(Bool, "lat_lon_valid"),
        field(Bool, "alt_valid"),
    ],
);
pub(super) const VEHICLE_LOCAL_POSITION_SETPOINT: Format = topic(
    "vehicle_local_position_setpoint",
    &[
        field(U64, "timestamp"),
        field(F32, "x"),
        field(F32, "y"),
        field(F32, "z"),
        field(F32, "yaw"),
        field(F32, "vx"),
        field(F32, "vy"),
        field(F32, "vz"),
        array(F32, 3, "acceleration"),
    ],
);
pub(super) const VEHICLE_GPS_POSITION: Format = topic(
    "vehicle_gps_position",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        field(U64, "time_utc_usec"),
        field(F64, "latitude_deg"),
        field(F64, "longitude_deg"),
        field(F64, "altitude_msl_m"),
        field(F32, "eph"),
        field(F32, "epv"),
        field(F32, "hdop"),
        field(F32, "vdop"),
        field(F32, "s_variance_m_s"),
        field(F32, "c_variance_rad"),
        field(F32, "vel_m_s"),
        field(F32, "vel_n_m_s"),
        field(F32, "vel_e_m_s"),
        field(F32, "vel_d_m_s"),
        field(F32, "cog_rad"),
        field(U8, "fix_type"),
        field(U8, "satellites_used"),
        field(Bool, "vel_ned_valid"),
    ],
);
pub(super) const VEHICLE_AIR_DATA: Format = topic(
    "vehicle_air_data",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        field(F32, "baro_alt_meter"),
    ],
);
pub(super) const VEHICLE_MAGNETOMETER: Format = topic(
    "vehicle_magnetometer",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        array(F32, 3, "magnetometer_ga"),
    ],
);
pub(super) const BATTERY_STATUS: Format = topic(
    "battery_status",
    &[
        field(U64, "timestamp"),
        field(F32, "voltage_v"),
        field(F32, "current_a"),
        field(F32, "discharged_mah"),
        field(F32, "remaining"),
        field(F32, "time_remaining_s"),
        field(Bool, "connected"),
    ],
);
pub(super) const ESTIMATOR_STATUS: Format = topic(
    "estimator_status",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        array(F32, 3, "gyro_bias"),
        // PX4 logs it in `estimator_sensor_bias`: the accelerometer's bias learned in flight.
        array(F32, 3, "accel_bias"),
        field(F32, "pos_horiz_accuracy"),
        field(F32, "time_slip"),
        field(U8, "health_flags"),
        field(U8, "timeout_flags"),
    ],
);
pub(super) const VEHICLE_STATUS: Format = topic(
    "vehicle_status",
    &[
        field(U64, "timestamp"),
        field(U64, "armed_time"),
        field(U64, "takeoff_time"),
        field(U64, "nav_state_timestamp"),
        field(U8, "arming_state"),
        field(U8, "nav_state"),
        field(U8, "vehicle_type"),
        field(Bool, "failsafe"),
        field(Bool, "is_vtol"),
        field(U8, "system_type"),
        field(U8, "system_id"),
        field(U8, "component_id"),
        field(Bool, "pre_flight_checks_pass"),
    ],
);
pub(super) const VEHICLE_LAND_DETECTED: Format = topic(
    "vehicle_land_detected",
    &[
        field(U64, "timestamp"),
        field(Bool, "ground_contact"),
        field(Bool, "maybe_landed"),
        field(Bool, "landed"),
    ],
);
/// PX4's `wind` (its estimator's wind): here the wind the outside force means.
pub(super) const WIND: Format = topic(
    "wind",
    &[
        field(U64, "timestamp"),
        field(U64, "timestamp_sample"),
        field(F32, "windspeed_north"),
        field(F32, "windspeed_east"),
        field(F32, "variance_north"),
        field(F32, "variance_east"),
    ],
);

/// Each topic's message id: its place in [`TOPICS`].
pub(super) mod id {
    /// `sensor_combined`.
    pub const SENSOR_COMBINED: usize = 0;
    /// `vehicle_attitude`.
    pub const VEHICLE_ATTITUDE: usize = 1;
    /// `vehicle_angular_velocity`.
    pub const VEHICLE_ANGULAR_VELOCITY: usize = 2;
    /// `vehicle_rates_setpoint`.
    pub const VEHICLE_RATES_SETPOINT: usize = 3;
    /// `vehicle_attitude_setpoint`.
    pub const VEHICLE_ATTITUDE_SETPOINT: usize = 4;
    /// `actuator_motors`.
    pub const ACTUATOR_MOTORS: usize = 5;
    /// `actuator_outputs`.
    pub const ACTUATOR_OUTPUTS: usize = 6;
    /// `vehicle_local_position`.
    pub const VEHICLE_LOCAL_POSITION: usize = 7;
    /// `vehicle_global_position`.
    pub const VEHICLE_GLOBAL_POSITION: usize = 8;
    /// `vehicle_local_position_setpoint`.
    pub const VEHICLE_LOCAL_POSITION_SETPOINT: usize = 9;
    /// `vehicle_gps_position`.
    pub const VEHICLE_GPS_POSITION: usize = 10;
    /// `vehicle_air_data`.
    pub const VEHICLE_AIR_DATA: usize = 11;
    /// `vehicle_magnetometer`.
    pub const VEHICLE_MAGNETOMETER: usize = 12;
    /// `battery_status`.
    pub const BATTERY_STATUS: usize = 13;
    /// `estimator_status`.
    pub const ESTIMATOR_STATUS: usize = 14;
    /// `vehicle_status`.
    pub const VEHICLE_STATUS: usize = 15;
    /// `vehicle_land_detected`.
    pub const VEHICLE_LAND_DETECTED: usize = 16;
    /// `wind`.
    pub const WIND: usize = 17;
}

/// The topics, in the order of their message ids.
pub(super) const TOPICS: [Format; 18] = [
    SENSOR_COMBINED,
    VEHICLE_ATTITUDE,
    VEHICLE_ANGULAR_VELOCITY,
    VEHICLE_RATES_SETPOINT,
    VEHICLE_ATTITUDE_SETPOINT,
    ACTUATOR_MOTORS,
    ACTUATOR_OUTPUTS,
    VEHICLE_LOCAL_POSITION,
    VEHICLE_GLOBAL_POSITION,
    VEHICLE_LOCAL_POSITION_SETPOINT,
    VEHICLE_GPS_POSITION,
    VEHICLE_AIR_DATA,
    VEHICLE_MAGNETOMETER,
    BATTERY_STATUS,
    ESTIMATOR_STATUS,
    VEHICLE_STATUS,
    VEHICLE_LAND_DETECTED,
    WIND,
];

/// Each topic's period (µs), as PX4's default logging profile spaces them: 0 for every sample
/// that carries it (GPS, barometer, magnetometer arrive at their own rates).
pub(super) const PERIOD_US: [u64; TOPICS.len()] = [
    10_000, 10_000, 10_000, 10_000, 10_000, 10_000, 10_000, // 100 Hz: IMU, attitude, outputs
    20_000, 20_000, 20_000, // 50 Hz: position and its set-point
    0, 0, 0, // as they come: GPS, barometer, magnetometer
    100_000, 100_000, // 10 Hz: battery, estimator
    1_000_000, 1_000_000, // 1 Hz, and at every change: status, land detector
    100_000,   // 10 Hz: wind, once known
];

/// `vehicle_status.nav_state` of a mode (PX4's `NAVIGATION_STATE_*`).
pub(super) fn nav_state(mode: FlightMode) -> u8 {
    match mode {
        FlightMode::Manual => 0,
        FlightMode::Altctl => 1,
        FlightMode::Posctl => 2,
        FlightMode::Mission => 3,
        FlightMode::Loiter => 4,
        FlightMode::Rtl => 5,
        FlightMode::Descend => 12,
        FlightMode::Offboard => 14,
        FlightMode::Stabilized => 15,
        FlightMode::Takeoff => 17,
        FlightMode::Land => 18,
        FlightMode::Orbit => 21,
        FlightMode::FollowTarget => 19,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::records::ulog::Scalar;

    #[test]
    fn every_topic_starts_with_its_timestamp_and_names_each_field_once() {
        for f in &TOPICS {
            assert_eq!(
                (f.fields[0].ty, f.fields[0].name),
                (Scalar::U64, "timestamp")
            );
            let mut names: Vec<_> = f.fields.iter().map(|x| x.name).collect();
            names.sort_unstable();
            names.dedup();
            assert_eq!(names.len(), f.fields.len(), "{}", f.name);
        }
        // The ids name their topics.
        for (i, name) in [
            (id::SENSOR_COMBINED, "sensor_combined"),
            (id::VEHICLE_GPS_POSITION, "vehicle_gps_position"),
            (id::VEHICLE_STATUS, "vehicle_status"),
            (id::VEHICLE_LAND_DETECTED, "vehicle_land_detected"),
        ] {
            assert_eq!(TOPICS[i].name, name);
        }
        let mut topics: Vec<_> = TOPICS.iter().map(|f| f.name).collect();
        topics.sort_unstable();
        topics.dedup();
        assert_eq!(topics.len(), TOPICS.len());
    }
}
