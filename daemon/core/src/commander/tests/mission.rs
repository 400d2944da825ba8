//! Mission mode, repositions, orbits and the guided commands, flown by a vehicle that follows its
//! set-point exactly (the commander's logic alone; closed-loop flights are in `tests/`).

use super::*;
use crate::math::geo::{LatLonAlt, LocalFrame};
use crate::mission::{MissionAltitude, MissionItem, MissionPoint, MissionState, SpeedChange};
use nalgebra::Vector2;

const ORIGIN: LatLonAlt = LatLonAlt {
    lat_deg: 47.397742,
    lon_deg: 8.545594,
    alt_m: 488.0,
};

/// A point `north`, `east` of the origin, `up` above home.
fn point(north: f64, east: f64, up: f64) -> MissionPoint {
    let g = LocalFrame::new(ORIGIN).to_geodetic(&Vector3::new(north, east, 0.0));
    MissionPoint {
        lat_lon_deg: Some((g.lat_deg, g.lon_deg)),
        alt: Some(MissionAltitude::AboveHome(up)),
    }
}

fn waypoint(north: f64, east: f64, up: f64) -> MissionItem {
    MissionItem::Waypoint {
        at: point(north, east, up),
        hold_s: 0.0,
        acceptance_m: Some(0.5),
        yaw_rad: None,
    }
}

/// A vehicle that is where its set-point is (never below the ground), 50 Hz.
struct Follower {
    c: Commander,
    t: f64,
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    yaw: f64,
    /// The set-points flown.
    path: Vec<PositionSetpoint>,
    /// North of this the vehicle is outside its geofence (what the caller's fence check says).
    fence_north_m: f64,
    /// Where the set-point's velocity takes the vehicle from its position in a step, rather
    /// than onto the position (an orbit's set-point is the nearest point of the circle).
    leads: bool,
}

impl Follower {
    fn new(params: CommanderParams) -> Self {
        let mut f = Self {
            c: Commander::new(params),
            t: 0.0,
            pos: Vector3::zeros(),
            vel: Vector3::zeros(),
            yaw: 0.0,
            path: Vec::new(),
            fence_north_m: f64::INFINITY,
            leads: false,
        };
        f.step();
        f
    }

    fn input(&self) -> CommanderInput {
        let mut i = CommanderInput {
            origin: Some(ORIGIN),
            ..at(self.t, self.pos, self.vel, self.yaw)
        };
        i.health.geofence_breached = self.pos.x > self.fence_north_m;
        i
    }

    fn step(&mut self) -> PositionSetpoint {
        let i = self.input();
        let (sp, armed) = step(&mut self.c, &i);
        let dt = 0.02;
        self.t += dt;
        if armed {
            let mut next = self.pos;
            for k in 0..3 {
                if sp.pos_ned_m[k].is_finite() && self.leads {
                    next[k] = sp.pos_ned_m[k] + sp.vel_ned_m_s[k] * dt;
                } else if sp.pos_ned_m[k].is_finite() {
                    next[k] = sp.pos_ned_m[k];
                } else if sp.vel_ned_m_s[k].is_finite() {
                    next[k] += sp.vel_ned_m_s[k] * dt;
                }
            }
            next.z = next.z.min(0.0);
            self.vel = (next - self.pos) / dt;
            self.pos = next;
            self.yaw = sp.yaw_rad;
            self.path.push(sp);
        } else {
            self.vel = Vector3::zeros();
        }
        sp
    }

    /// Steps until `done` or `limit_s` of time; returns whether `done` happened.
    fn until(&mut self, limit_s: f64, mut done: impl FnMut(&Self) -> bool) -> bool {
        let end = self.t + limit_s;
        while self.t < end {
            if done(self) {
                return true;
            }
            self.step();
        }
        false
    }

    fn reached(&self) -> Vec<u16> {
        self.c.mission_status().reached_since(0).collect()
    }
}

