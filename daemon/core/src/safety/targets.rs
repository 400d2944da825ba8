//! Where a command or a mission item may send the vehicle: the one check every place and
//! height a ground station gives passes before it is flown (`DO_SET_HOME`, `NAV_TAKEOFF`,
//! `DO_REPOSITION`, mission items).
//!
//! - A latitude and longitude are on the Earth (±90°, ±180°).
//! - A target is within [`PLAUSIBLE_RANGE_M`] of home, and of `GF_MAX_HOR_DIST` when set.
//! - A target's height above home is at least [`GROUND_CLEARANCE_M`] (no set-point held in
//!   the ground) and at most the ceiling: `LNDMC_ALT_MAX` (PX4's multicopter altitude limit),
//!   `GF_MAX_VER_DIST`, and in any case [`HARD_CEILING_M`].
//! - A new home is within the range of the vehicle, and within [`HOME_SHIFT_MAX_M`] of the
//!   current home's height; a mission's `DO_SET_HOME` items move the home its later items are
//!   checked against.

use crate::math::geo::{LatLonAlt, LocalFrame};
use crate::mission::{MissionAltitude, MissionItem, MissionPoint};
use crate::safety::failsafe::SafetyParams;
use nalgebra::Vector3;
use thiserror::Error;

/// Farthest a target may be from home, and a new home from the vehicle (m): ArduPilot's
/// bound on home's distance from the estimator's origin. No multirotor flies farther on one
/// battery; anything beyond is a mistake or an attack.
pub const PLAUSIBLE_RANGE_M: f64 = 50_000.0;

/// Highest target above home when no parameter limits it (m).
pub const HARD_CEILING_M: f64 = 10_000.0;

/// Lowest height above home of a target the vehicle holds (m): a set-point below it would
/// press the vehicle into the ground, armed and tilting.
pub const GROUND_CLEARANCE_M: f64 = 1.0;

/// Farthest a new home may be above or below the current one (m): the ground is not flat,
/// but heights are measured from home, so a home set far below would put every target
/// underground, and far above would lift every target past the ceiling.
pub const HOME_SHIFT_MAX_M: f64 = 100.0;

/// Why a place or height is refused; the words go to the operator.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum TargetError {
    /// The latitude is not on the Earth.
    #[error("latitude {0}° outside ±90°")]
    Latitude(f64),
    /// The longitude is not on the Earth.
    #[error("longitude {0}° outside ±180°")]
    Longitude(f64),
    /// The altitude is infinite (or, for a height that must be given, not a number).
    #[error("altitude {} m not finite", Metres(*.0))]
    Altitude(f64),
    /// A new home too far above or below the current one.
    #[error("new home {} m above the current one: more than {HOME_SHIFT_MAX_M} m up or down", Metres(*up_m))]
    HomeShift {
        /// Height of the new home above the current one (m).
        up_m: f64,
    },
    /// Closer to the ground than [`GROUND_CLEARANCE_M`].
    #[error("{} m above home, below the {GROUND_CLEARANCE_M} m ground clearance", Metres(*height_m))]
    BelowGround {
        /// Height above home (m).
        height_m: f64,
    },
    /// Above the ceiling.
    #[error("{} m above home, above the {ceiling_m:.0} m ceiling ({by})", Metres(*height_m))]
    AboveCeiling {
        /// Height above home (m).
        height_m: f64,
        /// The ceiling (m).
        ceiling_m: f64,
        /// What sets it.
        by: &'static str,
    },
    /// Too far horizontally.
    #[error("{} m from {from}, farther than {limit_m:.0} m ({by})", Metres(*distance_m))]
    TooFar {
        /// Horizontal distance (m).
        distance_m: f64,
        /// From what.
        from: &'static str,
        /// The limit (m).
        limit_m: f64,
        /// What sets it.
        by: &'static str,
    },
}

