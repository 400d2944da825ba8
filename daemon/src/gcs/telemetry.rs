//! Telemetry messages built from the control loop's latest [`Telemetry`]: pure functions of it
//! and the clock.

use crate::control_loop::Telemetry;
use crate::gcs::modes;
use flight_core::commander::{FlightMode, LandedState};
use flight_core::math::geo::{LatLonAlt, LocalFrame};
use flight_core::safety::failsafe::{CONDITIONS, Condition};
use mavlink::MessageData;
use mavlink::dialects::common::*;

/// Degrees as MAVLink's 1e7 integers.
fn e7(deg: f64) -> i32 {
    (deg * 1e7).round() as i32
}

/// The vehicle's clock (`time_boot_ms`): its sensor time.
fn boot_ms(t: &Telemetry) -> u32 {
    (t.t_s * 1e3) as u32
}

/// Whether the failsafe condition `c` is acting.
fn acting(t: &Telemetry, c: Condition) -> bool {
    let mask = t.status.map_or(0, |s| s.failsafe_conditions);
    CONDITIONS
        .iter()
        .position(|k| *k == c)
        .is_some_and(|k| mask & (1 << k) != 0)
}

/// Percent for MAVLink's `battery_remaining` (−1: unknown).
fn percent(remaining: Option<f64>) -> i8 {
    remaining.map_or(-1, |r| (r * 100.0).round().clamp(0.0, 100.0) as i8)
}

/// Centiamperes for MAVLink's `current_battery` (−1: not measured).
fn centiamps(current_a: Option<f64>) -> i16 {
    current_a.map_or(-1, |i| (i * 100.0).round().clamp(0.0, 32_767.0) as i16)
}