#[test]
fn a_mission_is_refused_until_there_is_one_and_a_global_position() {
    let mut f = Follower::new(CommanderParams::default());
    let err = f.c.set_mode(FlightMode::Mission).unwrap_err();
    assert!(err.to_string().contains("no mission"), "{err}");
    assert_eq!(f.c.mission_status().state, MissionState::NoMission);
    f.c.set_mission(vec![waypoint(10.0, 0.0, 5.0)]);
    assert_eq!(f.c.mission_status().state, MissionState::NotStarted);
    assert_eq!(f.c.mission_status().total, 1);
    let mut no_gps = Commander::new(CommanderParams::default());
    step(&mut no_gps, &input(0.0, 0.0, 0.0));
    no_gps.set_mission(vec![waypoint(10.0, 0.0, 5.0)]);
    let err = no_gps.set_mode(FlightMode::Mission).unwrap_err();
    assert!(err.to_string().contains("global position"), "{err}");
    assert!(f.c.set_mission_current(1).is_err(), "no item 1");
    f.c.set_mode(FlightMode::Mission).unwrap();
    f.c.arm(false).unwrap();
}

/// Take-off item, a square with a speed change, a timed loiter and one repeat of two legs by
/// a jump, then RTL: every item reached once (the jumped-over ones twice), in order, each
/// waypoint within its acceptance radius, the legs straight, a plain waypoint before another
/// flown through on an arc inside the corner, and landed at home.
#[test]
fn a_square_mission_is_flown_item_by_item_and_ends_landed_at_home() {
    let mut f = Follower::new(CommanderParams {
        cruise_speed_m_s: 5.0,
        ..CommanderParams::default()
    });
    let items = vec![
        MissionItem::Takeoff {
            at: MissionPoint {
                lat_lon_deg: None,
                alt: Some(MissionAltitude::AboveHome(10.0)),
            },
            yaw_rad: None,
        }, // 0
        waypoint(20.0, 0.0, 10.0),                      // 1
        MissionItem::ChangeSpeed(SpeedChange::To(3.0)), // 2
        waypoint(20.0, 20.0, 10.0),                     // 3
        waypoint(0.0, 20.0, 10.0),                      // 4
        MissionItem::Jump {
            to: 3,
            repeat: Some(1),
        }, // 5
        MissionItem::LoiterTime {
            at: point(0.0, 0.0, 12.0),
            time_s: 3.0,
        }, // 6
        MissionItem::ReturnToLaunch,                    // 7
    ];
    f.c.set_mission(items.clone());
    f.c.set_mode(FlightMode::Mission).unwrap();
    f.c.arm(false).unwrap();
    let mut reached_at: Vec<(u16, Vector3<f64>, f64)> = Vec::new();
    let mut shown = 0;
    let mut max_speed: f64 = 0.0;
    let mut off_leg: f64 = 0.0;
    let mut outside: f64 = 0.0;
    let mut speed_at: Vec<(u16, f64)> = Vec::new();
    while f.c.armed() && f.t < 300.0 {
        let sp = f.step();
        for seq in f.c.mission_status().reached_since(shown) {
            reached_at.push((seq, f.pos, f.t));
            speed_at.push((seq, sp.vel_ned_m_s.xy().norm()));
        }
        shown = f.c.mission_status().reached_count;
        let cur = f.c.mission_status().current;
        max_speed = max_speed.max(sp.vel_ned_m_s.xy().norm());
        // Between items 3 and 4 (north 20 → 0 at east 20): the corner at item 3 rounded inside
        // the square (its arc ends 1 m on), then the straight line.
        if cur == 4 && f.pos.z < -9.0 {
            outside = outside.max(f.pos.y - 20.0).max(f.pos.x - 20.0);
            if f.pos.x < 19.0 - 1e-6 {
                off_leg = off_leg.max((f.pos.y - 20.0).abs());
            }
        }
    }
    // Flown through item 3 (a plain waypoint before another), stopped at item 4 (a jump next).
    let first = |seq: u16| speed_at.iter().find(|s| s.0 == seq).map(|s| s.1).unwrap();
    assert!(first(3) > 0.2, "through item 3 at {} m/s", first(3));
    assert!(first(4) < 1e-6, "stopped at item 4: {} m/s", first(4));
    assert!(outside < 1e-3, "inside the square at the corner: {outside}");
    let order: Vec<u16> = reached_at.iter().map(|r| r.0).collect();
    assert_eq!(order, [0, 1, 2, 3, 4, 5, 3, 4, 5, 6, 7], "reached in order");
    let status = f.c.mission_status();
    assert_eq!(status.state, MissionState::Complete);
    assert!(!f.c.armed(), "disarmed after RTL");
    assert!(
        f.pos.xy().norm() < 0.5 && f.pos.z.abs() < 1e-9,
        "home: {:?}",
        f.pos
    );
    for (seq, pos, _) in &reached_at {
        if let MissionItem::Waypoint { at, .. } = items[*seq as usize] {
            let target = at.to_ned(&ORIGIN, &Vector3::zeros(), pos);
            assert!((pos - target).norm() <= 0.5, "item {seq} at {pos:?}");
        }
    }
    assert!(max_speed <= 5.0 + 1e-9, "cruise speed kept: {max_speed}");
    assert!(off_leg < 1e-3, "straight leg: {off_leg}");
    // The speed change to 3 m/s: the legs after item 2 are flown at 3 m/s.
    let leg4 = f.path.iter().map(|s| s.vel_ned_m_s.xy().norm());
    assert!(leg4.clone().any(|v| (v - 3.0).abs() < 1e-9));
    // The loiter held for its 3 s.
    let t6 = reached_at.iter().find(|r| r.0 == 6).map(|r| r.2).unwrap();
    let t5 = reached_at
        .iter()
        .rev()
        .find(|r| r.0 == 5)
        .map(|r| r.2)
        .unwrap();
    assert!(t6 - t5 > 3.0, "loitered {}", t6 - t5);
    // Acceleration limited along the legs.
    let accel = f
        .path
        .iter()
        .map(|s| s.accel_ned_m_s2.norm())
        .fold(0.0, f64::max);
    assert!(accel <= f.c.params().accel_m_s2 + 1e-9, "accel {accel}");
    // A heading along each leg: flying east on item 3's leg.
    assert!(f.path.iter().any(|s| (s.yaw_rad - FRAC_PI_2).abs() < 1e-6));
}

