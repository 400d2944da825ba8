//! `SERVO_OUTPUT_RAW`.

use super::prelude::*;

/// `SERVO_OUTPUT_RAW` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let out = s.out;
    let usec = s.usec;
    let o = out?;
    // PWM as a flight board would drive the ESCs: 1000 µs stopped, 2000 µs full.
    let pwm = |i: usize| (1000.0 + 1000.0 * o.commands[i].clamp(0.0, 1.0)) as u16;
    Some(MavMessage::SERVO_OUTPUT_RAW(SERVO_OUTPUT_RAW_DATA {
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
    }))
}