/// The sensors and loops `SYS_STATUS` reports, all present and enabled.
fn sensors_present() -> MavSysStatusSensor {
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
fn is_auto(mode: FlightMode) -> bool {
    matches!(
        mode,
        FlightMode::Takeoff
            | FlightMode::Loiter
            | FlightMode::Mission
            | FlightMode::Rtl
            | FlightMode::Land
            | FlightMode::Descend
    )
}

/// The vehicle as `HEARTBEAT` shows it.
pub fn heartbeat(t: &Telemetry, mav_type: MavType) -> MavMessage {
    let status = t.status;
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

/// The message with id `id` from the latest telemetry, if there is data for it.
pub fn build(id: u32, t: &Telemetry, unix_usec: u64) -> Option<MavMessage> {
    let out = t.output;
    let att = out.and_then(|o| o.attitude);
    let tr = out.map(|o| o.translation);
    let status = t.status;
    let frame = tr.and_then(|tr| tr.origin).map(LocalFrame::new);
    let ms = boot_ms(t);
    Some(match id {
        SYS_STATUS_DATA::ID => {
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
            MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                onboard_control_sensors_present: present | extra,
                onboard_control_sensors_enabled: present | extra,
                onboard_control_sensors_health: health,
                voltage_battery: (t.battery_v * 1e3).clamp(0.0, 65534.0) as u16,
                current_battery: centiamps(t.battery.current_a),
                battery_remaining: percent(t.battery.remaining),
                // (The crate's default for these is its first flag, a recovery system.)
                onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
                onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
                onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
                ..Default::default()
            })
        }
        EXTENDED_SYS_STATE_DATA::ID => {
            let landed = match status?.landed {
                LandedState::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
                LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
            };
            MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                landed_state: landed,
            })
        }
        ATTITUDE_DATA::ID => {
            let a = att?;
            let (roll, pitch, yaw) = a.q.euler_angles();
            let w = a.rate;
            MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                roll: roll as f32,
                pitch: pitch as f32,
                yaw: yaw as f32,
                rollspeed: w.x as f32,
                pitchspeed: w.y as f32,
                yawspeed: w.z as f32,
            })
        }
        ATTITUDE_QUATERNION_DATA::ID => {
            let a = att?;
            let q = a.q.quaternion();
            let w = a.rate;
            MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
                time_boot_ms: ms,
                q1: q.w as f32,
                q2: q.i as f32,
                q3: q.j as f32,
                q4: q.k as f32,
                rollspeed: w.x as f32,
                pitchspeed: w.y as f32,
                yawspeed: w.z as f32,
                repr_offset_q: [0.0; 4],
            })
        }
        LOCAL_POSITION_NED_DATA::ID => {
            let tr = tr.filter(|t| t.vertical_valid)?;
            let (p, v) = (tr.pos_ned_m, tr.vel_ned_m_s);
            MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms: ms,
                x: p.x as f32,
                y: p.y as f32,
                z: p.z as f32,
                vx: v.x as f32,
                vy: v.y as f32,
                vz: v.z as f32,
            })
        }
        GLOBAL_POSITION_INT_DATA::ID => {
            let tr = tr.filter(|t| t.horizontal_valid)?;
            let g = frame?.to_geodetic(&tr.pos_ned_m);
            let home_down = status.and_then(|s| s.home).map_or(0.0, |h| h.0.z);
            let v = tr.vel_ned_m_s * 100.0;
            let yaw = att.map_or(0.0, |a| a.q.euler_angles().2);
            MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: ms,
                lat: e7(g.lat_deg),
                lon: e7(g.lon_deg),
                alt: (g.alt_m * 1e3).round() as i32,
                relative_alt: ((home_down - tr.pos_ned_m.z) * 1e3).round() as i32,
                vx: v.x.clamp(-32767.0, 32767.0) as i16,
                vy: v.y.clamp(-32767.0, 32767.0) as i16,
                vz: v.z.clamp(-32767.0, 32767.0) as i16,
                hdg: (yaw.to_degrees().rem_euclid(360.0) * 100.0) as u16,
            })
        }
        GPS_RAW_INT_DATA::ID => {
            let g = t.gps?;
            let speed = g.vel_ned_m_s.xy().norm();
            let cog = g.vel_ned_m_s.y.atan2(g.vel_ned_m_s.x).to_degrees();
            MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: (t.t_s * 1e6) as u64,
                lat: e7(g.position.lat_deg),
                lon: e7(g.position.lon_deg),
                alt: (g.position.alt_m * 1e3).round() as i32,
                eph: (g.h_acc_m * 100.0).clamp(0.0, 65534.0) as u16,
                epv: u16::MAX,
                vel: (speed * 100.0).clamp(0.0, 65534.0) as u16,
                cog: (cog.rem_euclid(360.0) * 100.0) as u16,
                fix_type: match g.fix_type {
                    0 => GpsFixType::GPS_FIX_TYPE_NO_GPS,
                    1 => GpsFixType::GPS_FIX_TYPE_NO_FIX,
                    2 => GpsFixType::GPS_FIX_TYPE_2D_FIX,
                    _ => GpsFixType::GPS_FIX_TYPE_3D_FIX,
                },
                satellites_visible: g.satellites,
                h_acc: (g.h_acc_m * 1e3) as u32,
                ..Default::default()
            })
        }
        VFR_HUD_DATA::ID => {
            let tr = tr?;
            let o = out?;
            let alt = frame.map_or(-tr.pos_ned_m.z, |f| f.to_geodetic(&tr.pos_ned_m).alt_m);
            let yaw = att.map_or(0.0, |a| a.q.euler_angles().2);
            let n = o.commands.iter().filter(|c| **c > 0.0).count().max(1);
            let throttle = o.commands.iter().sum::<f64>() / n as f64;
            MavMessage::VFR_HUD(VFR_HUD_DATA {
                airspeed: tr.vel_ned_m_s.xy().norm() as f32,
                groundspeed: tr.vel_ned_m_s.xy().norm() as f32,
                alt: alt as f32,
                climb: -tr.vel_ned_m_s.z as f32,
                heading: yaw.to_degrees().rem_euclid(360.0) as i16,
                throttle: (throttle * 100.0).clamp(0.0, 100.0) as u16,
            })
        }
        BATTERY_STATUS_DATA::ID => {
            let mut voltages = [u16::MAX; 10];
            voltages[0] = (t.battery_v * 1e3).clamp(0.0, 65534.0) as u16;
            let b = &t.battery;
            let charge_state = if acting(t, Condition::BatteryEmergency) {
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_EMERGENCY
            } else if acting(t, Condition::BatteryCritical) {
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_CRITICAL
            } else if acting(t, Condition::BatteryLow) {
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW
            } else if b.remaining.is_some() {
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK
            } else {
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED
            };
            MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                voltages,
                current_battery: centiamps(b.current_a),
                current_consumed: b.consumed_mah.map_or(-1, |q| q.round() as i32),
                energy_consumed: -1,
                temperature: i16::MAX,
                battery_remaining: percent(b.remaining),
                time_remaining: b.time_remaining_s.map_or(0, |s| s.round().max(1.0) as i32),
                charge_state,
                battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                ..Default::default()
            })
        }
        HOME_POSITION_DATA::ID => {
            let (home, yaw) = status?.home?;
            let g: LatLonAlt = frame?.to_geodetic(&home);
            let (s, c) = (yaw * 0.5).sin_cos();
            MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                latitude: e7(g.lat_deg),
                longitude: e7(g.lon_deg),
                altitude: (g.alt_m * 1e3).round() as i32,
                x: home.x as f32,
                y: home.y as f32,
                z: home.z as f32,
                q: [c as f32, 0.0, 0.0, s as f32],
                approach_x: 0.0,
                approach_y: 0.0,
                approach_z: 0.0,
                time_usec: (t.t_s * 1e6) as u64,
            })
        }
        ALTITUDE_DATA::ID => {
            let tr = tr.filter(|t| t.vertical_valid)?;
            let amsl = frame.map_or(f64::NAN, |f| f.to_geodetic(&tr.pos_ned_m).alt_m);
            let home_down = status.and_then(|s| s.home).map_or(0.0, |h| h.0.z);
            MavMessage::ALTITUDE(ALTITUDE_DATA {
                time_usec: (t.t_s * 1e6) as u64,
                altitude_monotonic: amsl as f32,
                altitude_amsl: amsl as f32,
                altitude_local: -tr.pos_ned_m.z as f32,
                altitude_relative: (home_down - tr.pos_ned_m.z) as f32,
                altitude_terrain: f32::NAN,
                bottom_clearance: f32::NAN,
            })
        }
        SYSTEM_TIME_DATA::ID => MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: unix_usec,
            time_boot_ms: ms,
        }),
        CURRENT_MODE_DATA::ID => {
            let mode = status.map_or(FlightMode::Loiter, |s| s.mode);
            MavMessage::CURRENT_MODE(CURRENT_MODE_DATA {
                custom_mode: modes::custom_mode(mode),
                intended_custom_mode: modes::custom_mode(mode),
                standard_mode: modes::standard_mode(mode),
            })
        }
        other => return detail(other, t),
    })
}

