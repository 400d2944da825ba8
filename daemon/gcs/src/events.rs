//! The MAVLink events interface (`EVENT`, `CURRENT_EVENT_SEQUENCE`, `REQUEST_EVENT`,
//! `RESPONSE_EVENT_ERROR`), as PX4 sends its events: arming refusals, failsafes beginning,
//! escalating and ending, mode changes, arming and disarming, each an id of the events metadata
//! (PX4's format, libevents') with its arguments, so QGroundControl and MAVSDK show the reasons
//! the `STATUSTEXT`s (which stay) give in words.
//!
//! Sequence numbers start near the top of their range (65526, as PX4's do) so that wrapping is
//! exercised at once; `CURRENT_EVENT_SEQUENCE` says the last one sent (with the reset flag until
//! the first) every 3 s; the last [`KEPT`] events can be asked for again.

use crate::telemetry::{LogFault, Telemetry};
use crate::{GroundStation, Outbox};
use flight_core::commander::{ArmingDenial, FlightMode, LandedState};
use flight_core::safety::failsafe::{CONDITIONS, Condition, FailsafeAction, SafetyEvent};
use flight_core::safety::preflight::PreflightCheck;
use mavlink::MavHeader;
use mavlink::dialects::common::*;
use serde_json::{Map, Value, json};
use std::collections::VecDeque;

/// Events kept to be sent again on request.
pub const KEPT: usize = 64;

/// The events metadata's component key: the upper byte of every id (PX4's is 1 too).
const NAMESPACE_COMPONENT: u32 = 1;

/// The first sequence number after a start.
const FIRST_SEQUENCE: u16 = 65535 - 9;

/// One kind of event: its name, message template (`{1}` the first argument), log level and
/// arguments (type, name).
#[derive(Debug, Clone, Copy)]
pub struct EventKind {
    /// Its name (the sub-id is its FNV-1a hash, as PX4 makes it).
    pub name: &'static str,
    /// What it says.
    pub message: &'static str,
    /// Its level (`MAV_SEVERITY`'s numbers).
    pub level: u8,
    /// Its arguments: type (an integer type or an enum below), name.
    pub arguments: &'static [(&'static str, &'static str)],
}

