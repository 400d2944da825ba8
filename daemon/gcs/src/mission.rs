//! The MAVLink mission microservice, vehicle side: upload (`MISSION_COUNT` →
//! `MISSION_REQUEST_INT` per item → `MISSION_ACK`), download (`MISSION_REQUEST_LIST` →
//! `MISSION_COUNT` → `MISSION_ITEM_INT` per request), `MISSION_CLEAR_ALL`, for the three plan
//! types (mission, geofence, rally points), each stored on its own.
//!
//! Items are stored as they were uploaded, so that a download gives them back identical; a
//! mission item is also decoded into what the commander flies ([`MissionItem`]) as it
//! arrives, and one the vehicle cannot fly ends the upload with the reason
//! (`MAV_MISSION_UNSUPPORTED`, `…_UNSUPPORTED_FRAME`, `…_INVALID_PARAMn`), keeping the plan
//! there was. So does one the vehicle must not fly: a place off the Earth, a height below the
//! ground or above the ceiling, a place too far from home ([`MissionBounds`]). The vehicle asks for each item with `MISSION_REQUEST_INT` (never the old
//! `MISSION_REQUEST`), again after [`RETRY_S`] without an answer, and gives up after
//! [`RETRIES`] tries.

mod items;

use super::{Delivery, Outbox};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::mission::MissionItem;
use mavlink::MavHeader;
use mavlink::dialects::common::*;

use items::item_float;
pub use items::{FencePlan, MissionBounds, decode, decode_fence, item_int, speed_change};

/// Time without the item asked for before asking again (s, wall clock).
pub const RETRY_S: f64 = 0.5;
/// Requests of one item before the upload is given up.
pub const RETRIES: u32 = 5;
/// Most items a plan may hold.
pub const MAX_ITEMS: usize = 1000;

/// One plan (mission, fence or rally points): its items as uploaded and an id that changes
/// with them (`opaque_id`).
#[derive(Debug, Clone, Default, PartialEq)]
struct Plan {
    items: Vec<MISSION_ITEM_INT_DATA>,
    opaque_id: u32,
}

/// An upload in progress.
#[derive(Debug, Clone)]
struct Upload {
    kind: MavMissionType,
    /// Who uploads (system, component).
    peer: (u8, u8),
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
    decoded: Vec<MissionItem>,
    asked_at_s: f64,
    tries: u32,
}

/// The plans and the transfer in progress.
#[derive(Debug, Default)]
pub struct Missions {
    plans: [Plan; 3],
    upload: Option<Upload>,
    /// The last finished upload (peer, kind, count): a repeated last item means our ack was
    /// lost, and gets it again.
    finished: Option<((u8, u8), MavMissionType, u16)>,
    now_s: f64,
    /// Uploads given up for want of items.
    pub timeouts: u64,
    /// What items are checked against (none: only what [`decode`] checks).
    pub bounds: Option<MissionBounds>,
}

/// A new mission for the commander, from an upload or a clear.
pub type NewMission = Vec<MissionItem>;

fn index(kind: MavMissionType) -> Option<usize> {
    match kind {
        MavMissionType::MAV_MISSION_TYPE_MISSION => Some(0),
        MavMissionType::MAV_MISSION_TYPE_FENCE => Some(1),
        MavMissionType::MAV_MISSION_TYPE_RALLY => Some(2),
        MavMissionType::MAV_MISSION_TYPE_ALL => None,
    }
}

/// An id for a plan's content (FNV-1a over the items' fields), never 0 for a non-empty plan.
fn opaque_id(items: &[MISSION_ITEM_INT_DATA]) -> u32 {
    if items.is_empty() {
        return 0;
    }
    let mut h: u32 = 0x811c_9dc5;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= *b as u32;
            h = h.wrapping_mul(0x0100_0193);
        }
    };
    for i in items {
        for p in [i.param1, i.param2, i.param3, i.param4, i.z] {
            eat(&p.to_le_bytes());
        }
        eat(&i.x.to_le_bytes());
        eat(&i.y.to_le_bytes());
        eat(&(i.command as u16).to_le_bytes());
        eat(&[i.frame as u8, i.autocontinue]);
    }
    h.max(1)
}