/// A waypoint with a hold time stops and holds there though a waypoint follows; a plain one is
/// flown through; the last before a landing is reached at rest.
#[test]
fn a_hold_time_and_a_landing_next_stop_the_vehicle_and_plain_waypoints_do_not() {
    let mut f = Follower::new(CommanderParams::default());
    let held = MissionItem::Waypoint {
        at: point(15.0, 0.0, 5.0),
        hold_s: 2.0,
        acceptance_m: Some(0.5),
        yaw_rad: None,
    };
    let items = vec![
        held,                      // 0
        waypoint(15.0, 15.0, 5.0), // 1
        waypoint(0.0, 15.0, 5.0),  // 2
        MissionItem::Land {
            at: point(0.0, 15.0, 0.0),
            yaw_rad: None,
        }, // 3
    ];
    f.c.set_mission(items);
    f.c.set_mode(FlightMode::Mission).unwrap();
    f.c.arm(false).unwrap();
    let mut shown = 0;
    let mut reached: Vec<(u16, f64, f64)> = Vec::new(); // item, speed, time
    let mut arrived_at_0 = None;
    while f.c.armed() && f.t < 120.0 {
        let sp = f.step();
        if (f.pos - Vector3::new(15.0, 0.0, -5.0)).norm() < 1e-6 && f.vel.norm() < 1e-9 {
            arrived_at_0.get_or_insert(f.t);
        }
        for seq in f.c.mission_status().reached_since(shown) {
            reached.push((seq, sp.vel_ned_m_s.xy().norm(), f.t));
        }
        shown = f.c.mission_status().reached_count;
    }
    let at = |seq: u16| *reached.iter().find(|r| r.0 == seq).unwrap();
    assert!(
        at(0).1 < 1e-6 && at(1).1 > 0.5 && at(2).1 < 1e-6,
        "{reached:?}"
    );
    // At item 0 at rest, it holds there 2 s before the item is done.
    let held_s = at(0).2 - arrived_at_0.unwrap();
    assert!((1.98..2.1).contains(&held_s), "held {held_s} s");
    assert!(!f.c.armed() && (f.pos - Vector3::new(0.0, 15.0, 0.0)).norm() < 0.5);
}

