//! What the vehicle announces when it changes rather than at a rate: a heartbeat (with
//! `EXTENDED_SYS_STATE` and `CURRENT_MODE`) when the armed state, mode or landed state change,
//! each failsafe event, `HOME_POSITION` on every change, the mission's progress
//! (`MISSION_ITEM_REACHED`, `MISSION_CURRENT`) and the notices (`notices.rs`). What was last
//! shown is kept here, in [`Announced`].

use crate::notices::Notices;
use crate::streams;
use crate::telemetry::Telemetry;
use crate::{GroundStation, Outbox, Outgoing};
use flight_core::commander::{Denial, FlightMode, LandedState};
use flight_core::mission::MissionState;
use flight_core::safety::failsafe::{FailsafeAction, SafetyEvent};
use mavlink::MessageData;
use mavlink::dialects::common::*;

/// What has been announced.
#[derive(Debug, Default)]
pub(crate) struct Announced {
    /// What the last heartbeat showed: a change sends one at once.
    heartbeat: Option<(bool, FlightMode, LandedState)>,
    /// Home as last sent (NED, m).
    home: Option<[f64; 3]>,
    /// Failsafe events already said (the count of the commander's log).
    safety_events: u64,
    /// The mission's progress last shown (current item, state), the items reached said, and
    /// when `MISSION_CURRENT` is next due (s).
    mission: Option<(u16, MissionState)>,
    reached: u32,
    mission_current_next_s: f64,
    /// What has been said once of what happened.
    notices: Notices,
    /// The logs' stop was said.
    logs_stopped: bool,
    /// The follow target was last said to be lost.
    pub(crate) follow_lost: bool,
    /// The last refusal of a follow-target fix said.
    pub(crate) follow_refusal: Option<Denial>,
}

impl GroundStation {
    /// Announces what changed since the last poll (at `now_s`; Unix time `unix`).
    pub(crate) fn announce(&mut self, now_s: f64, t: &Telemetry, unix: u64, out: &mut Outbox) {
        self.announce_heartbeat(now_s, t, unix, out);
        self.announced.notices.say(t, self.mav_type, out);
        if let Some(why) = t.link.logs_stopped
            && !self.announced.logs_stopped
        {
            // Once, in words and as an event: the flight goes on without its logs.
            self.announced.logs_stopped = true;
            out.say(
                MavSeverity::MAV_SEVERITY_ERROR,
                &format!("logging stopped: {}", why.describe()),
            );
            self.logging_stopped_event(why, t, out);
        }
        self.announce_failsafes(t, out);
        let home = t
            .status()
            .and_then(|s| s.home)
            .map(|h| [h.0.x, h.0.y, h.0.z]);
        if home.is_some() && home != self.announced.home {
            // HOME_POSITION on every change, as PX4.
            self.announced.home = home;
            out.messages
                .extend(streams::build(HOME_POSITION_DATA::ID, t, unix).map(Outgoing::Message));
        }
        self.missions.poll(now_s, out);
        self.report_calibration(t, out);
        self.announce_mission(now_s, t, out);
    }

    /// A heartbeat at once, with the extended state and the mode, when what it shows changed.
    fn announce_heartbeat(&mut self, now_s: f64, t: &Telemetry, unix: u64, out: &mut Outbox) {
        let shown = t.status().map(|s| (s.armed, s.mode, s.landed));
        if shown == self.announced.heartbeat {
            return;
        }
        self.said_in_events(self.announced.heartbeat, shown, t, out);
        self.announced.heartbeat = shown;
        out.send(streams::heartbeat(t, self.mav_type));
        for id in [EXTENDED_SYS_STATE_DATA::ID, CURRENT_MODE_DATA::ID] {
            out.messages
                .extend(streams::build(id, t, unix).map(Outgoing::Message));
        }
        self.rates.sent_everywhere(HEARTBEAT_DATA::ID, now_s);
    }

    /// Each failsafe event once, in the state machine's words, however short-lived.
    fn announce_failsafes(&mut self, t: &Telemetry, out: &mut Outbox) {
        let Some(log) = t.status().map(|s| s.safety_log) else {
            return;
        };
        let (missed, events) = log.since(self.announced.safety_events);
        if missed > 0 {
            out.say(
                MavSeverity::MAV_SEVERITY_WARNING,
                &format!("{missed} failsafe messages missed"),
            );
        }
        for e in events {
            self.failsafe_event(&e, t, out);
            let severity = match e {
                SafetyEvent::Cleared(_) => MavSeverity::MAV_SEVERITY_NOTICE,
                SafetyEvent::Triggered(_, FailsafeAction::None | FailsafeAction::Warn) => {
                    MavSeverity::MAV_SEVERITY_WARNING
                }
                _ => MavSeverity::MAV_SEVERITY_CRITICAL,
            };
            out.say(severity, &e.to_string());
        }
        self.announced.safety_events = log.count;
    }

    /// `MISSION_ITEM_REACHED` once per item, then `MISSION_CURRENT` (at 1 Hz and on every
    /// change) saying where the mission went on.
    fn announce_mission(&mut self, now_s: f64, t: &Telemetry, out: &mut Outbox) {
        let Some(status) = t.status() else {
            return;
        };
        let m = status.mission;
        for seq in m.reached_since(self.announced.reached) {
            out.send(MavMessage::MISSION_ITEM_REACHED(
                MISSION_ITEM_REACHED_DATA { seq },
            ));
        }
        self.announced.reached = m.reached_count;
        let shown = (m.current, m.state);
        let a = &mut self.announced;
        if a.mission != Some(shown) || now_s >= a.mission_current_next_s {
            a.mission = Some(shown);
            a.mission_current_next_s = now_s + 1.0;
            out.send(self.mission_current(&status));
        }
    }
}