/// Messages sent only when asked for (`REQUEST_MESSAGE`, or a rate through
/// `SET_MESSAGE_INTERVAL`): sensor, estimator and output detail, and SITL's truth.
pub const ON_REQUEST: [u32; 6] = [
    HIGHRES_IMU_DATA::ID,
    SCALED_IMU_DATA::ID,
    ESTIMATOR_STATUS_DATA::ID,
    SERVO_OUTPUT_RAW_DATA::ID,
    ACTUATOR_OUTPUT_STATUS_DATA::ID,
    HIL_STATE_QUATERNION_DATA::ID,
];

/// ISA pressure (hPa) at a pressure altitude (m).
fn isa_pressure_hpa(alt_m: f64) -> f64 {
    1013.25 * (1.0 - 2.255_77e-5 * alt_m).max(0.0).powf(5.255_88)
}

/// Saturating conversion to `i16`.
fn i16_sat(x: f64) -> i16 {
    x.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16
}

/// The on-request messages ([`ON_REQUEST`]) from the latest telemetry, if there is data.
fn detail(id: u32, t: &Telemetry) -> Option<MavMessage> {
    let ms = boot_ms(t);
    let usec = (t.t_s * 1e6) as u64;
    let out = t.output;
    Some(match id {
        HIGHRES_IMU_DATA::ID => {
            let s = t.sample?;
            let mag = s.mag.unwrap_or(nalgebra::Vector3::repeat(f64::NAN));
            let alt = s.baro_alt_m.unwrap_or(f64::NAN);
            use HighresImuUpdatedFlags as F;
            MavMessage::HIGHRES_IMU(HIGHRES_IMU_DATA {
                time_usec: s.t_usec,
                xacc: s.accel.x as f32,
                yacc: s.accel.y as f32,
                zacc: s.accel.z as f32,
                xgyro: s.gyro.x as f32,
                ygyro: s.gyro.y as f32,
                zgyro: s.gyro.z as f32,
                xmag: mag.x as f32,
                ymag: mag.y as f32,
                zmag: mag.z as f32,
                abs_pressure: isa_pressure_hpa(alt) as f32,
                diff_pressure: 0.0,
                pressure_alt: alt as f32,
                temperature: f32::NAN,
                fields_updated: F::HIGHRES_IMU_UPDATED_XACC
                    | F::HIGHRES_IMU_UPDATED_YACC
                    | F::HIGHRES_IMU_UPDATED_ZACC
                    | F::HIGHRES_IMU_UPDATED_XGYRO
                    | F::HIGHRES_IMU_UPDATED_YGYRO
                    | F::HIGHRES_IMU_UPDATED_ZGYRO
                    | F::HIGHRES_IMU_UPDATED_XMAG
                    | F::HIGHRES_IMU_UPDATED_YMAG
                    | F::HIGHRES_IMU_UPDATED_ZMAG
                    | F::HIGHRES_IMU_UPDATED_ABS_PRESSURE
                    | F::HIGHRES_IMU_UPDATED_PRESSURE_ALT,
                id: 0,
            })
        }
        SCALED_IMU_DATA::ID => {
            // mg, mrad/s, mgauss.
            let s = t.sample?;
            let mg = |x: f64| i16_sat(x / flight_core::GRAVITY_M_S2 * 1e3);
            let mag = s.mag.unwrap_or_default() * 1e3;
            MavMessage::SCALED_IMU(SCALED_IMU_DATA {
                time_boot_ms: ms,
                xacc: mg(s.accel.x),
                yacc: mg(s.accel.y),
                zacc: mg(s.accel.z),
                xgyro: i16_sat(s.gyro.x * 1e3),
                ygyro: i16_sat(s.gyro.y * 1e3),
                zgyro: i16_sat(s.gyro.z * 1e3),
                xmag: i16_sat(mag.x),
                ymag: i16_sat(mag.y),
                zmag: i16_sat(mag.z),
                temperature: 0,
            })
        }
        ESTIMATOR_STATUS_DATA::ID => {
            let o = out?;
            let tr = o.translation;
            use EstimatorStatusFlags as F;
            let mut flags = F::empty();
            if o.attitude.is_some_and(|a| a.valid) {
                flags |= F::ESTIMATOR_ATTITUDE;
            }
            if tr.horizontal_valid {
                flags |= F::ESTIMATOR_VELOCITY_HORIZ
                    | F::ESTIMATOR_POS_HORIZ_REL
                    | F::ESTIMATOR_POS_HORIZ_ABS;
            }
            if tr.vertical_valid {
                flags |= F::ESTIMATOR_VELOCITY_VERT | F::ESTIMATOR_POS_VERT_ABS;
            }
            let h_acc = t.gps.map_or(f32::NAN, |g| g.h_acc_m as f32);
            MavMessage::ESTIMATOR_STATUS(ESTIMATOR_STATUS_DATA {
                time_usec: usec,
                flags,
                // No innovation test ratios: the complementary filters gate by accuracy and age.
                pos_horiz_accuracy: h_acc,
                pos_vert_accuracy: f32::NAN,
                ..Default::default()
            })
        }
        SERVO_OUTPUT_RAW_DATA::ID => {
            let o = out?;
            // PWM as a flight board would drive the ESCs: 1000 µs stopped, 2000 µs full.
            let pwm = |i: usize| (1000.0 + 1000.0 * o.commands[i].clamp(0.0, 1.0)) as u16;
            MavMessage::SERVO_OUTPUT_RAW(SERVO_OUTPUT_RAW_DATA {
                time_usec: usec as u32,
                servo1_raw: pwm(0),
                servo2_raw: pwm(1),
                servo3_raw: pwm(2),
                servo4_raw: pwm(3),
                servo5_raw: pwm(4),
                servo6_raw: pwm(5),
                servo7_raw: pwm(6),
                servo8_raw: pwm(7),
                port: 0,
                servo9_raw: pwm(8),
                servo10_raw: pwm(9),
                servo11_raw: pwm(10),
                servo12_raw: pwm(11),
                servo13_raw: pwm(12),
                servo14_raw: pwm(13),
                servo15_raw: pwm(14),
                servo16_raw: pwm(15),
            })
        }
        ACTUATOR_OUTPUT_STATUS_DATA::ID => {
            let o = out?;
            let mut actuator = [0.0f32; 32];
            for (a, c) in actuator.iter_mut().zip(o.commands.iter()) {
                *a = *c as f32;
            }
            MavMessage::ACTUATOR_OUTPUT_STATUS(ACTUATOR_OUTPUT_STATUS_DATA {
                time_usec: usec,
                active: (1u32 << o.commands.len().min(31)) - 1,
                actuator,
            })
        }
        ATTITUDE_TARGET_DATA::ID => {
            let sp = out?.attitude_setpoint?;
            let q = sp.q_d.quaternion();
            let w = out?.rate_reference;
            MavMessage::ATTITUDE_TARGET(ATTITUDE_TARGET_DATA {
                time_boot_ms: ms,
                q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
                body_roll_rate: w.x as f32,
                body_pitch_rate: w.y as f32,
                body_yaw_rate: w.z as f32,
                thrust: (sp.thrust_n / t.max_thrust_n.max(1e-9)).clamp(0.0, 1.0) as f32,
                type_mask: AttitudeTargetTypemask::empty(),
            })
        }
        POSITION_TARGET_LOCAL_NED_DATA::ID => {
            let sp = *t.setpoint?.position()?;
            use PositionTargetTypemask as M;
            let mut mask = M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE;
            let ignore = [
                (sp.pos_ned_m.x, M::POSITION_TARGET_TYPEMASK_X_IGNORE),
                (sp.pos_ned_m.y, M::POSITION_TARGET_TYPEMASK_Y_IGNORE),
                (sp.pos_ned_m.z, M::POSITION_TARGET_TYPEMASK_Z_IGNORE),
                (sp.vel_ned_m_s.x, M::POSITION_TARGET_TYPEMASK_VX_IGNORE),
                (sp.vel_ned_m_s.y, M::POSITION_TARGET_TYPEMASK_VY_IGNORE),
                (sp.vel_ned_m_s.z, M::POSITION_TARGET_TYPEMASK_VZ_IGNORE),
            ];
            for (v, m) in ignore {
                if v.is_nan() {
                    mask |= m;
                }
            }
            MavMessage::POSITION_TARGET_LOCAL_NED(POSITION_TARGET_LOCAL_NED_DATA {
                time_boot_ms: ms,
                x: sp.pos_ned_m.x as f32,
                y: sp.pos_ned_m.y as f32,
                z: sp.pos_ned_m.z as f32,
                vx: sp.vel_ned_m_s.x as f32,
                vy: sp.vel_ned_m_s.y as f32,
                vz: sp.vel_ned_m_s.z as f32,
                afx: sp.accel_ned_m_s2.x as f32,
                afy: sp.accel_ned_m_s2.y as f32,
                afz: sp.accel_ned_m_s2.z as f32,
                yaw: sp.yaw_rad as f32,
                yaw_rate: 0.0,
                type_mask: mask,
                coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            })
        }
        HIL_STATE_QUATERNION_DATA::ID => {
            let g = t.truth?;
            let q = g.q.quaternion();
            let w = g.rate_frd_rad_s;
            let v = g.vel_ned_m_s * 100.0;
            let f = g.specific_force_frd_m_s2 / flight_core::GRAVITY_M_S2 * 1e3;
            MavMessage::HIL_STATE_QUATERNION(HIL_STATE_QUATERNION_DATA {
                time_usec: g.time_usec,
                attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
                rollspeed: w.x as f32,
                pitchspeed: w.y as f32,
                yawspeed: w.z as f32,
                lat: e7(g.lat_deg),
                lon: e7(g.lon_deg),
                alt: (g.alt_m * 1e3).round() as i32,
                vx: i16_sat(v.x),
                vy: i16_sat(v.y),
                vz: i16_sat(v.z),
                ind_airspeed: 0,
                true_airspeed: 0,
                xacc: i16_sat(f.x),
                yacc: i16_sat(f.y),
                zacc: i16_sat(f.z),
            })
        }
        _ => return None,
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