#[test]
fn leaving_mission_pauses_it_and_coming_back_resumes_the_same_item() {
    let mut f = Follower::new(CommanderParams::default());
    f.c.set_mission(vec![waypoint(0.0, 0.0, 5.0), waypoint(40.0, 0.0, 5.0)]);
    f.c.set_mode(FlightMode::Mission).unwrap();
    f.c.arm(false).unwrap();
    assert!(f.until(60.0, |f| f.pos.x > 10.0));
    assert_eq!(f.c.mission_status().current, 1);
    f.c.set_mode(FlightMode::Loiter).unwrap();
    assert_eq!(f.c.mission_status().state, MissionState::Paused);
    f.until(5.0, |_| false);
    let held = f.pos;
    f.until(2.0, |_| false);
    assert!((f.pos - held).norm() < 1e-9, "holding");
    f.c.set_mode(FlightMode::Mission).unwrap();
    assert!(f.until(60.0, |f| f.c.mission_status().state
        == MissionState::Complete));
    assert_eq!(f.reached(), [0, 1], "resumed at item 1, not from the start");
    assert!((f.pos - Vector3::new(40.0, 0.0, -5.0)).norm() < 0.5);
    // Complete: hold there; entering Mission again starts over.
    f.c.set_mode(FlightMode::Loiter).unwrap();
    f.c.set_mode(FlightMode::Mission).unwrap();
    assert_eq!(f.c.mission_status().state, MissionState::NotStarted);
    assert!(f.until(60.0, |f| f.c.mission_status().reached_count == 3));
    assert!(f.pos.xy().norm() < 0.5, "back at item 0");
}

#[test]
fn set_current_jumps_and_a_jump_forever_keeps_looping() {
    let mut f = Follower::new(CommanderParams::default());
    f.c.set_mission(vec![
        waypoint(0.0, 0.0, 5.0),
        waypoint(10.0, 0.0, 5.0),
        MissionItem::Jump {
            to: 0,
            repeat: None,
        },
        waypoint(99.0, 0.0, 5.0),
    ]);
    f.c.set_mission_current(1).unwrap();
    f.c.set_mode(FlightMode::Mission).unwrap();
    f.c.arm(false).unwrap();
    assert!(f.until(200.0, |f| f.c.mission_status().reached_count >= 7));
    let r = f.reached();
    assert_eq!(&r[..6], [1, 2, 0, 1, 2, 0], "from item 1, round and round");
    assert!(
        f.path.iter().all(|s| s.pos_ned_m.x < 11.0),
        "item 3 never flown"
    );
    // A jump-only loop holds instead of spinning.
    let mut g = Follower::new(CommanderParams::default());
    g.c.set_mission(vec![
        waypoint(0.0, 0.0, 5.0),
        MissionItem::Jump {
            to: 2,
            repeat: None,
        },
        MissionItem::Jump {
            to: 1,
            repeat: None,
        },
    ]);
    g.c.set_mode(FlightMode::Mission).unwrap();
    g.c.arm(false).unwrap();
    assert!(g.until(30.0, |g| g.c.mission_status().reached_count >= 3));
    let p = g.pos;
    g.until(1.0, |_| false);
    assert!((g.pos - p).norm() < 1e-6, "holds in a loop of jumps");
}

#[test]
fn land_item_touches_down_where_it_says_and_a_delay_waits() {
    let mut f = Follower::new(CommanderParams::default());
    let g = point(10.0, 5.0, 0.0);
    f.c.set_mission(vec![
        MissionItem::Takeoff {
            at: MissionPoint {
                lat_lon_deg: None,
                alt: Some(MissionAltitude::AboveHome(4.0)),
            },
            yaw_rad: None,
        },
        MissionItem::Delay { delay_s: 2.0 },
        MissionItem::Land {
            at: g,
            yaw_rad: Some(1.0),
        },
    ]);
    f.c.set_mode(FlightMode::Mission).unwrap();
    f.c.arm(false).unwrap();
    assert!(f.until(10.0, |f| f.c.mission_status().reached_count == 1));
    assert!((f.pos.z + 4.0).abs() < 0.3, "took off to 4 m: {:?}", f.pos);
    let t0 = f.t;
    assert!(f.until(10.0, |f| f.c.mission_status().reached_count == 2));
    assert!((f.t - t0 - 2.0).abs() < 0.1, "waited {}", f.t - t0);
    assert!(f.until(60.0, |f| !f.c.armed()));
    assert_eq!(f.reached(), [0, 1, 2]);
    assert_eq!(f.c.mission_status().state, MissionState::Complete);
    assert!(
        (f.pos - Vector3::new(10.0, 5.0, 0.0)).norm() < 0.1,
        "{:?}",
        f.pos
    );
    assert!((f.yaw - 1.0).abs() < 1e-6, "the item's heading");
    // Armed again in Mission: the mission starts over (a take-off first).
    f.c.arm(false).unwrap();
    assert_eq!(f.c.mission_status().state, MissionState::NotStarted);
}