impl EventKind {
    /// The 32-bit id: the namespace's component key, then the name's 24-bit FNV-1a hash.
    pub fn id(&self) -> u32 {
        let hash = self.name.bytes().fold(0x811c_9dc5u32, |h, b| {
            (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
        });
        (NAMESPACE_COMPONENT << 24) | (hash & 0x00ff_ffff)
    }
}

/// The events this vehicle sends.
pub mod kinds {
    use super::EventKind;
    /// Arming refused, and why.
    pub const ARMING_DENIED: EventKind = EventKind {
        name: "arming_denied",
        message: "Arming denied: {1}",
        level: 2,
        arguments: &[("arming_check_t", "check")],
    };
    /// A failsafe condition began, with its action.
    pub const FAILSAFE_TRIGGERED: EventKind = EventKind {
        name: "failsafe_triggered",
        message: "Failsafe: {1}: {2}",
        level: 2,
        arguments: &[
            ("failsafe_condition_t", "condition"),
            ("failsafe_action_t", "action"),
        ],
    };
    /// A condition that only warns began.
    pub const FAILSAFE_WARNING: EventKind = EventKind {
        name: "failsafe_warning",
        message: "{1}",
        level: 4,
        arguments: &[("failsafe_condition_t", "condition")],
    };
    /// A delayed failsafe action began.
    pub const FAILSAFE_ESCALATED: EventKind = EventKind {
        name: "failsafe_escalated",
        message: "Failsafe: {1}: {2} now",
        level: 2,
        arguments: &[
            ("failsafe_condition_t", "condition"),
            ("failsafe_action_t", "action"),
        ],
    };
    /// A failsafe condition is over.
    pub const FAILSAFE_CLEARED: EventKind = EventKind {
        name: "failsafe_cleared",
        message: "Over: {1}",
        level: 5,
        arguments: &[("failsafe_condition_t", "condition")],
    };
    /// The flight mode changed.
    pub const MODE_CHANGED: EventKind = EventKind {
        name: "mode_changed",
        message: "Flight mode: {1}",
        level: 6,
        arguments: &[("navigation_mode_t", "mode")],
    };
    /// Armed.
    pub const ARMED: EventKind = EventKind {
        name: "armed",
        message: "Armed",
        level: 6,
        arguments: &[],
    };
    /// Disarmed.
    pub const DISARMED: EventKind = EventKind {
        name: "disarmed",
        message: "Disarmed",
        level: 6,
        arguments: &[],
    };
    /// The flight's logs stopped (the flight goes on).
    pub const LOGGING_STOPPED: EventKind = EventKind {
        name: "logging_stopped",
        message: "Logging stopped: {1}",
        level: 3,
        arguments: &[("log_fault_t", "reason")],
    };
    /// Every kind.
    pub const ALL: [EventKind; 9] = [
        ARMING_DENIED,
        FAILSAFE_TRIGGERED,
        FAILSAFE_WARNING,
        FAILSAFE_ESCALATED,
        FAILSAFE_CLEARED,
        MODE_CHANGED,
        ARMED,
        DISARMED,
        LOGGING_STOPPED,
    ];
}

/// The modes, in the order of their `navigation_mode_t` values.
pub const MODES: [FlightMode; 13] = [
    FlightMode::Manual,
    FlightMode::Stabilized,
    FlightMode::Altctl,
    FlightMode::Posctl,
    FlightMode::Takeoff,
    FlightMode::Loiter,
    FlightMode::Mission,
    FlightMode::Rtl,
    FlightMode::Land,
    FlightMode::Offboard,
    FlightMode::Descend,
    FlightMode::Orbit,
    FlightMode::FollowTarget,
];

/// The failsafe actions, in the order of their `failsafe_action_t` values.
pub const ACTIONS: [FailsafeAction; 8] = [
    FailsafeAction::None,
    FailsafeAction::Warn,
    FailsafeAction::Hold,
    FailsafeAction::Return,
    FailsafeAction::Land,
    FailsafeAction::Descend,
    FailsafeAction::Disarm,
    FailsafeAction::Terminate,
];

/// The arming checks an `arming_denied` names (name, description): a refusal's value is its
/// place here ([`arming_check`]); the first, `other`, for any other reason.
pub const ARMING_CHECKS: [(&str, &str); 23] = [
    ("other", "another reason (see the message)"),
    ("terminated", "the flight was terminated: restart"),
    ("imu_lost", "IMU missing or frozen"),
    ("motor_failed", "a motor failed"),
    ("tilted", "tilted beyond COM_ARM_TILT"),
    ("battery_emergency", "battery at emergency level"),
    ("battery_low", "battery low"),
    ("params_invalid", "parameters invalid"),
    ("attitude", "attitude estimate not converged"),
    ("gyro_bias", "gyro bias not settled: keep still"),
    ("position", "position estimate not valid"),
    ("altitude", "altitude estimate not valid"),
    ("mag_lost", "magnetometer silent or frozen"),
    ("baro_lost", "barometer silent or frozen"),
    ("gps_lost", "GPS silent or frozen"),
    ("mag_uncalibrated", "magnetometer not calibrated"),
    ("mag_field", "magnetic field unlike the expected one"),
    ("geofence", "outside the geofence"),
    ("no_sensors", "no sensor data yet"),
    ("estimator", "estimator not ready"),
    ("mode", "not in a mode to start in"),
    ("offboard", "no offboard set-points"),
    ("throttle", "throttle stick not low (or above centre)"),
];

/// The `arming_check_t` value of an arming refusal: its place in [`ARMING_CHECKS`].
pub fn arming_check(denial: &ArmingDenial) -> u8 {
    use PreflightCheck as C;
    match denial {
        ArmingDenial::Check { check, .. } => match check {
            C::Terminated => 1,
            C::ImuLost => 2,
            C::MotorFailed(_) => 3,
            C::Tilted { .. } => 4,
            C::BatteryEmergency(_) => 5,
            C::BatteryLow(_) => 6,
            C::ParamsInvalid(_) => 7,
            C::AttitudeNotConverged => 8,
            C::GyroBiasUnsettled => 9,
            C::PositionInvalid => 10,
            C::AltitudeInvalid => 11,
            C::MagLost => 12,
            C::BaroLost => 13,
            C::GpsLost => 14,
            C::MagUncalibrated => 15,
            C::MagField(_) => 16,
            C::Geofence => 17,
            C::EstimatorNotReady => 19,
        },
        ArmingDenial::NoSensorData => 18,
        ArmingDenial::ModeCannotStart(_) => 20,
        ArmingDenial::NoOffboard => 21,
        ArmingDenial::ThrottleAboveCentre | ArmingDenial::ThrottleNotLow => 22,
        ArmingDenial::NeedsSticks(_) | ArmingDenial::Calibrating(_) | ArmingDenial::Mission(_) => 0,
    }
}

/// An enum's value in the metadata: its position in its list.
fn index_of<T: PartialEq>(list: &[T], x: T) -> u8 {
    list.iter().position(|y| *y == x).unwrap_or(0) as u8
}

/// `failsafe_condition_t` of a condition.
pub fn condition_arg(c: Condition) -> u8 {
    index_of(&CONDITIONS, c)
}

/// `failsafe_action_t` of an action: its place in [`ACTIONS`] (a test keeps them in step).
pub fn action_arg(a: FailsafeAction) -> u8 {
    match a {
        FailsafeAction::None => 0,
        FailsafeAction::Warn => 1,
        FailsafeAction::Hold => 2,
        FailsafeAction::Return => 3,
        FailsafeAction::Land => 4,
        FailsafeAction::Descend => 5,
        FailsafeAction::Disarm => 6,
        FailsafeAction::Terminate => 7,
    }
}

/// `navigation_mode_t` of a mode: its place in [`MODES`] (a test keeps them in step).
pub fn mode_arg(m: FlightMode) -> u8 {
    match m {
        FlightMode::Manual => 0,
        FlightMode::Stabilized => 1,
        FlightMode::Altctl => 2,
        FlightMode::Posctl => 3,
        FlightMode::Takeoff => 4,
        FlightMode::Loiter => 5,
        FlightMode::Mission => 6,
        FlightMode::Rtl => 7,
        FlightMode::Land => 8,
        FlightMode::Offboard => 9,
        FlightMode::Descend => 10,
        FlightMode::Orbit => 11,
        FlightMode::FollowTarget => 12,
    }
}

/// The events sent, and their numbering.
#[derive(Debug, Clone)]
pub struct EventLog {
    next: u16,
    sent: VecDeque<EVENT_DATA>,
}

impl Default for EventLog {
    fn default() -> Self {
        Self {
            next: FIRST_SEQUENCE,
            sent: VecDeque::with_capacity(KEPT),
        }
    }
}

impl EventLog {
    /// The `EVENT` of `kind` with `args` (one byte each: the enums' values) at `t_ms`.
    pub fn emit(&mut self, kind: &EventKind, args: &[u8], t_ms: u32) -> MavMessage {
        let mut arguments = [0u8; 40];
        arguments[..args.len().min(40)].copy_from_slice(&args[..args.len().min(40)]);
        let e = EVENT_DATA {
            id: kind.id(),
            event_time_boot_ms: t_ms,
            sequence: self.next,
            destination_component: 0,
            destination_system: 0,
            // Internal level in the high nibble, the one shown in the low one.
            log_levels: (kind.level << 4) | kind.level,
            arguments,
        };
        self.next = self.next.wrapping_add(1);
        if self.sent.len() == KEPT {
            self.sent.pop_front();
        }
        self.sent.push_back(e.clone());
        MavMessage::EVENT(e)
    }

