//! The MAVLink mission microservice, vehicle side: upload (`MISSION_COUNT` →
//! `MISSION_REQUEST_INT` per item → `MISSION_ACK`), download (`MISSION_REQUEST_LIST` →
//! `MISSION_COUNT` → `MISSION_ITEM_INT` per request), `MISSION_CLEAR_ALL`, for the three plan
//! types (mission, geofence, rally points), each stored on its own.
//!
//! Items are stored as they were uploaded, so that a download gives them back identical; a
//! mission item is also decoded into what the commander flies ([`MissionItem`]) as it
//! arrives, and one the vehicle cannot fly ends the upload with the reason
//! (`MAV_MISSION_UNSUPPORTED`, `…_UNSUPPORTED_FRAME`, `…_INVALID_PARAMn`), keeping the plan
//! there was. The vehicle asks for each item with `MISSION_REQUEST_INT` (never the old
//! `MISSION_REQUEST`), again after [`RETRY_S`] without an answer, and gives up after
//! [`RETRIES`] tries.

use super::Outbox;
use flight_core::mission::{MissionAltitude, MissionItem, MissionPoint, SpeedChange};
use flight_core::safety::geofence::GeoZone;
use mavlink::MavHeader;
use mavlink::dialects::common::*;

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

/// Whether x and y of an item in `frame` are latitude and longitude (scaled by 1e7 in
/// `MISSION_ITEM_INT`), rather than plain numbers.
fn is_global(frame: MavFrame) -> bool {
    use MavFrame::*;
    matches!(
        frame,
        MAV_FRAME_GLOBAL
            | MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MAV_FRAME_GLOBAL_INT
            | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            | MAV_FRAME_GLOBAL_TERRAIN_ALT
            | MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
    )
}

/// A `MISSION_ITEM` (float coordinates) as the `MISSION_ITEM_INT` it stands for.
pub fn item_int(m: &MISSION_ITEM_DATA) -> MISSION_ITEM_INT_DATA {
    let global = is_global(m.frame);
    let scaled = |v: f32| {
        if global {
            (v as f64 * 1e7).round() as i32
        } else {
            v as i32
        }
    };
    MISSION_ITEM_INT_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x: scaled(m.x),
        y: scaled(m.y),
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: m.target_system,
        target_component: m.target_component,
        frame: m.frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}