fn ack(to: (u8, u8), kind: MavMissionType, result: MavMissionResult, id: u32) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: to.0,
        target_component: to.1,
        mavtype: result,
        mission_type: kind,
        opaque_id: id,
    })
}

fn request(to: (u8, u8), kind: MavMissionType, seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: to.0,
        target_component: to.1,
        mission_type: kind,
    })
}

/// Whether a fence or rally item is one of its kind (a fence is checked as a whole when the
/// upload completes; rally points are stored, nothing flies them yet).
fn fits(kind: MavMissionType, command: MavCmd) -> bool {
    use MavCmd::*;
    match kind {
        MavMissionType::MAV_MISSION_TYPE_FENCE => matches!(
            command,
            MAV_CMD_NAV_FENCE_RETURN_POINT
                | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
                | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
                | MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
                | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
        ),
        MavMissionType::MAV_MISSION_TYPE_RALLY => command == MAV_CMD_NAV_RALLY_POINT,
        _ => false,
    }
}

impl Missions {
    /// The stored items of a plan.
    pub fn items(&self, kind: MavMissionType) -> &[MISSION_ITEM_INT_DATA] {
        index(kind).map_or(&[], |k| &self.plans[k].items[..])
    }

    /// The id of a plan's content (`opaque_id`, `MISSION_CURRENT.mission_id` and friends).
    pub fn opaque_id(&self, kind: MavMissionType) -> u32 {
        index(kind).map_or(0, |k| self.plans[k].opaque_id)
    }