    /// `CURRENT_EVENT_SEQUENCE`: the last sequence sent, the reset flag until the first.
    pub fn current(&self) -> MavMessage {
        MavMessage::CURRENT_EVENT_SEQUENCE(CURRENT_EVENT_SEQUENCE_DATA {
            sequence: self.next.wrapping_sub(1),
            flags: if self.sent.is_empty() {
                MavEventCurrentSequenceFlags::MAV_EVENT_CURRENT_SEQUENCE_FLAGS_RESET
            } else {
                MavEventCurrentSequenceFlags::empty()
            },
        })
    }

    /// The answers to `REQUEST_EVENT` (an inclusive range, which may wrap): each event again
    /// up to the first that is not kept, for which one `RESPONSE_EVENT_ERROR` names the oldest
    /// kept after it (a receiver asks again from there). At most [`KEPT`] + 1.
    pub fn request(&self, r: &REQUEST_EVENT_DATA, from: &MavHeader) -> Vec<MavMessage> {
        let mut out = Vec::new();
        let mut seq = r.first_sequence;
        loop {
            match self.sent.iter().find(|e| e.sequence == seq) {
                Some(e) => out.push(MavMessage::EVENT(e.clone())),
                None => {
                    out.push(MavMessage::RESPONSE_EVENT_ERROR(
                        RESPONSE_EVENT_ERROR_DATA {
                            target_system: from.system_id as u8,
                            target_component: from.component_id,
                            sequence: seq,
                            sequence_oldest_available: self.oldest_after(seq),
                            reason: MavEventErrorReason::MAV_EVENT_ERROR_REASON_UNAVAILABLE,
                        },
                    ));
                    return out;
                }
            }
            if seq == r.last_sequence || out.len() > KEPT {
                return out;
            }
            seq = seq.wrapping_add(1);
        }
    }