/// Decodes a mission item into what the commander flies, or says why it cannot be flown.
pub fn decode(m: &MISSION_ITEM_INT_DATA) -> Result<MissionItem, MavMissionResult> {
    use MavMissionResult::*;
    let relative = match m.frame {
        MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => Some(false),
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
            Some(true)
        }
        MavFrame::MAV_FRAME_MISSION => None,
        _ => return Err(MAV_MISSION_UNSUPPORTED_FRAME),
    };
    // A position in a global frame; (0, 0) is "here", as a NaN altitude.
    let point = || -> Result<MissionPoint, MavMissionResult> {
        let Some(relative) = relative else {
            return Err(MAV_MISSION_UNSUPPORTED_FRAME);
        };
        let (lat, lon) = (m.x as f64 * 1e-7, m.y as f64 * 1e-7);
        if !(-90.0..=90.0).contains(&lat) {
            return Err(MAV_MISSION_INVALID_PARAM5_X);
        }
        if !(-180.0..=180.0).contains(&lon) {
            return Err(MAV_MISSION_INVALID_PARAM6_Y);
        }
        let z = m.z as f64;
        if z.is_infinite() {
            return Err(MAV_MISSION_INVALID_PARAM7);
        }
        Ok(MissionPoint {
            lat_lon_deg: (m.x != 0 || m.y != 0).then_some((lat, lon)),
            alt: z.is_finite().then_some(if relative {
                MissionAltitude::AboveHome(z)
            } else {
                MissionAltitude::Amsl(z)
            }),
        })
    };
    let yaw = |deg: f32| -> Result<Option<f64>, MavMissionResult> {
        match deg {
            d if d.is_nan() => Ok(None),
            d if d.is_finite() => Ok(Some((d as f64).to_radians())),
            _ => Err(MAV_MISSION_INVALID_PARAM4),
        }
    };
    let seconds = |s: f32, err| {
        if s.is_finite() && s >= 0.0 {
            Ok(s as f64)
        } else {
            Err(err)
        }
    };
    Ok(match m.command {
        MavCmd::MAV_CMD_NAV_WAYPOINT => MissionItem::Waypoint {
            at: point()?,
            // NaN: no hold.
            hold_s: if m.param1.is_nan() {
                0.0
            } else {
                seconds(m.param1, MAV_MISSION_INVALID_PARAM1)?
            },
            acceptance_m: match m.param2 {
                r if r.is_finite() && r > 0.0 => Some(r as f64),
                r if r.is_nan() || r == 0.0 => None,
                _ => return Err(MAV_MISSION_INVALID_PARAM2),
            },
            yaw_rad: yaw(m.param4)?,
        },
        MavCmd::MAV_CMD_NAV_TAKEOFF => {
            let at = point()?;
            if at.alt.is_none() {
                return Err(MAV_MISSION_INVALID_PARAM7);
            }
            MissionItem::Takeoff {
                at,
                yaw_rad: yaw(m.param4)?,
            }
        }
        MavCmd::MAV_CMD_NAV_LAND => MissionItem::Land {
            at: point()?,
            yaw_rad: yaw(m.param4)?,
        },
        MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => MissionItem::ReturnToLaunch,
        MavCmd::MAV_CMD_NAV_LOITER_TIME => MissionItem::LoiterTime {
            at: point()?,
            time_s: seconds(m.param1, MAV_MISSION_INVALID_PARAM1)?,
        },
        MavCmd::MAV_CMD_NAV_LOITER_UNLIM => MissionItem::LoiterUnlimited { at: point()? },
        // param1 −1 (a time of day in params 2–4) is not flown.
        MavCmd::MAV_CMD_NAV_DELAY => MissionItem::Delay {
            delay_s: seconds(m.param1, MAV_MISSION_INVALID_PARAM1)?,
        },
        MavCmd::MAV_CMD_DO_CHANGE_SPEED => MissionItem::ChangeSpeed(speed_change(m.param2)?),
        MavCmd::MAV_CMD_DO_JUMP => {
            let to = m.param1;
            if !(to.is_finite() && to >= 0.0 && to.fract() == 0.0 && to < MAX_ITEMS as f32) {
                return Err(MAV_MISSION_INVALID_PARAM1);
            }
            let repeat = match m.param2 {
                -1.0 => None,
                r if r.is_finite() && r >= 0.0 && r.fract() == 0.0 => Some(r as u32),
                _ => return Err(MAV_MISSION_INVALID_PARAM2),
            };
            MissionItem::Jump {
                to: to as u16,
                repeat,
            }
        }
        MavCmd::MAV_CMD_DO_SET_HOME => MissionItem::SetHome {
            at: if m.param1 == 1.0 {
                None
            } else {
                let at = point()?;
                if at.lat_lon_deg.is_none() || at.alt.is_none() {
                    return Err(MAV_MISSION_INVALID_PARAM5_X);
                }
                Some(at)
            },
        },
        _ => return Err(MAV_MISSION_UNSUPPORTED),
    })
}

/// `DO_CHANGE_SPEED`'s param2: a speed (m/s), −1 no change, −2 the default.
pub fn speed_change(p: f32) -> Result<SpeedChange, MavMissionResult> {
    match p {
        -1.0 => Ok(SpeedChange::Unchanged),
        -2.0 => Ok(SpeedChange::Default),
        s if s.is_finite() && s > 0.0 => Ok(SpeedChange::To(s as f64)),
        _ => Err(MavMissionResult::MAV_MISSION_INVALID_PARAM2),
    }
}