    /// Handles a mission-protocol message from `from` (addressed to us); returns whether it was
    /// one. A finished mission upload (or a clear) puts the new mission in [`Outbox::mission`].
    pub fn on_message(&mut self, from: &MavHeader, msg: &MavMessage, out: &mut Outbox) -> bool {
        let peer = (from.system_id as u8, from.component_id);
        match msg {
            MavMessage::MISSION_COUNT(c) => self.count(peer, c, out),
            MavMessage::MISSION_ITEM_INT(m) => self.item(peer, m, out),
            MavMessage::MISSION_ITEM(m) => self.item(peer, &item_int(m), out),
            MavMessage::MISSION_REQUEST_LIST(r) => {
                let kind = r.mission_type;
                out.send(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                    count: self.items(kind).len() as u16,
                    target_system: peer.0,
                    target_component: peer.1,
                    mission_type: kind,
                    opaque_id: self.opaque_id(kind),
                }));
            }
            MavMessage::MISSION_REQUEST_INT(r) => {
                match self.items(r.mission_type).get(r.seq as usize) {
                    Some(item) => out.send(MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                        target_system: peer.0,
                        target_component: peer.1,
                        ..item.clone()
                    })),
                    None => out.send(ack(
                        peer,
                        r.mission_type,
                        MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                        0,
                    )),
                }
            }
            MavMessage::MISSION_REQUEST(r) => {
                // The old request, answered with the old item (float coordinates).
                match self.items(r.mission_type).get(r.seq as usize) {
                    Some(item) => out.send(MavMessage::MISSION_ITEM(item_float(item, peer))),
                    None => out.send(ack(
                        peer,
                        r.mission_type,
                        MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                        0,
                    )),
                }
            }
            MavMessage::MISSION_ACK(a) => {
                // The end of a download, or the uploader cancelling.
                if self.upload.as_ref().is_some_and(|u| u.peer == peer) {
                    tracing::info!(result = ?a.mavtype, "mission upload cancelled by the ground station");
                    self.upload = None;
                }
            }
            MavMessage::MISSION_CLEAR_ALL(c) => {
                let kinds = match index(c.mission_type) {
                    Some(k) => k..k + 1,
                    None => 0..3,
                };
                if self.upload.as_ref().is_some_and(|u| u.peer == peer) {
                    self.upload = None;
                }
                for k in kinds {
                    self.plans[k] = Plan::default();
                    match k {
                        0 => {
                            out.request(AutopilotCommand::SetMission(Vec::new()), Delivery::InOrder)
                        }
                        1 => out.request(AutopilotCommand::SetFence(Vec::new()), Delivery::InOrder),
                        _ => {}
                    }
                }
                out.send(ack(
                    peer,
                    c.mission_type,
                    MavMissionResult::MAV_MISSION_ACCEPTED,
                    0,
                ));
            }
            _ => return false,
        }
        true
    }

    /// `MISSION_COUNT`: an upload begins (or, with 0 items, the plan is cleared).
    fn count(&mut self, peer: (u8, u8), c: &MISSION_COUNT_DATA, out: &mut Outbox) {
        let kind = c.mission_type;
        let Some(k) = index(kind) else {
            return out.send(ack(
                peer,
                kind,
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                0,
            ));
        };
        if self.upload.as_ref().is_some_and(|u| u.peer != peer) {
            return out.send(ack(peer, kind, MavMissionResult::MAV_MISSION_DENIED, 0));
        }
        // (The same peer starts again.)
        self.upload = None;
        self.finished = None;
        if c.count as usize > MAX_ITEMS {
            return out.send(ack(peer, kind, MavMissionResult::MAV_MISSION_NO_SPACE, 0));
        }
        if c.count == 0 {
            self.plans[k] = Plan::default();
            match k {
                0 => out.request(AutopilotCommand::SetMission(Vec::new()), Delivery::InOrder),
                1 => out.request(AutopilotCommand::SetFence(Vec::new()), Delivery::InOrder),
                _ => {}
            }
            return out.send(ack(peer, kind, MavMissionResult::MAV_MISSION_ACCEPTED, 0));
        }
        self.upload = Some(Upload {
            kind,
            peer,
            count: c.count,
            items: Vec::with_capacity(c.count as usize),
            decoded: Vec::with_capacity(c.count as usize),
            asked_at_s: self.now_s,
            tries: 1,
        });
        out.send(request(peer, kind, 0));
    }

    /// An item of the upload in progress.
    fn item(&mut self, peer: (u8, u8), m: &MISSION_ITEM_INT_DATA, out: &mut Outbox) {
        let Some(u) = self.upload.as_mut().filter(|u| u.peer == peer) else {
            // The last item again after the upload ended: our ack was lost.
            if let Some((p, kind, count)) = self.finished
                && p == peer
                && kind == m.mission_type
                && m.seq + 1 == count
            {
                out.send(ack(
                    peer,
                    kind,
                    MavMissionResult::MAV_MISSION_ACCEPTED,
                    self.opaque_id(kind),
                ));
            }
            return;
        };
        let expected = u.items.len() as u16;
        if m.mission_type != u.kind || m.seq != expected {
            // A repeat, or one out of order: ask again for the one expected.
            if m.seq < expected || m.mission_type != u.kind {
                out.send(request(peer, u.kind, expected));
                u.asked_at_s = self.now_s;
            } else {
                out.send(ack(
                    peer,
                    u.kind,
                    MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                    0,
                ));
                self.upload = None;
            }
            return;
        }
        let checked = check_item(m, u.kind, u.count, self.bounds.as_ref());
        let decoded = match checked {
            Ok(d) => d,
            Err((reason, why)) => {
                tracing::warn!(seq = m.seq, command = ?m.command, frame = ?m.frame, ?why, reason, "mission upload refused");
                out.send(ack(peer, u.kind, why, 0));
                out.say(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!("mission item {} refused: {reason}", m.seq),
                );
                self.upload = None;
                return;
            }
        };
        u.items.push(MISSION_ITEM_INT_DATA {
            target_system: 0,
            target_component: 0,
            ..m.clone()
        });
        u.decoded.extend(decoded);
        u.tries = 1;
        u.asked_at_s = self.now_s;
        if u.items.len() < u.count as usize {
            out.send(request(peer, u.kind, u.items.len() as u16));
            return;
        }
        self.upload_complete(peer, out);
    }

    /// The last item of an upload arrived: a fence is decoded whole, the plan kept, the
    /// mission or fence handed to the vehicle, the upload acknowledged.
    fn upload_complete(&mut self, peer: (u8, u8), out: &mut Outbox) {
        let Some(u) = self.upload.take() else {
            return;
        };
        let k = index(u.kind).unwrap_or(0);
        if u.kind == MavMissionType::MAV_MISSION_TYPE_FENCE {
            match decode_fence(&u.items) {
                Ok(plan) => {
                    if plan.placeholders > 0 {
                        tracing::warn!(n = plan.placeholders, "fence: radius-0 circles ignored");
                        out.say(
                            MavSeverity::MAV_SEVERITY_WARNING,
                            &format!(
                                "fence: {} circle(s) of radius 0 ignored (no circle)",
                                plan.placeholders
                            ),
                        );
                    }
                    out.request(AutopilotCommand::SetFence(plan.zones), Delivery::InOrder);
                }
                Err(why) => {
                    tracing::warn!(?why, "fence upload refused");
                    out.send(ack(peer, u.kind, why, 0));
                    out.say(
                        MavSeverity::MAV_SEVERITY_WARNING,
                        &format!("fence refused: {why:?}"),
                    );
                    return;
                }
            }
        }
        let id = opaque_id(&u.items);
        tracing::info!(kind = ?u.kind, count = u.count, "plan uploaded");
        self.plans[k] = Plan {
            items: u.items,
            opaque_id: id,
        };
        self.finished = Some((peer, u.kind, u.count));
        if k == 0 {
            out.request(AutopilotCommand::SetMission(u.decoded), Delivery::InOrder);
        }
        out.send(ack(
            peer,
            u.kind,
            MavMissionResult::MAV_MISSION_ACCEPTED,
            id,
        ));
    }

    /// Advances the clock (s, wall): asks again for an item that has not come, and gives the
    /// upload up after [`RETRIES`] requests.
    pub fn poll(&mut self, now_s: f64, out: &mut Outbox) {
        self.now_s = now_s;
        let Some(u) = self.upload.as_mut() else {
            return;
        };
        if now_s - u.asked_at_s < RETRY_S {
            return;
        }
        if u.tries >= RETRIES {
            tracing::warn!(
                seq = u.items.len(),
                "mission upload given up: the ground station stopped sending items"
            );
            out.send(ack(
                u.peer,
                u.kind,
                MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                0,
            ));
            self.upload = None;
            self.timeouts += 1;
            return;
        }
        u.tries += 1;
        u.asked_at_s = now_s;
        out.send(request(u.peer, u.kind, u.items.len() as u16));
    }
}

