//! Home: `DO_SET_HOME` (from `COMMAND_LONG` or `COMMAND_INT`) and `GET_HOME_POSITION`.

use super::Call;
use super::vehicle;
use crate::Outgoing;
use crate::streams;
use crate::{GroundStation, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::math::geo::LatLonAlt;
use mavlink::MessageData;
use mavlink::dialects::common::*;

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn home(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, t } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_DO_SET_HOME => {
                if p[0] == 1.0 {
                    vehicle(out, to, AutopilotCommand::SetHome(None));
                } else if p[4].is_finite() && p[5].is_finite() && p[6].is_finite() {
                    let g = LatLonAlt {
                        lat_deg: p[4] as f64,
                        lon_deg: p[5] as f64,
                        alt_m: p[6] as f64,
                    };
                    vehicle(out, to, AutopilotCommand::SetHomeGlobal(g));
                } else {
                    self.deny(to, out, "set home: latitude, longitude and altitude needed");
                }
            }
            MavCmd::MAV_CMD_GET_HOME_POSITION => {
                let home = streams::build(HOME_POSITION_DATA::ID, t, 0);
                let result = if home.is_some() {
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                };
                out.send(self.ack(to, result));
                out.messages.extend(home.map(Outgoing::Message));
            }

            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