/// A fence plan as zones: consecutive polygon vertices of one kind, as many as each one's
/// param1 says, make one polygon; a circle is one item (param1 its radius); a return point is
/// kept in the plan but not a zone. Coordinates in a global frame only.
pub fn decode_fence(items: &[MISSION_ITEM_INT_DATA]) -> Result<Vec<GeoZone>, MavMissionResult> {
    use MavCmd::*;
    let mut zones = Vec::new();
    let mut k = 0;
    while k < items.len() {
        let m = &items[k];
        let latlon = |m: &MISSION_ITEM_INT_DATA| {
            let (lat, lon) = (m.x as f64 * 1e-7, m.y as f64 * 1e-7);
            if is_global(m.frame) && lat.abs() <= 90.0 && lon.abs() <= 180.0 {
                Ok((lat, lon))
            } else {
                Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
            }
        };
        match m.command {
            MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
            | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION => {
                let n = m.param1;
                if !(n.is_finite() && n >= 3.0 && n.fract() == 0.0) || k + n as usize > items.len()
                {
                    return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
                }
                let vertices = &items[k..k + n as usize];
                if vertices
                    .iter()
                    .any(|v| v.command != m.command || v.param1 != n)
                {
                    return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
                }
                zones.push(GeoZone::Polygon {
                    inclusion: m.command == MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                    vertices_deg: vertices.iter().map(latlon).collect::<Result<_, _>>()?,
                });
                k += n as usize;
            }
            MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION => {
                if !(m.param1.is_finite() && m.param1 > 0.0) {
                    return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
                }
                zones.push(GeoZone::Circle {
                    inclusion: m.command == MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                    center_deg: latlon(m)?,
                    radius_m: m.param1 as f64,
                });
                k += 1;
            }
            _ => k += 1,
        }
    }
    Ok(zones)
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
                        0 => out.mission = Some(Vec::new()),
                        1 => out.fence = Some(Vec::new()),
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
                0 => out.mission = Some(Vec::new()),
                1 => out.fence = Some(Vec::new()),
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
        let checked = if u.kind == MavMissionType::MAV_MISSION_TYPE_MISSION {
            decode(m).and_then(|item| match item {
                MissionItem::Jump { to, .. } if to >= u.count => {
                    Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1)
                }
                item => Ok(Some(item)),
            })
        } else if fits(u.kind, m.command) {
            Ok(None)
        } else {
            Err(MavMissionResult::MAV_MISSION_UNSUPPORTED)
        };
        let decoded = match checked {
            Ok(d) => d,
            Err(why) => {
                tracing::warn!(seq = m.seq, command = ?m.command, frame = ?m.frame, ?why, "mission upload refused");
                out.send(ack(peer, u.kind, why, 0));
                out.say(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!("mission item {} refused: {why:?}", m.seq),
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
        // Complete.
        let Some(u) = self.upload.take() else {
            return;
        };
        let k = index(u.kind).unwrap_or(0);
        if u.kind == MavMissionType::MAV_MISSION_TYPE_FENCE {
            match decode_fence(&u.items) {
                Ok(zones) => out.fence = Some(zones),
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
            out.mission = Some(u.decoded);
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

/// A stored item as the old `MISSION_ITEM` (float coordinates), for `peer`.
fn item_float(m: &MISSION_ITEM_INT_DATA, peer: (u8, u8)) -> MISSION_ITEM_DATA {
    let global = is_global(m.frame);
    let unscaled = |v: i32| {
        if global {
            (v as f64 * 1e-7) as f32
        } else {
            v as f32
        }
    };
    MISSION_ITEM_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x: unscaled(m.x),
        y: unscaled(m.y),
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: peer.0,
        target_component: peer.1,
        frame: m.frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}

#[cfg(test)]
mod tests;
