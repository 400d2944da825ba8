//! What a calibration asks of the person holding the vehicle, carried from the autopilot to a
//! simulator that plays that person (`sitl`'s hand, `SIM_CAL_HAND`): a `NAMED_VALUE_INT` named
//! `CAL_POSE` sent just before a `HIL_ACTUATOR_CONTROLS`, when a calibration's request changes
//! and again every 0.2 s while it stands. Value 1–6: put the vehicle down on that face (its number + 1: back, front,
//! left, right, up, down) and hold it still; 7: turn it through every orientation.
//! No `CAL_POSE` for half a second: nothing is asked (the hand sets the vehicle down and lets
//! go).
//! A flight board ignores it; a person reads the same requests as `[cal]` texts.

use mavlink::dialects::common::{MavMessage, NAMED_VALUE_INT_DATA};
use sitl_core::sim::Face;

/// The `NAMED_VALUE_INT` name.
pub const NAME: &str = "CAL_POSE";

/// A calibration's request to the hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HandRequest {
    /// Nothing asked.
    #[default]
    None,
    /// Put the vehicle down with this face on the ground and hold it still.
    Place(Face),
    /// Turn the vehicle through every orientation (a magnetometer calibration).
    Tumble,
}

impl HandRequest {
    /// The wire value (0: none).
    pub fn value(self) -> i32 {
        match self {
            HandRequest::None => 0,
            HandRequest::Place(f) => Face::ALL
                .iter()
                .position(|&x| x == f)
                .map_or(0, |i| i as i32 + 1),
            HandRequest::Tumble => 7,
        }
    }

    /// The request a wire value carries; `None` for a value no request has.
    pub fn from_value(v: i32) -> Option<Self> {
        match v {
            0 => Some(HandRequest::None),
            1..=6 => Some(HandRequest::Place(Face::ALL[(v - 1) as usize])),
            7 => Some(HandRequest::Tumble),
            _ => None,
        }
    }

    /// The `CAL_POSE` message, if anything is asked.
    pub fn message(self) -> Option<MavMessage> {
        (self != HandRequest::None).then(|| {
            MavMessage::NAMED_VALUE_INT(NAMED_VALUE_INT_DATA {
                time_boot_ms: 0,
                value: self.value(),
                name: NAME.into(),
            })
        })
    }

    /// The request a received message carries: `Some` for a `CAL_POSE` with a known value.
    pub fn from_message(m: &MavMessage) -> Option<Self> {
        match m {
            MavMessage::NAMED_VALUE_INT(n) if n.name.to_str().ok() == Some(NAME) => {
                Self::from_value(n.value)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_request_survives_the_wire_and_other_values_are_none() {
        let mut all = vec![HandRequest::None, HandRequest::Tumble];
        all.extend(Face::ALL.map(HandRequest::Place));
        for r in all {
            let back = r
                .message()
                .map_or(Some(HandRequest::None), |m| HandRequest::from_message(&m));
            assert_eq!(back, Some(r));
        }
        assert_eq!(HandRequest::from_value(8), None);
        assert_eq!(HandRequest::from_value(-1), None);
    }
}
