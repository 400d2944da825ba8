//! What a mission item means: decoded into what the commander flies (or why it cannot be
//! flown), checked against where the vehicle may go, and converted between the float and
//! integer item messages.

use flight_core::math::geo::LatLonAlt;
use flight_core::mission::{MissionAltitude, MissionItem, MissionPoint, SpeedChange};
use flight_core::safety::geofence::GeoZone;
use flight_core::safety::targets::{TargetError, TargetLimits, check_point};
use mavlink::dialects::common::*;
use nalgebra::Vector3;

use super::MAX_ITEMS;
/// What mission items are checked against as they arrive: the vehicle's limits and, once
/// known, its home (the estimator's origin, and home in its frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionBounds {
    /// The limits on targets.
    pub limits: TargetLimits,
    /// The origin and home (NED, m), once known.
    pub home: Option<(LatLonAlt, Vector3<f64>)>,
}

impl MissionBounds {
    /// An item within the bounds, or the field at fault as the mission protocol names it.
    pub(super) fn check(&self, item: &MissionItem) -> Result<(), (TargetError, MavMissionResult)> {
        let home = self.home.as_ref().map(|(o, h)| (o, h));
        self.limits
            .check_item(item, home)
            .map_err(|e| (e, field_at_fault(&e)))
    }
}

/// The mission result naming the field of a place that is refused.
fn field_at_fault(e: &TargetError) -> MavMissionResult {
    match e.mission_param() {
        5 => MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
        6 => MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y,
        _ => MavMissionResult::MAV_MISSION_INVALID_PARAM7,
    }
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
    let point = || global_point(m, relative);
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
        MavCmd::MAV_CMD_DO_JUMP => jump(m)?,
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

/// The item's position in a global frame (`relative`: its altitude above home; `None`: a frame
/// without positions); (0, 0) is "here", as a NaN altitude.
fn global_point(
    m: &MISSION_ITEM_INT_DATA,
    relative: Option<bool>,
) -> Result<MissionPoint, MavMissionResult> {
    let Some(relative) = relative else {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME);
    };
    let (lat, lon, z) = (m.x as f64 * 1e-7, m.y as f64 * 1e-7, m.z as f64);
    let point = MissionPoint {
        lat_lon_deg: (m.x != 0 || m.y != 0).then_some((lat, lon)),
        alt: (!z.is_nan()).then_some(if relative {
            MissionAltitude::AboveHome(z)
        } else {
            MissionAltitude::Amsl(z)
        }),
    };
    check_point(&point).map_err(|e| field_at_fault(&e))?;
    Ok(point)
}

/// A heading in degrees (NaN: none).
fn yaw(deg: f32) -> Result<Option<f64>, MavMissionResult> {
    match deg {
        d if d.is_nan() => Ok(None),
        d if d.is_finite() => Ok(Some((d as f64).to_radians())),
        _ => Err(MavMissionResult::MAV_MISSION_INVALID_PARAM4),
    }
}

/// A duration (s), finite and not negative, else `err`.
fn seconds(s: f32, err: MavMissionResult) -> Result<f64, MavMissionResult> {
    if s.is_finite() && s >= 0.0 {
        Ok(s as f64)
    } else {
        Err(err)
    }
}

/// `DO_JUMP`: to item param1, param2 times (−1: for ever).
fn jump(m: &MISSION_ITEM_INT_DATA) -> Result<MissionItem, MavMissionResult> {
    let to = m.param1;
    if !(to.is_finite() && to >= 0.0 && to.fract() == 0.0 && to < MAX_ITEMS as f32) {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
    }
    let repeat = match m.param2 {
        -1.0 => None,
        r if r.is_finite() && r >= 0.0 && r.fract() == 0.0 => Some(r as u32),
        _ => return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM2),
    };
    Ok(MissionItem::Jump {
        to: to as u16,
        repeat,
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

/// A fence plan decoded: its zones, and how many of its circles were MAVSDK's "no circle".
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FencePlan {
    /// The zones to keep the vehicle in (or out of).
    pub zones: Vec<GeoZone>,
    /// Circles of radius 0, ignored: MAVSDK's geofence plugin sends one as its placeholder for
    /// "no circle", and PX4 takes the plan without it.
    pub placeholders: usize,
}

/// A fence plan as zones: consecutive polygon vertices of one kind, as many as each one's
/// param1 says, make one polygon; a circle is one item (param1 its radius, 0 a placeholder
/// for none); a return point is kept in the plan but not a zone. Coordinates in a global
/// frame only.
pub fn decode_fence(items: &[MISSION_ITEM_INT_DATA]) -> Result<FencePlan, MavMissionResult> {
    use MavCmd::*;
    let mut zones = Vec::new();
    let mut placeholders = 0;
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
                // The vertex count, whole, at least 3 and no more than the items left (compared
                // before it becomes an index: 1e30 must not wrap).
                let n = m.param1;
                let left = (items.len() - k) as f32;
                if !(n.is_finite() && n >= 3.0 && n.fract() == 0.0 && n <= left) {
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
            MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
                if m.param1 == 0.0 =>
            {
                placeholders += 1;
                k += 1;
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
    Ok(FencePlan {
        zones,
        placeholders,
    })
}

/// A stored item as the old `MISSION_ITEM` (float coordinates), for `peer`.
pub(super) fn item_float(m: &MISSION_ITEM_INT_DATA, peer: (u8, u8)) -> MISSION_ITEM_DATA {
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
