//! Missions as the commander flies them: the items a ground station uploads (MAVLink's
//! `MAV_CMD_NAV_*` and `MAV_CMD_DO_*`, already checked and decoded), where their positions are
//! in the local frame, and the mission's progress as telemetry reports it (`MISSION_CURRENT`,
//! `MISSION_ITEM_REACHED`).
//!
//! The MAVLink side (the upload and download protocol, which commands and frames are accepted)
//! is the daemon's; the commander's Mission mode flies a `Vec<MissionItem>`.

use crate::math::geo::{LatLonAlt, LocalFrame};
use nalgebra::Vector3;

/// An altitude as a mission item gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MissionAltitude {
    /// Above home (m): MAVLink's `*_RELATIVE_ALT` frames.
    AboveHome(f64),
    /// Above mean sea level (m): MAVLink's `GLOBAL` frames.
    Amsl(f64),
}

/// Where a navigation item goes. A missing part is where the vehicle is when the item starts
/// (a take-off or landing without coordinates, a loiter "here").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionPoint {
    /// Latitude and longitude (deg).
    pub lat_lon_deg: Option<(f64, f64)>,
    /// Altitude.
    pub alt: Option<MissionAltitude>,
}

impl MissionPoint {
    /// The point in the local NED frame of `origin` (m), with home at `home_ned_m`; the parts
    /// it leaves open are taken from `here_ned_m`.
    pub fn to_ned(
        &self,
        origin: &LatLonAlt,
        home_ned_m: &Vector3<f64>,
        here_ned_m: &Vector3<f64>,
    ) -> Vector3<f64> {
        let frame = LocalFrame::new(*origin);
        let mut p = *here_ned_m;
        if let Some((lat_deg, lon_deg)) = self.lat_lon_deg {
            let ned = frame.to_ned(&LatLonAlt {
                lat_deg,
                lon_deg,
                alt_m: origin.alt_m,
            });
            p.x = ned.x;
            p.y = ned.y;
        }
        match self.alt {
            Some(MissionAltitude::AboveHome(h)) => p.z = home_ned_m.z - h,
            Some(MissionAltitude::Amsl(a)) => p.z = origin.alt_m - a,
            None => {}
        }
        p
    }
}

/// What a `DO_CHANGE_SPEED` asks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpeedChange {
    /// This horizontal speed (m/s).
    To(f64),
    /// Back to `MPC_XY_CRUISE` (MAVLink's −2).
    Default,
    /// Nothing (MAVLink's −1).
    Unchanged,
}

/// One mission item, in the terms of its `MAV_CMD`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MissionItem {
    /// `MAV_CMD_NAV_WAYPOINT`: fly there, reach it within the acceptance radius, stay for the
    /// hold time; the heading is the item's, or along the leg.
    Waypoint {
        /// Where.
        at: MissionPoint,
        /// Time to stay once reached (s).
        hold_s: f64,
        /// Horizontal acceptance radius (m); `None`: `NAV_ACC_RAD`.
        acceptance_m: Option<f64>,
        /// Heading (rad); `None`: along the leg.
        yaw_rad: Option<f64>,
    },
    /// `MAV_CMD_NAV_TAKEOFF`: climb to the item's altitude (from the ground: a take-off).
    Takeoff {
        /// Where; usually only the altitude.
        at: MissionPoint,
        /// Heading (rad); `None`: kept.
        yaw_rad: Option<f64>,
    },
    /// `MAV_CMD_NAV_LAND`: fly over the point (or land where it is), descend, touch down.
    Land {
        /// Where; the altitude is ignored.
        at: MissionPoint,
        /// Heading (rad); `None`: kept.
        yaw_rad: Option<f64>,
    },
    /// `MAV_CMD_NAV_RETURN_TO_LAUNCH`: return home and land, as the RTL mode.
    ReturnToLaunch,
    /// `MAV_CMD_NAV_LOITER_TIME`: fly there and hold for a time.
    LoiterTime {
        /// Where.
        at: MissionPoint,
        /// How long (s).
        time_s: f64,
    },
    /// `MAV_CMD_NAV_LOITER_UNLIM`: fly there and hold until told otherwise.
    LoiterUnlimited {
        /// Where.
        at: MissionPoint,
    },
    /// `MAV_CMD_NAV_DELAY`: hold where it is for a time.
    Delay {
        /// How long (s).
        delay_s: f64,
    },
    /// `MAV_CMD_DO_CHANGE_SPEED`: the horizontal speed of the legs that follow.
    ChangeSpeed(SpeedChange),
    /// `MAV_CMD_DO_JUMP`: go back (or forward) to item `to`, `repeat` times (`None`: forever).
    Jump {
        /// The item to continue at (its sequence number).
        to: u16,
        /// How often; `None` repeats forever.
        repeat: Option<u32>,
    },
    /// `MAV_CMD_DO_SET_HOME`: home here (`None`) or at the point.
    SetHome {
        /// Where, or the current position.
        at: Option<MissionPoint>,
    },
}

