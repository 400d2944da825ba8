//! Requests to the vehicle: what the ground stations ask, forwarded to the control loop by each
//! request's delivery rule ([`Delivery`]); the loop's answers matched back to whom they are for.

use crate::control_loop::LoopCommand;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::Denial;
use gcs::{AckTo, Delivery, Request};
use std::collections::VecDeque;
use std::mem::discriminant;
use std::time::{Duration, Instant};
use tokio::sync::mpsc::{self, error::TrySendError};

/// How long an answered request waits for the control loop's answer.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(2);

/// The links' side of the control loop's command queue.
pub(super) struct ToVehicle {
    commands: mpsc::Sender<LoopCommand>,
    /// Plans the queue could not take yet, in order.
    plans: VecDeque<AutopilotCommand>,
    /// Answered requests in the queue, oldest first: their number, whom the answer is for and
    /// when it is given up.
    awaiting: VecDeque<(u64, AckTo, Instant)>,
    next: u64,
}

impl ToVehicle {
    /// Requests go to the loop through `commands`.
    pub(super) fn new(commands: mpsc::Sender<LoopCommand>) -> Self {
        Self {
            commands,
            plans: VecDeque::new(),
            awaiting: VecDeque::new(),
            next: 0,
        }
    }

    /// Forwards `requests` in order. Returns the answers given at once: "busy" for an answered
    /// request the full queue refused.
    pub(super) fn forward(
        &mut self,
        requests: impl IntoIterator<Item = Request>,
        now: Instant,
    ) -> Vec<(AckTo, Result<(), Denial>)> {
        let mut refused = Vec::new();
        self.send_plans();
        for Request { command, delivery } in requests {
            match delivery {
                Delivery::Answered(to) => {
                    let id = self.next;
                    let c = LoopCommand::Vehicle {
                        command,
                        answer: Some(id),
                    };
                    if self.commands.try_send(c).is_ok() {
                        self.next += 1;
                        self.awaiting.push_back((id, to, now + ANSWER_TIMEOUT));
                    } else {
                        refused.push((to, Err(Denial::Busy)));
                    }
                }
                // A full queue loses this value only: the stream's next follows.
                Delivery::Latest => {
                    let _ = self.commands.try_send(LoopCommand::Vehicle {
                        command,
                        answer: None,
                    });
                }
                Delivery::InOrder => {
                    let kind = discriminant(&command);
                    self.plans.retain(|p| discriminant(p) != kind);
                    self.plans.push_back(command);
                    self.send_plans();
                }
            }
        }
        refused
    }

    /// Sends the waiting plans in order, as far as the queue takes them.
    fn send_plans(&mut self) {
        while let Some(command) = self.plans.pop_front() {
            let c = LoopCommand::Vehicle {
                command,
                answer: None,
            };
            if let Err(TrySendError::Full(LoopCommand::Vehicle { command, .. })) =
                self.commands.try_send(c)
            {
                self.plans.push_front(command);
                break;
            }
        }
    }

    /// Whom the answer numbered `id` is for (none: given up on, or not ours).
    pub(super) fn answered(&mut self, id: u64) -> Option<AckTo> {
        let k = self.awaiting.iter().position(|(n, _, _)| *n == id)?;
        self.awaiting.remove(k).map(|(_, to, _)| to)
    }

    /// The requests whose answer has not come by `now`: answered "no answer".
    pub(super) fn given_up(&mut self, now: Instant) -> Vec<(AckTo, Result<(), Denial>)> {
        let mut late = Vec::new();
        while let Some(&(_, to, due)) = self.awaiting.front() {
            if due > now {
                break;
            }
            self.awaiting.pop_front();
            late.push((to, Err(Denial::NoAnswer)));
        }
        late
    }

    /// Tells the loop a ground station's heartbeat arrived.
    pub(super) fn heartbeat(&self) {
        let _ = self.commands.try_send(LoopCommand::GcsHeartbeat);
    }

    /// Stops the loop (a reboot or shutdown).
    pub(super) fn stop(&self) {
        let _ = self.commands.try_send(LoopCommand::Stop);
    }

    /// Stops the loop and waits until it takes the command (an endpoint could not be opened).
    pub(super) async fn stop_now(&self) {
        let _ = self.commands.send(LoopCommand::Stop).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gcs::Reply;
    use mavlink::dialects::common::MavCmd;

    fn to(component: u8) -> AckTo {
        AckTo {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            system: 255,
            component,
            reply: Reply::Ack,
        }
    }

    fn answered(command: AutopilotCommand, component: u8) -> Request {
        Request {
            command,
            delivery: Delivery::Answered(to(component)),
        }
    }

    /// What the loop has been sent, in order.
    fn taken(rx: &mut mpsc::Receiver<LoopCommand>) -> Vec<LoopCommand> {
        std::iter::from_fn(|| rx.try_recv().ok()).collect()
    }

    #[test]
    fn each_delivery_rule_holds_when_the_queue_is_full() {
        let (tx, mut rx) = mpsc::channel(1);
        let mut v = ToVehicle::new(tx);
        let t0 = Instant::now();
        let plan = |command| Request {
            command,
            delivery: Delivery::InOrder,
        };
        let busy = v.forward(
            [
                answered(AutopilotCommand::Arm { force: false }, 1),
                // Full from here: the sticks are lost, the plans wait (the newer mission
                // replacing the older), the command is refused as busy.
                Request {
                    command: AutopilotCommand::Sticks(flight_core::commander::Sticks::CENTRED),
                    delivery: Delivery::Latest,
                },
                plan(AutopilotCommand::SetMission(Vec::new())),
                plan(AutopilotCommand::SetFence(Vec::new())),
                plan(AutopilotCommand::SetMission(Vec::new())),
                answered(AutopilotCommand::Disarm { force: false }, 2),
            ],
            t0,
        );
        assert_eq!(busy, [(to(2), Err(Denial::Busy))]);
        assert!(matches!(
            taken(&mut rx).as_slice(),
            [LoopCommand::Vehicle {
                command: AutopilotCommand::Arm { .. },
                answer: Some(0)
            }]
        ));
        // The waiting plans follow in order as the queue empties: the fence, then the newer
        // mission only.
        let mut plans = Vec::new();
        for _ in 0..3 {
            assert!(v.forward([], t0).is_empty());
            plans.extend(taken(&mut rx));
        }
        assert!(matches!(
            plans.as_slice(),
            [
                LoopCommand::Vehicle {
                    command: AutopilotCommand::SetFence(_),
                    answer: None
                },
                LoopCommand::Vehicle {
                    command: AutopilotCommand::SetMission(_),
                    answer: None
                },
            ]
        ));
        // The answer goes to its asker; one not given in time is "no answer".
        assert_eq!(v.answered(0), Some(to(1)));
        assert_eq!(v.answered(0), None);
        v.forward([answered(AutopilotCommand::Arm { force: true }, 3)], t0);
        assert!(v.given_up(t0 + Duration::from_secs(1)).is_empty());
        let late = v.given_up(t0 + ANSWER_TIMEOUT);
        assert_eq!(late, [(to(3), Err(Denial::NoAnswer))]);
        assert_eq!(v.answered(1), None, "a late answer is dropped");
    }
}
