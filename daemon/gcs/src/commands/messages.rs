//! What is sent: `SET_MESSAGE_INTERVAL`, `GET_MESSAGE_INTERVAL`, `REQUEST_MESSAGE`,
//! `REQUEST_AUTOPILOT_CAPABILITIES`.

use super::Call;
use crate::{GroundStation, Outbox};
use mavlink::dialects::common::*;
use mavlink::{Message, MessageData};

impl GroundStation {
    /// One of this file's commands: answered, refused, or passed to the vehicle.
    pub(super) fn messages(&mut self, call: Call, out: &mut Outbox) {
        let Call { c, to, t } = call;
        let p = c.p;
        match c.command {
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let id = p[0] as u32;
                if !(p[0].is_finite() && Self::can_stream(id)) {
                    return self.deny(
                        to,
                        out,
                        &format!("message interval: cannot stream {}", p[0]),
                    );
                }
                let us = p[1];
                let hz = match us {
                    -1.0 => None,
                    0.0 => self.rates.default_hz(self.link, id),
                    x if x > 0.0 && x.is_finite() => Some(1e6 / x as f64),
                    x => {
                        return self.deny(to, out, &format!("message interval: bad interval {x}"));
                    }
                };
                let max = self.max_rate_hz(id);
                if let Some(hz) = hz.filter(|&hz| hz > max * 1.05) {
                    // Faster than it can be sent: refused, rather than sent slower than asked
                    // (said in one STATUSTEXT's 50 characters).
                    let name = MavMessage::default_message_from_id(id)
                        .map_or_else(|| id.to_string(), |m| m.message_name().to_owned());
                    let why = if crate::link_rates::SENSOR_STREAMS.contains(&id) {
                        format!("{name}: at most {max:.0} Hz (sensor rate)")
                    } else {
                        format!("{name}: at most {max:.0} Hz")
                    };
                    tracing::info!(hz, "message interval refused: {why}");
                    return self.deny(to, out, &why);
                }
                self.set_rate(id, hz);
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
            }
            MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL => {
                let id = p[0] as u32;
                let interval_us = match self.interval_s(id) {
                    Some(s) => (s * 1e6) as i32,
                    None if Self::can_stream(id) => -1,
                    None => 0,
                };
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                out.send(MavMessage::MESSAGE_INTERVAL(MESSAGE_INTERVAL_DATA {
                    interval_us,
                    message_id: id as u16,
                }));
            }
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                let id = p[0] as u32;
                if !(p[0].is_finite() && self.can_send(id)) {
                    return self.deny(to, out, &format!("request message: cannot send {}", p[0]));
                }
                if id == AVAILABLE_MODES_DATA::ID && p[1] == 0.0 {
                    // Every mode, one message each (param2 = 0), as QGroundControl may ask.
                    out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                    let n = crate::modes::SELECTABLE.len();
                    self.requested.extend((1..=n).map(|k| (id, k as f32)));
                    return;
                }
                if self.one_off(id, p[1], t, 0).is_none() {
                    // Known, but no data for it yet (no position, no home).
                    out.send(self.ack(to, MavResult::MAV_RESULT_TEMPORARILY_REJECTED));
                    return;
                }
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                self.requested.push((id, p[1]));
            }
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
                out.send(self.ack(to, MavResult::MAV_RESULT_ACCEPTED));
                out.send(self.autopilot_version());
            }
            _ => out.send(self.ack(to, MavResult::MAV_RESULT_UNSUPPORTED)),
        }
    }
}
