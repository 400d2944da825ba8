//! What a ground station asks of the vehicle: one [`Request`] type, each carrying the rule by
//! which it reaches the control loop ([`Delivery`]).

use crate::{AckTo, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use std::mem::discriminant;

/// How a request reaches the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Delivery {
    /// A command the vehicle answers: the answer goes back to [`crate::GroundStation::answered`]
    /// for `AckTo` (a `COMMAND_ACK`, a refusal's `STATUSTEXT`, the shell's line). A full queue
    /// answers "busy".
    Answered(AckTo),
    /// A stream's latest value (sticks, an offboard set-point): a newer one replaces it, and a
    /// full queue loses it (the next follows within a stream period).
    Latest,
    /// A plan that must arrive, in order (a mission, a fence: they were acknowledged): a full
    /// queue keeps it for later; a newer plan of the same kind replaces one still waiting.
    InOrder,
}

/// One thing asked of the vehicle, and how it is delivered.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    /// What is asked.
    pub command: AutopilotCommand,
    /// How it reaches the vehicle.
    pub delivery: Delivery,
}

impl Request {
    /// Whether `other` is a newer value of the same stream or plan, which replaces this one.
    pub fn replaced_by(&self, other: &Request) -> bool {
        !matches!(self.delivery, Delivery::Answered(_))
            && self.delivery == other.delivery
            && discriminant(&self.command) == discriminant(&other.command)
    }
}

impl Outbox {
    /// Asks `command` of the vehicle, delivered as `delivery`; a stream's value or a plan
    /// replaces the one of its kind still in the outbox.
    pub fn request(&mut self, command: AutopilotCommand, delivery: Delivery) {
        let r = Request { command, delivery };
        self.requests.retain(|old| !old.replaced_by(&r));
        self.requests.push(r);
    }

    /// The commands asked with an answer, and whom each answer is for (in order).
    pub fn answered_requests(&self) -> impl Iterator<Item = (&AutopilotCommand, AckTo)> {
        self.requests.iter().filter_map(|r| match r.delivery {
            Delivery::Answered(to) => Some((&r.command, to)),
            _ => None,
        })
    }
}
