//! The HIL messages of a sensor link turned into the autopilot's typed samples, and its answer
//! into `HIL_ACTUATOR_CONTROLS`.

use flight_core::autopilot::AutopilotOutput;
use flight_core::core::SensorSample;
use flight_core::estimator::translation::GpsMeasurement;
use flight_core::math::geo::LatLonAlt;
use hil::{SensorUpdate, TruthReport};
use mavlink::dialects::common::MavMessage;

/// What has arrived since the last sensor frame, until `HIL_SENSOR` closes it.
#[derive(Debug, Default)]
pub struct FrameAssembler {
    update: SensorUpdate,
}

impl FrameAssembler {
    /// Folds one message in; `HIL_SENSOR` closes a frame: its sample (with what arrived before
    /// it: GPS, rotor speeds, battery) and the simulator's truth, if one came.
    pub fn absorb(&mut self, msg: &MavMessage) -> Option<(SensorSample, Option<TruthReport>)> {
        if !self.update.absorb(msg) {
            return None;
        }
        let u = &mut self.update;
        let (t_usec, gyro, accel) = (u.time_usec?, u.gyro_frd?, u.accel_frd?);
        let sample = SensorSample {
            t_usec,
            gyro,
            accel,
            mag: u.mag_frd.take(),
            baro_alt_m: u.pressure_alt_m.take(),
            gps: u.gps.take().map(|g| GpsMeasurement {
                fix_type: g.fix_type,
                position: LatLonAlt {
                    lat_deg: g.lat_deg,
                    lon_deg: g.lon_deg,
                    alt_m: g.alt_m,
                },
                vel_ned_m_s: g.vel_ned_m_s,
                h_acc_m: g.h_acc_m,
                satellites: g.satellites,
            }),
            // The pack's state as last reported (ESC_STATUS comes at its own rate).
            battery_v: u.battery_v,
            esc_current_a: u.esc_current_a,
            rotor_speed_rad_s: u.rotor_speed_rad_s.take(),
        };
        Some((sample, u.truth.take()))
    }
}

/// `HIL_ACTUATOR_CONTROLS` for the first `rotors` commands of `out`.
pub fn answer(out: &AutopilotOutput, rotors: usize) -> MavMessage {
    hil::actuator_controls(out.t_usec, &out.commands[..rotors], out.armed)
}