#[test]
fn reposition_flies_to_the_point_and_holds_and_yaw_and_speed_commands_apply() {
    let mut f = Follower::new(CommanderParams::default());
    let there = Vector3::new(30.0, -10.0, -8.0);
    assert!(
        f.c.reposition(there, None, None, true).is_err(),
        "not flying"
    );
    f.c.takeoff(Some(5.0)).unwrap();
    f.c.arm(false).unwrap();
    assert!(f.until(20.0, |f| f.c.mode() == FlightMode::Loiter));
    f.c.set_mode(FlightMode::Land).unwrap();
    let err = f.c.reposition(there, None, None, false).unwrap_err();
    assert!(err.to_string().contains("not in Hold"), "{err}");
    f.c.reposition(there, Some(2.0), Some(-FRAC_PI_2), true)
        .unwrap();
    assert_eq!(f.c.mode(), FlightMode::Loiter);
    let t0 = f.t;
    assert!(f.until(60.0, |f| (f.pos - there).norm() < 1e-6));
    let d = 30.0_f64.hypot(10.0).hypot(3.0);
    assert!(f.t - t0 > d / 2.0, "at 2 m/s: {} s", f.t - t0);
    assert!(
        (f.yaw + FRAC_PI_2).abs() < 1e-6,
        "turned to the heading asked"
    );
    f.until(2.0, |_| false);
    assert!((f.pos - there).norm() < 1e-6, "holds there");
    // CONDITION_YAW turns at its rate.
    f.c.condition_yaw(0.0, Some(0.5)).unwrap();
    let t0 = f.t;
    assert!(f.until(10.0, |f| f.yaw.abs() < 1e-6));
    assert!((f.t - t0 - FRAC_PI_2 / 0.5).abs() < 0.1, "{}", f.t - t0);
    // DO_CHANGE_SPEED applies to the next leg and to the one in progress.
    f.c.change_speed(SpeedChange::To(1.0)).unwrap();
    assert!(f.c.change_speed(SpeedChange::To(-1.0)).is_err());
    f.c.reposition(Vector3::new(30.0, 60.0, f64::NAN), None, None, false)
        .unwrap();
    f.until(10.0, |_| false);
    assert!((f.vel.xy().norm() - 1.0).abs() < 1e-6, "{:?}", f.vel);
    assert!((f.pos.z + 8.0).abs() < 1e-9, "altitude kept (NaN)");
    f.c.change_speed(SpeedChange::To(4.0)).unwrap();
    f.until(4.0, |_| false);
    assert!((f.vel.xy().norm() - 4.0).abs() < 1e-6, "{:?}", f.vel);
}

/// An uploaded fence breached on a reposition leg (the caller's check): `GF_ACTION` Hold stops
/// the leg at the breach, braking at `MPC_ACC_FS_BRK` (not the gentle `MPC_ACC_HOR`, which would
/// carry it 12.5 m on), even though the vehicle was in Hold already.
#[test]
fn a_fence_breach_on_a_reposition_leg_stops_it() {
    let mut f = Follower::new(CommanderParams::default());
    f.fence_north_m = 12.0;
    f.c.takeoff(Some(5.0)).unwrap();
    f.c.arm(false).unwrap();
    assert!(f.until(20.0, |f| f.c.mode() == FlightMode::Loiter));
    f.c.reposition(Vector3::new(25.0, 0.0, -5.0), None, None, false)
        .unwrap();
    f.until(30.0, |_| false);
    assert_eq!(f.c.mode(), FlightMode::Loiter);
    assert!(
        f.pos.x > 12.0 && f.pos.x < 17.5,
        "stopped at {:?} (fence at 12 m, braking from 5 m/s at 2.5 m/s²: 5 m)",
        f.pos
    );
}