/// A length as the operator reads it: to the decimetre, or in powers of ten when huge.
struct Metres(f64);

impl std::fmt::Display for Metres {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.abs() < 1e6 {
            write!(f, "{:.1}", self.0)
        } else {
            write!(f, "{:.1e}", self.0)
        }
    }
}

impl TargetError {
    /// Which field of a mission item is wrong: 5 (x, latitude), 6 (y, longitude) or 7 (z).
    pub fn mission_param(&self) -> u8 {
        match self {
            Self::Latitude(_) | Self::TooFar { .. } => 5,
            Self::Longitude(_) => 6,
            Self::Altitude(_)
            | Self::BelowGround { .. }
            | Self::AboveCeiling { .. }
            | Self::HomeShift { .. } => 7,
        }
    }
}

/// A latitude and longitude on the Earth (deg).
pub fn check_lat_lon(lat_deg: f64, lon_deg: f64) -> Result<(), TargetError> {
    if !(-90.0..=90.0).contains(&lat_deg) {
        return Err(TargetError::Latitude(lat_deg));
    }
    if !(-180.0..=180.0).contains(&lon_deg) {
        return Err(TargetError::Longitude(lon_deg));
    }
    Ok(())
}

/// A point's parts that need no home: latitude and longitude on the Earth, altitude not
/// infinite (NaN: "keep").
pub fn check_point(p: &MissionPoint) -> Result<(), TargetError> {
    if let Some((lat, lon)) = p.lat_lon_deg {
        check_lat_lon(lat, lon)?;
    }
    match p.alt {
        Some(MissionAltitude::AboveHome(a) | MissionAltitude::Amsl(a)) if a.is_infinite() => {
            Err(TargetError::Altitude(a))
        }
        _ => Ok(()),
    }
}