    /// The oldest kept sequence after `seq` (counting with the wrap); the next to come when
    /// none is kept, or `seq` is not sent yet.
    fn oldest_after(&self, seq: u16) -> u16 {
        let last = self.next.wrapping_sub(1);
        // Ahead of the last one sent (within half the range): nothing kept comes after it.
        if seq.wrapping_sub(last) != 0 && seq.wrapping_sub(last) < 0x8000 {
            return self.next;
        }
        self.sent
            .iter()
            .map(|e| e.sequence)
            .min_by_key(|s| s.wrapping_sub(seq))
            .unwrap_or(self.next)
    }
}

/// How often `CURRENT_EVENT_SEQUENCE` goes out (s), as PX4 sends it.
const CURRENT_INTERVAL_S: f64 = 3.0;

impl GroundStation {
    /// What the status shows, changed from `before` to `now`: armed or disarmed, the mode.
    pub(crate) fn said_in_events(
        &mut self,
        before: Option<(bool, FlightMode, LandedState)>,
        now: Option<(bool, FlightMode, LandedState)>,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let (Some((was_armed, was_mode, _)), Some((armed, mode, _))) = (before, now) else {
            return;
        };
        let ms = (t.link.t_s * 1e3) as u32;
        if mode != was_mode {
            out.send(
                self.events
                    .emit(&kinds::MODE_CHANGED, &[mode_arg(mode)], ms),
            );
        }
        if armed != was_armed {
            let kind = if armed { kinds::ARMED } else { kinds::DISARMED };
            out.send(self.events.emit(&kind, &[], ms));
        }
    }

    /// A failsafe's beginning, escalation or end.
    pub(crate) fn failsafe_event(&mut self, e: &SafetyEvent, t: &Telemetry, out: &mut Outbox) {
        let ms = (t.link.t_s * 1e3) as u32;
        let m = match *e {
            SafetyEvent::Triggered(c, FailsafeAction::None | FailsafeAction::Warn) => self
                .events
                .emit(&kinds::FAILSAFE_WARNING, &[condition_arg(c)], ms),
            SafetyEvent::Triggered(c, a) => self.events.emit(
                &kinds::FAILSAFE_TRIGGERED,
                &[condition_arg(c), action_arg(a)],
                ms,
            ),
            SafetyEvent::Escalated(c, a) => self.events.emit(
                &kinds::FAILSAFE_ESCALATED,
                &[condition_arg(c), action_arg(a)],
                ms,
            ),
            SafetyEvent::Cleared(c) => {
                self.events
                    .emit(&kinds::FAILSAFE_CLEARED, &[condition_arg(c)], ms)
            }
        };
        out.send(m);
    }