/// Hovering at 5 m, ready for an orbit.
fn hovering_follower() -> Follower {
    let mut f = Follower::new(CommanderParams::default());
    f.leads = true;
    f.c.takeoff(Some(5.0)).unwrap();
    f.c.arm(false).unwrap();
    assert!(f.until(20.0, |f| f.c.mode() == FlightMode::Loiter));
    f
}

/// `DO_ORBIT` about a point 20 m north, 10 m clockwise at 5 m/s: the vehicle flies to the
/// circle facing the centre, then circles it on the radius, north → east → south, the front
/// at the centre; the status says the orbit; asked for one turn, it holds after one.
#[test]
fn an_orbit_flies_to_its_circle_then_circles_it_and_holds_after_its_turns() {
    let mut f = hovering_follower();
    let center = Vector2::new(20.0, 0.0);
    f.c.orbit(OrbitRequest {
        radius_m: Some(10.0),
        speed_m_s: Some(5.0),
        center_ne_m: Some(center),
        center_down_m: Some(-8.0),
        turns: Some(1.0),
        ..OrbitRequest::default()
    })
    .unwrap();
    assert_eq!(f.c.mode(), FlightMode::Orbit);
    let s = f.c.status().orbit.unwrap();
    assert!(
        !s.circling && s.radius_m == 10.0 && s.speed_m_s == 5.0,
        "{s:?}"
    );
    assert!(f.until(30.0, |f| f.c.status().orbit.is_some_and(|o| o.circling)));
    let on = f.pos;
    assert!(((on.xy() - center).norm() - 10.0).abs() < 0.5 && (on.z + 8.0).abs() < 0.5);
    // Half a turn: clockwise seen from above, on the radius, facing the centre, at 5 m/s.
    let mut worst = 0.0f64;
    let mut angle = (on.y - center.y).atan2(on.x - center.x);
    let mut turned = 0.0;
    let t0 = f.t;
    while f.t - t0 < 5.0 {
        f.step();
        let rel = f.pos.xy() - center;
        let a = rel.y.atan2(rel.x);
        turned += wrap(a - angle);
        angle = a;
        worst = worst.max((rel.norm() - 10.0).abs());
        let facing = wrap(f.yaw - (-rel.y).atan2(-rel.x)).abs();
        assert!(
            f.t - t0 < 2.0 || facing < 0.05,
            "facing {facing} rad off the centre"
        );
    }
    assert!(turned > 0.0, "clockwise: {turned}");
    assert!(worst < 0.3, "{worst} m off the radius");
    let speed = f.vel.xy().norm();
    assert!((speed - 5.0).abs() < 0.1, "{speed} m/s");
    assert!(
        f.until(20.0, |f| f.c.mode() == FlightMode::Loiter),
        "one turn, then Hold"
    );
    assert!(f.c.status().orbit.is_none());
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// What an orbit cannot be: on the ground, radii under 1 m or over `MC_ORBIT_RAD_MAX`, speeds
/// not above zero or absurd, a centre too far from home; a speed above the radius's bound is
/// lowered to it; a command that leaves parts out keeps the orbit's.
#[test]
fn orbits_that_cannot_be_flown_are_refused_with_the_reason() {
    let mut f = Follower::new(CommanderParams::default());
    let err = f.c.orbit(OrbitRequest::default()).unwrap_err();
    assert!(err.to_string().contains("not flying"), "{err}");
    let mut f = hovering_follower();
    for (radius, speed, why) in [
        (0.5, 2.0, "radius"),
        (-0.0, 2.0, "radius"),
        (2000.0, 2.0, "radius"),
        (f64::INFINITY, 2.0, "radius"),
        (10.0, 0.0, "speed"),
        (10.0, -3.0, "speed"),
        (10.0, 100.0, "speed"),
    ] {
        let req = OrbitRequest {
            radius_m: Some(radius),
            speed_m_s: Some(speed),
            ..OrbitRequest::default()
        };
        let err = f.c.orbit(req).unwrap_err();
        assert!(
            err.to_string().contains(why),
            "{radius} m, {speed} m/s: {err}"
        );
        assert_eq!(f.c.mode(), FlightMode::Loiter);
    }
    let far = OrbitRequest {
        center_ne_m: Some(Vector2::new(1e7, 0.0)),
        ..OrbitRequest::default()
    };
    assert!(f.c.orbit(far).is_err());
    // 5 m/s on 4 m: √(3 m/s² × 4 m) = 3.46 m/s.
    f.c.orbit(OrbitRequest {
        radius_m: Some(-4.0),
        speed_m_s: Some(5.0),
        ..OrbitRequest::default()
    })
    .unwrap();
    let s = f.c.status().orbit.unwrap();
    assert!(
        (s.speed_m_s - 12.0f64.sqrt()).abs() < 1e-9 && s.radius_m == -4.0,
        "{s:?}"
    );
    // Only the speed changes: the centre (where it was) and the radius stay.
    f.until(3.0, |_| false);
    f.c.orbit(OrbitRequest {
        speed_m_s: Some(1.0),
        ..OrbitRequest::default()
    })
    .unwrap();
    let t = f.c.status().orbit.unwrap();
    assert_eq!(
        (t.center_ned_m, t.radius_m, t.speed_m_s),
        (s.center_ned_m, -4.0, 1.0)
    );
}

/// Follow Target: refused on the ground; in the air it holds until the first fix, then flies
/// 8 m behind a target walking north at 2 m/s, facing it, 8 m above home; fixes not numbers or
/// 10 km away are refused; when the fixes stop the target stands where it was last estimated
/// and the vehicle stops behind it.
#[test]
fn follow_target_flies_behind_the_target_and_stops_when_its_fixes_do() {
    let mut f = Follower::new(CommanderParams::default());
    assert!(
        f.c.set_mode(FlightMode::FollowTarget).is_err(),
        "on the ground"
    );
    let mut f = hovering_follower();
    f.leads = false;
    f.c.set_mode(FlightMode::FollowTarget).unwrap();
    let at = f.pos;
    f.until(2.0, |_| false);
    assert!((f.pos - at).norm() < 1e-6, "holds without a fix");
    let fix = |n: f64| TargetFix {
        pos_ned_m: Vector3::new(n, 0.0, 0.0),
        vel_ned_m_s: None,
    };
    let nan = TargetFix {
        pos_ned_m: Vector3::new(f64::NAN, 0.0, 0.0),
        vel_ned_m_s: None,
    };
    assert!(f.c.follow_target_fix(nan).is_err());
    assert!(f.c.follow_target_fix(fix(1e7)).is_err(), "10 000 km away");
    let err = f.c.follow_target_fix(fix(1e4)).unwrap_err();
    assert!(err.to_string().contains("away"), "10 km: {err}");
    let t0 = f.t;
    let mut next = t0;
    while f.t - t0 < 30.0 {
        if f.t >= next {
            f.c.follow_target_fix(fix(2.0 * (f.t - t0))).unwrap();
            next += 0.5;
        }
        f.step();
    }
    let target = 2.0 * (f.t - t0);
    let behind = target - f.pos.x;
    assert!(
        (behind - 8.0).abs() < 1.0 && f.pos.y.abs() < 0.5,
        "{behind} m behind, {:?}",
        f.pos
    );
    assert!((f.pos.z + 8.0).abs() < 0.1, "8 m above home: {}", f.pos.z);
    assert!(f.yaw.abs() < 0.1, "facing it (north): {}", f.yaw);
    // The fixes stop: after STALE_S the target stands; the vehicle stops behind it.
    f.until(crate::commander::FOLLOW_STALE_S + 5.0, |_| false);
    let stood = f.c.status().follow.unwrap();
    assert!(stood.stale, "{stood:?}");
    let here = f.pos;
    f.until(3.0, |_| false);
    assert!(
        (f.pos - here).norm() < 0.01,
        "stopped: {:?} → {:?}",
        here,
        f.pos
    );
    assert_eq!(f.c.mode(), FlightMode::FollowTarget);
}
