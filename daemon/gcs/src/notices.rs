//! What the vehicle says once, when it happens: manual control or offboard set-points lost, a
//! motor failed, the sensor frames stopped or their source restarted, the attitude estimate
//! reset (its tilt or heading taken afresh from the accelerometer or the magnetometer).

use crate::Outbox;
use crate::telemetry::Telemetry;
use mavlink::dialects::common::{MavSeverity, MavType};

/// What has been said already.
#[derive(Debug, Default)]
pub(crate) struct Notices {
    /// Manual-control and offboard losses reported.
    manual_losses: u32,
    offboard_losses: u32,
    /// The failed motor last announced (1-based).
    motor_failed: Option<usize>,
    /// The sensor link's state as last said: frames silent, source restarts.
    sensors_silent: bool,
    source_restarts: u32,
    /// The attitude estimate's tilt and heading resets said.
    tilt_resets: u64,
    heading_resets: u64,
}

impl Notices {
    /// Says what changed since the last call, once.
    pub(crate) fn say(&mut self, t: &Telemetry, mav_type: MavType, out: &mut Outbox) {
        let losses = t.status().map_or(0, |s| s.manual_losses);
        if losses > self.manual_losses {
            self.manual_losses = losses;
            let mode = t.status().map_or("Hold", |s| s.mode.name());
            out.say(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                &format!("manual control lost: {mode}"),
            );
        }
        let losses = t.status().map_or(0, |s| s.offboard_losses);
        if losses > self.offboard_losses {
            self.offboard_losses = losses;
            let mode = t.status().map_or("Hold", |s| s.mode.name());
            out.say(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                &format!("offboard set-points lost: {mode}"),
            );
        }
        let motor = t.status().and_then(|s| s.motor_failed);
        if motor != self.motor_failed {
            self.motor_failed = motor;
            if let Some(m) = motor {
                let how = if t.status().is_some_and(|s| s.spinning) {
                    "flying on three rotors, spinning"
                } else if mav_type == MavType::MAV_TYPE_QUADROTOR {
                    "cannot fly on three rotors"
                } else {
                    "flying on the others"
                };
                out.say(
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &format!("motor {m} failed: {how}"),
                );
            }
        }
        // Said before the frames are back: it is why.
        let restarts = t.vehicle.as_ref().map_or(0, |v| v.source_restarts);
        if restarts > self.source_restarts {
            self.source_restarts = restarts;
            out.say(
                MavSeverity::MAV_SEVERITY_WARNING,
                "sensor source restarted: vehicle reset",
            );
        }
        if t.link.sensors_silent != self.sensors_silent {
            self.sensors_silent = t.link.sensors_silent;
            if t.link.sensors_silent {
                out.say(
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &format!(
                        "sensor frames stopped: {}",
                        t.status().map_or("-", |s| if s.armed {
                            s.mode.name()
                        } else {
                            "disarmed"
                        })
                    ),
                );
            } else {
                out.say(MavSeverity::MAV_SEVERITY_NOTICE, "sensor frames back");
            }
        }
        self.estimate_resets(t, out);
    }

    /// A reset of the attitude estimate (PX4 counts them in `quat_reset_counter`): the estimate
    /// was wrong by that much (a gyro that saturated, a bump, a glitch) and is right again.
    fn estimate_resets(&mut self, t: &Telemetry, out: &mut Outbox) {
        let Some(r) = t.estimate().and_then(|o| o.attitude).map(|a| a.reset) else {
            return;
        };
        let kinds = [
            ("tilt", r.tilt, r.tilt_rad, &mut self.tilt_resets),
            (
                "heading",
                r.heading,
                r.heading_rad,
                &mut self.heading_resets,
            ),
        ];
        for (what, count, size_rad, said) in kinds {
            // The counts start again with the vehicle (a sensor source that restarted).
            *said = (*said).min(count);
            if count > *said {
                *said = count;
                out.say(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!(
                        "attitude estimate reset: {what} was {:.0} deg off",
                        size_rad.to_degrees()
                    ),
                );
            }
        }
    }
}
