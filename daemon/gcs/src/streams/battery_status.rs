//! `BATTERY_STATUS`.

use super::prelude::*;

/// `BATTERY_STATUS` from the latest telemetry, if there is data for it.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let mut voltages = [u16::MAX; 10];
    voltages[0] = (s.v.map_or(0.0, |v| v.battery_v) * 1e3).clamp(0.0, 65534.0) as u16;
    let b = s.v.map(|v| v.battery).unwrap_or_default();
    let charge_state = if acting(s.t, Condition::BatteryEmergency) {
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_EMERGENCY
    } else if acting(s.t, Condition::BatteryCritical) {
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_CRITICAL
    } else if acting(s.t, Condition::BatteryLow) {
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW
    } else if b.remaining.is_some() {
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK
    } else {
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED
    };
    Some(MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
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
    }))
}