impl MissionItem {
    /// Whether the item moves the vehicle or waits (a `NAV_*` command), as opposed to one done
    /// at once (a `DO_*` command).
    pub fn is_nav(&self) -> bool {
        !matches!(
            self,
            Self::ChangeSpeed(_) | Self::Jump { .. } | Self::SetHome { .. }
        )
    }
}

/// A mission's state, as `MISSION_CURRENT.mission_state` reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MissionState {
    /// No mission uploaded.
    #[default]
    NoMission,
    /// A mission, not started (or started afresh).
    NotStarted,
    /// Being flown.
    Active,
    /// Left for another mode before its end; entering Mission resumes it.
    Paused,
    /// Its last item is done.
    Complete,
}

/// How many of the latest reached items [`MissionStatus`] keeps.
pub const REACHED_KEPT: usize = 8;

/// A mission's progress.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MissionStatus {
    /// The current item (its sequence number); `total` once complete.
    pub current: u16,
    /// How many items.
    pub total: u16,
    /// The state.
    pub state: MissionState,
    /// Items reached since start-up (every item done counts, `DO_*` ones too).
    pub reached_count: u32,
    /// The latest reached items: item `reached_count - 1 - k` is
    /// `reached_recent[(reached_count - 1 - k) % REACHED_KEPT]`.
    pub reached_recent: [u16; REACHED_KEPT],
}

impl MissionStatus {
    /// The items reached after the first `shown` ones, oldest first (at most the last
    /// [`REACHED_KEPT`]).
    pub fn reached_since(&self, shown: u32) -> impl Iterator<Item = u16> + '_ {
        let from = shown.max(self.reached_count.saturating_sub(REACHED_KEPT as u32));
        (from..self.reached_count).map(|n| self.reached_recent[n as usize % REACHED_KEPT])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_resolve_against_origin_home_and_here() {
        let origin = LatLonAlt {
            lat_deg: 47.397742,
            lon_deg: 8.545594,
            alt_m: 488.0,
        };
        let frame = LocalFrame::new(origin);
        let home = Vector3::new(1.0, 2.0, -0.5);
        let here = Vector3::new(5.0, 6.0, -10.0);
        let far = frame.to_geodetic(&Vector3::new(30.0, -40.0, 0.0));
        let p = MissionPoint {
            lat_lon_deg: Some((far.lat_deg, far.lon_deg)),
            alt: Some(MissionAltitude::AboveHome(20.0)),
        };
        let ned = p.to_ned(&origin, &home, &here);
        assert!((ned.xy() - nalgebra::Vector2::new(30.0, -40.0)).norm() < 1e-6);
        assert!(
            (ned.z - (-20.5)).abs() < 1e-9,
            "relative to home, not to the origin"
        );
        let amsl = MissionPoint {
            lat_lon_deg: None,
            alt: Some(MissionAltitude::Amsl(500.0)),
        };
        let ned = amsl.to_ned(&origin, &home, &here);
        assert_eq!(
            ned,
            Vector3::new(5.0, 6.0, -12.0),
            "here, 12 m above the origin"
        );
        let here_only = MissionPoint {
            lat_lon_deg: None,
            alt: None,
        };
        assert_eq!(here_only.to_ned(&origin, &home, &here), here);
    }

    #[test]
    fn reached_items_are_reported_once_each_and_in_order() {
        let mut s = MissionStatus {
            current: 0,
            total: 20,
            state: MissionState::Active,
            reached_count: 0,
            reached_recent: [0; REACHED_KEPT],
        };
        let reach = |s: &mut MissionStatus, seq: u16| {
            s.reached_recent[s.reached_count as usize % REACHED_KEPT] = seq;
            s.reached_count += 1;
        };
        for seq in [0, 1, 2] {
            reach(&mut s, seq);
        }
        assert_eq!(s.reached_since(0).collect::<Vec<_>>(), [0, 1, 2]);
        assert_eq!(s.reached_since(2).collect::<Vec<_>>(), [2]);
        for seq in 3..13 {
            reach(&mut s, seq);
        }
        // Only the last REACHED_KEPT survive a long silence.
        assert_eq!(
            s.reached_since(1).collect::<Vec<_>>(),
            (5..13).collect::<Vec<_>>()
        );
        assert_eq!(s.reached_since(13).count(), 0);
    }
}