/// The limits on targets, from the parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetLimits {
    /// Highest target above home (m) and what sets it.
    pub ceiling: (f64, &'static str),
    /// Farthest target from home (m) and what sets it.
    pub range: (f64, &'static str),
}

impl TargetLimits {
    /// The limits `p` sets: the lowest of the ceilings and ranges that are set.
    pub fn new(p: &SafetyParams) -> Self {
        let lowest = |hard: (f64, &'static str), set: &[(f64, &'static str)]| {
            set.iter()
                .filter(|(v, _)| *v > 0.0)
                .fold(hard, |a, &b| if b.0 < a.0 { b } else { a })
        };
        Self {
            ceiling: lowest(
                (HARD_CEILING_M, "the hard ceiling"),
                &[
                    (p.max_altitude_m, "LNDMC_ALT_MAX"),
                    (p.fence_max_vertical_m, "GF_MAX_VER_DIST"),
                ],
            ),
            range: lowest(
                (PLAUSIBLE_RANGE_M, "the plausible range"),
                &[(p.fence_max_horizontal_m, "GF_MAX_HOR_DIST")],
            ),
        }
    }

    /// A height above home (m) the vehicle may be sent to.
    pub fn check_height(&self, height_m: f64) -> Result<(), TargetError> {
        if !height_m.is_finite() {
            return Err(TargetError::Altitude(height_m));
        }
        if height_m < GROUND_CLEARANCE_M {
            return Err(TargetError::BelowGround { height_m });
        }
        let (ceiling_m, by) = self.ceiling;
        if height_m > ceiling_m {
            return Err(TargetError::AboveCeiling {
                height_m,
                ceiling_m,
                by,
            });
        }
        Ok(())
    }

    /// A target (NED, m; a NaN part is "where the vehicle is" and not checked) against home.
    pub fn check_target(
        &self,
        target: &Vector3<f64>,
        home: &Vector3<f64>,
    ) -> Result<(), TargetError> {
        if !(target.x.is_nan() && target.y.is_nan()) {
            let distance_m = (target.xy() - home.xy()).norm();
            let (limit_m, by) = self.range;
            if distance_m.is_nan() || distance_m > limit_m {
                return Err(TargetError::TooFar {
                    distance_m,
                    from: "home",
                    limit_m,
                    by,
                });
            }
        }
        if !target.z.is_nan() {
            self.check_height(home.z - target.z)?;
        }
        Ok(())
    }

    /// A new home (NED, m) for a vehicle at `here` whose home is `current`: within the range
    /// of the vehicle, and within [`HOME_SHIFT_MAX_M`] of the current home's height (heights
    /// are measured from home: one moved far up or down would move every target with it).
    pub fn check_home(
        &self,
        home: &Vector3<f64>,
        here: &Vector3<f64>,
        current: &Vector3<f64>,
    ) -> Result<(), TargetError> {
        let distance_m = (home.xy() - here.xy()).norm();
        let (limit_m, by) = self.range;
        if distance_m.is_nan() || distance_m > limit_m {
            return Err(TargetError::TooFar {
                distance_m,
                from: "the vehicle",
                limit_m,
                by,
            });
        }
        let up_m = current.z - home.z;
        if up_m.is_nan() || up_m.abs() > HOME_SHIFT_MAX_M {
            return Err(TargetError::HomeShift { up_m });
        }
        Ok(())
    }

    /// A mission item: its point, where it has one (a landing's altitude is not flown and not
    /// checked; a take-off's or a hover's is). With home (NED, m, in the frame of the origin)
    /// known, everything; without it, what needs no home (the place on the Earth, a height
    /// above home).
    pub fn check_item(
        &self,
        item: &MissionItem,
        home: Option<(&LatLonAlt, &Vector3<f64>)>,
    ) -> Result<(), TargetError> {
        let nowhere = Vector3::repeat(f64::NAN);
        let (point, height_flown) = match item {
            MissionItem::Waypoint { at, .. }
            | MissionItem::Takeoff { at, .. }
            | MissionItem::LoiterTime { at, .. }
            | MissionItem::LoiterUnlimited { at } => (at, true),
            MissionItem::Land { at, .. } => (at, false),
            MissionItem::SetHome { at: Some(at) } => {
                check_point(at)?;
                return home.map_or(Ok(()), |(origin, home)| {
                    self.check_home(&at.to_ned(origin, home, &nowhere), home, home)
                });
            }
            _ => return Ok(()),
        };
        check_point(point)?;
        let Some((origin, home)) = home else {
            return match point.alt {
                Some(MissionAltitude::AboveHome(h)) if height_flown => self.check_height(h),
                _ => Ok(()),
            };
        };
        let mut target = point.to_ned(origin, home, &nowhere);
        if !height_flown {
            target.z = f64::NAN;
        }
        self.check_target(&target, home)
    }
}

/// A mission against home, item by item, home moving with its `DO_SET_HOME` items as it will
/// in flight; the first refused item and why.
pub fn check_mission(
    items: &[MissionItem],
    limits: &TargetLimits,
    origin: &LatLonAlt,
    home: &Vector3<f64>,
) -> Result<(), (usize, TargetError)> {
    let mut home = *home;
    for (k, item) in items.iter().enumerate() {
        limits
            .check_item(item, Some((origin, &home)))
            .map_err(|e| (k, e))?;
        if let MissionItem::SetHome { at: Some(at) } = item {
            home = at.to_ned(origin, &home, &home);
        }
    }
    Ok(())
}

/// The global position `p` in the local frame of `origin`, checked on the Earth.
pub fn global_to_ned(p: &LatLonAlt, origin: &LatLonAlt) -> Result<Vector3<f64>, TargetError> {
    check_lat_lon(p.lat_deg, p.lon_deg)?;
    if !p.alt_m.is_finite() {
        return Err(TargetError::Altitude(p.alt_m));
    }
    Ok(LocalFrame::new(*origin).to_ned(p))
}

#[cfg(test)]
mod tests;