/// The target (system, component) of a mission-protocol message; `None` for other messages.
pub fn target(msg: &MavMessage) -> Option<(u8, u8)> {
    Some(match msg {
        MavMessage::MISSION_COUNT(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_ITEM_INT(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_ITEM(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_REQUEST_LIST(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_REQUEST_INT(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_REQUEST(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_ACK(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_CLEAR_ALL(m) => (m.target_system, m.target_component),
        MavMessage::MISSION_SET_CURRENT(m) => (m.target_system, m.target_component),
        _ => return None,
    })
}

/// An item of an upload of `kind` (`count` items) checked: decoded (a mission's; a jump within
/// the mission) and within `bounds`, or the reason and result it is refused with.
fn check_item(
    m: &MISSION_ITEM_INT_DATA,
    kind: MavMissionType,
    count: u16,
    bounds: Option<&MissionBounds>,
) -> Result<Option<MissionItem>, (String, MavMissionResult)> {
    let checked = if kind == MavMissionType::MAV_MISSION_TYPE_MISSION {
        decode(m).and_then(|item| match item {
            MissionItem::Jump { to, .. } if to >= count => {
                Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1)
            }
            item => Ok(Some(item)),
        })
    } else if fits(kind, m.command) {
        Ok(None)
    } else {
        Err(MavMissionResult::MAV_MISSION_UNSUPPORTED)
    };
    checked
        .map_err(|why| (format!("{why:?}"), why))
        .and_then(|d| match (d, bounds) {
            (Some(item), Some(b)) => b
                .check(&item)
                .map(|()| Some(item))
                .map_err(|(e, why)| (e.to_string(), why)),
            (d, _) => Ok(d),
        })
}

#[cfg(test)]
mod tests;