    /// The flight's logs stopped, for `why`.
    pub(crate) fn logging_stopped_event(&mut self, why: LogFault, t: &Telemetry, out: &mut Outbox) {
        let ms = (t.link.t_s * 1e3) as u32;
        let arg = LogFault::ALL.iter().position(|&f| f == why).unwrap_or(0) as u8;
        out.send(self.events.emit(&kinds::LOGGING_STOPPED, &[arg], ms));
    }

    /// Arming refused for `why`.
    pub(crate) fn arming_denied_event(&mut self, why: &ArmingDenial, out: &mut Outbox) {
        let ms = self.events_now_ms;
        let m = self
            .events
            .emit(&kinds::ARMING_DENIED, &[arming_check(why)], ms);
        out.send(m);
    }

    /// `CURRENT_EVENT_SEQUENCE` when due at `now_s`.
    pub(crate) fn events_poll(&mut self, now_s: f64, t: &Telemetry, out: &mut Outbox) {
        self.events_now_ms = (t.link.t_s * 1e3) as u32;
        if now_s >= self.events_current_due {
            self.events_current_due = now_s + CURRENT_INTERVAL_S;
            out.send(self.events.current());
        }
    }

    /// `REQUEST_EVENT` from `from`.
    pub(crate) fn events_requested(
        &mut self,
        r: &REQUEST_EVENT_DATA,
        from: &MavHeader,
        out: &mut Outbox,
    ) {
        // On the requester's link only: a request must not multiply traffic everywhere.
        let link = self.link;
        out.streamed.extend(
            self.events
                .request(r, from)
                .into_iter()
                .map(|m| (link, crate::Outgoing::Message(m))),
        );
    }
}

/// The events metadata (libevents' format, as PX4 publishes its events).
pub fn metadata_json() -> Value {
    let entries = |names: &mut dyn Iterator<Item = (String, String)>| -> Value {
        let mut m = Map::new();
        for (i, (name, description)) in names.enumerate() {
            m.insert(
                i.to_string(),
                json!({ "name": name, "description": description }),
            );
        }
        Value::Object(m)
    };
    let enum_of = |entries: Value, description: &str| json!({ "type": "uint8_t", "description": description, "entries": entries });
    let words = |s: &str| {
        s.replace(|c: char| !c.is_ascii_alphanumeric(), "_")
            .to_lowercase()
    };
    let mut events = Map::new();
    for k in kinds::ALL {
        let arguments: Vec<Value> = k
            .arguments
            .iter()
            .map(|(t, n)| json!({ "type": t, "name": n }))
            .collect();
        let mut e = json!({ "name": k.name, "message": k.message });
        if !arguments.is_empty() {
            e["arguments"] = Value::Array(arguments);
        }
        events.insert((k.id() & 0x00ff_ffff).to_string(), e);
    }
    json!({
        "version": 2,
        "components": {
            NAMESPACE_COMPONENT.to_string(): {
                "namespace": "autopilot",
                "enums": {
                    "arming_check_t": enum_of(
                        entries(&mut ARMING_CHECKS.iter().map(|(n, d)| (n.to_string(), d.to_string()))),
                        "why arming was refused"),
                    "failsafe_condition_t": enum_of(
                        entries(&mut CONDITIONS.iter().map(|c| (words(&c.to_string()), c.to_string()))),
                        "a failsafe condition"),
                    "failsafe_action_t": enum_of(
                        entries(&mut ACTIONS.iter().map(|a| (words(a.name()), a.name().to_owned()))),
                        "what a failsafe does"),
                    "navigation_mode_t": enum_of(
                        entries(&mut MODES.iter().map(|m| (words(m.name()), m.name().to_owned()))),
                        "a flight mode"),
                    "log_fault_t": enum_of(
                        entries(&mut LogFault::ALL.iter().map(|f| (f.name().to_owned(), f.describe().to_owned()))),
                        "why the logs stopped"),
                },
                "event_groups": { "default": { "events": Value::Object(events) } },
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use flight_core::safety::preflight::MagFieldCheck;

    fn header() -> MavHeader {
        MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        }
    }

    #[test]
    fn sequences_wrap_and_a_missed_event_can_be_asked_for_again() {
        let mut log = EventLog::default();
        let MavMessage::CURRENT_EVENT_SEQUENCE(c) = log.current() else {
            panic!()
        };
        // Before any event: the one before the first, with the reset flag.
        assert_eq!(c.sequence, FIRST_SEQUENCE - 1);
        assert!(!c.flags.is_empty());
        let seqs: Vec<u16> = (0..12)
            .map(|k| match log.emit(&kinds::MODE_CHANGED, &[k], 1000) {
                MavMessage::EVENT(e) => e.sequence,
                _ => panic!(),
            })
            .collect();
        assert_eq!(&seqs[..3], [65526, 65527, 65528]);
        assert_eq!(&seqs[10..], [0, 1]);
        let MavMessage::CURRENT_EVENT_SEQUENCE(c) = log.current() else {
            panic!()
        };
        assert_eq!((c.sequence, c.flags.is_empty()), (1, true));
        // A range across the wrap: each event again, in order.
        let r = REQUEST_EVENT_DATA {
            target_system: 1,
            target_component: 1,
            first_sequence: 65534,
            last_sequence: 0,
        };
        let again: Vec<(u16, u8)> = log
            .request(&r, &header())
            .iter()
            .map(|m| match m {
                MavMessage::EVENT(e) => (e.sequence, e.arguments[0]),
                _ => panic!("{m:?}"),
            })
            .collect();
        assert_eq!(again, [(65534, 8), (65535, 9), (0, 10)]);
        // Forgotten (or not yet sent): an error to the requester naming the oldest kept.
        for _ in 0..KEPT {
            log.emit(&kinds::ARMED, &[], 2000);
        }
        let lost = REQUEST_EVENT_DATA {
            first_sequence: 65526,
            last_sequence: 65526,
            ..r
        };
        match &log.request(&lost, &header())[..] {
            [MavMessage::RESPONSE_EVENT_ERROR(e)] => {
                assert_eq!((e.target_system, e.target_component), (255, 190));
                // 12 events, then 64 more: 2 to 65 are kept.
                assert_eq!(e.sequence_oldest_available, 2);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn arming_refusals_name_their_check_and_the_metadata_defines_every_event() {
        let check = |check| ArmingDenial::Check { check, more: 0 };
        let tilted = PreflightCheck::Tilted {
            tilt_deg: 40.0,
            limit_deg: 30.0,
        };
        assert_eq!(arming_check(&check(tilted)), 4);
        assert_eq!(arming_check(&check(PreflightCheck::MagUncalibrated)), 15);
        let field = MagFieldCheck::Strength {
            got: 0.2,
            want: 0.5,
        };
        assert_eq!(arming_check(&check(PreflightCheck::MagField(field))), 16);
        assert_eq!(arming_check(&ArmingDenial::ThrottleNotLow), 22);
        assert_eq!(arming_check(&ArmingDenial::NeedsSticks("POSCTL")), 0);
        let m = metadata_json();
        let events = &m["components"]["1"]["event_groups"]["default"]["events"];
        for k in kinds::ALL {
            let e = &events[(k.id() & 0xff_ffff).to_string()];
            assert_eq!(e["name"], k.name);
            for (ty, _) in k.arguments {
                assert!(
                    ty.ends_with("_t") && !m["components"]["1"]["enums"][*ty].is_null(),
                    "{ty}"
                );
            }
        }
        // PX4's ids: FNV-1a of the name (libevents' test file's).
        let test1 = EventKind {
            name: "test1",
            ..kinds::ARMED
        };
        assert_eq!(test1.id() & 0xff_ffff, 2_306_236);
        assert_eq!(condition_arg(Condition::GcsLinkLost), 0);
        for (k, a) in ACTIONS.iter().enumerate() {
            assert_eq!(usize::from(action_arg(*a)), k);
        }
        for (k, m) in MODES.iter().enumerate() {
            assert_eq!(usize::from(mode_arg(*m)), k);
        }
    }
}
