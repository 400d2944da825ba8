#![allow(clippy::unwrap_used)]
use super::*;
use flight_core::math::geo::LatLonAlt;
use flight_core::mission::{MissionAltitude, SpeedChange};
use flight_core::safety::geofence::GeoZone;
use flight_core::safety::targets::TargetLimits;
use nalgebra::Vector3;

const GCS: (u8, u8) = (255, 190);

fn header(peer: (u8, u8)) -> MavHeader {
    MavHeader {
        system_id: peer.0 as _,
        component_id: peer.1,
        sequence: 0,
    }
}

fn item(
    seq: u16,
    command: MavCmd,
    frame: MavFrame,
    p: [f32; 4],
    xyz: (i32, i32, f32),
) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        x: xyz.0,
        y: xyz.1,
        z: xyz.2,
        seq,
        command,
        target_system: 1,
        target_component: 1,
        frame,
        current: (seq == 0) as u8,
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
    }
}

/// A take-off, a waypoint in each frame MAVSDK uses, a speed change and a return.
fn square() -> Vec<MISSION_ITEM_INT_DATA> {
    use MavCmd::*;
    use MavFrame::*;
    let nan = f32::NAN;
    vec![
        item(
            0,
            MAV_CMD_NAV_TAKEOFF,
            MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            [0.0, 0.0, 0.0, nan],
            (0, 0, 10.0),
        ),
        item(
            1,
            MAV_CMD_NAV_WAYPOINT,
            MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            [0.0, 1.0, 0.0, nan],
            (473_977_420, 85_455_940, 10.0),
        ),
        item(
            2,
            MAV_CMD_DO_CHANGE_SPEED,
            MAV_FRAME_MISSION,
            [1.0, 3.0, -1.0, 0.0],
            (0, 0, 0.0),
        ),
        item(
            3,
            MAV_CMD_NAV_WAYPOINT,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            [2.0, 0.0, 0.0, 90.0],
            (473_978_320, 85_455_940, 10.0),
        ),
        item(
            4,
            MAV_CMD_NAV_WAYPOINT,
            MAV_FRAME_GLOBAL_INT,
            [0.0, 0.0, 0.0, nan],
            (473_978_320, 85_457_270, 498.0),
        ),
        item(
            5,
            MAV_CMD_NAV_RETURN_TO_LAUNCH,
            MAV_FRAME_MISSION,
            [0.0; 4],
            (0, 0, 0.0),
        ),
    ]
}

fn send(m: &mut Missions, peer: (u8, u8), msg: MavMessage) -> Outbox {
    let mut out = Outbox::default();
    assert!(
        m.on_message(&header(peer), &msg, &mut out),
        "{msg:?} is ours"
    );
    out
}

fn count(n: u16, kind: MavMissionType) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: n,
        target_system: 1,
        target_component: 1,
        mission_type: kind,
        opaque_id: 0,
    })
}

/// The one message of `out`.
fn only(out: &Outbox) -> &MavMessage {
    assert_eq!(out.messages.len(), 1, "{:?}", out.messages);
    match &out.messages[0] {
        super::super::Outgoing::Message(m) => m,
        other => panic!("{other:?}"),
    }
}

fn requested(out: &Outbox) -> u16 {
    match only(out) {
        MavMessage::MISSION_REQUEST_INT(r) => {
            assert_eq!((r.target_system, r.target_component), GCS);
            r.seq
        }
        other => panic!("a MISSION_REQUEST_INT expected, not {other:?}"),
    }
}

fn acked(out: &Outbox) -> (MavMissionResult, u32) {
    let m = out.messages.iter().find_map(|m| match m {
        super::super::Outgoing::Message(MavMessage::MISSION_ACK(a)) => Some(a),
        _ => None,
    });
    let a = m.unwrap_or_else(|| panic!("a MISSION_ACK expected in {:?}", out.messages));
    (a.mavtype, a.opaque_id)
}

/// Uploads `items` by the book; returns the last answer.
fn upload(m: &mut Missions, kind: MavMissionType, items: &[MISSION_ITEM_INT_DATA]) -> Outbox {
    let mut out = send(m, GCS, count(items.len() as u16, kind));
    for it in items {
        assert_eq!(requested(&out), it.seq);
        out = send(
            m,
            GCS,
            MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                mission_type: kind,
                ..it.clone()
            }),
        );
    }
    out
}

#[test]
fn a_mission_uploads_item_by_item_and_downloads_identical() {
    let mut m = Missions::default();
    let items = square();
    let out = upload(&mut m, MavMissionType::MAV_MISSION_TYPE_MISSION, &items);
    let (result, id) = acked(&out);
    assert_eq!(result, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_ne!(id, 0, "an opaque id for the plan");
    let flown = crate::testing::mission(&out).unwrap();
    assert_eq!(flown.len(), 6, "every item, item 0 included (not home)");
    assert!(matches!(flown[0], MissionItem::Takeoff { .. }));
    assert_eq!(flown[2], MissionItem::ChangeSpeed(SpeedChange::To(3.0)));
    match flown[3] {
        MissionItem::Waypoint {
            hold_s,
            yaw_rad: Some(y),
            acceptance_m: None,
            at,
        } => {
            assert_eq!(hold_s, 2.0);
            assert!((y - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
            assert_eq!(at.alt, Some(MissionAltitude::AboveHome(10.0)));
        }
        ref other => panic!("{other:?}"),
    }
    match flown[4] {
        MissionItem::Waypoint { at, .. } => assert_eq!(at.alt, Some(MissionAltitude::Amsl(498.0))),
        ref other => panic!("{other:?}"),
    }
    // Download.
    let out = send(
        &mut m,
        GCS,
        MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        }),
    );
    match only(&out) {
        MavMessage::MISSION_COUNT(c) => assert_eq!((c.count, c.opaque_id), (6, id)),
        other => panic!("{other:?}"),
    }
    for it in &items {
        let out = send(
            &mut m,
            GCS,
            MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq: it.seq,
                target_system: 1,
                target_component: 1,
                mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            }),
        );
        match only(&out) {
            MavMessage::MISSION_ITEM_INT(got) => {
                let want = MISSION_ITEM_INT_DATA {
                    target_system: GCS.0,
                    target_component: GCS.1,
                    ..it.clone()
                };
                // Bit for bit (NaN yaws included).
                assert_eq!(format!("{got:?}"), format!("{want:?}"));
            }
            other => panic!("{other:?}"),
        }
    }
    // Past the end: refused.
    let out = send(
        &mut m,
        GCS,
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq: 6,
            target_system: 1,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        }),
    );
    assert_eq!(
        acked(&out).0,
        MavMissionResult::MAV_MISSION_INVALID_SEQUENCE
    );
    // The old request gets the old item, in degrees.
    let out = send(
        &mut m,
        GCS,
        MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
            seq: 1,
            target_system: 1,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        }),
    );
    match only(&out) {
        MavMessage::MISSION_ITEM(i) => assert!((i.x - 47.397742).abs() < 1e-5 && i.seq == 1),
        other => panic!("{other:?}"),
    }
}

#[test]
fn items_the_vehicle_cannot_fly_end_the_upload_and_keep_the_old_plan() {
    use MavCmd::*;
    use MavFrame::*;
    let mut m = Missions::default();
    upload(&mut m, MavMissionType::MAV_MISSION_TYPE_MISSION, &square());
    // Debug text: the NaN yaws compare equal there.
    let before = format!("{:?}", m.items(MavMissionType::MAV_MISSION_TYPE_MISSION));
    let ok = item(
        0,
        MAV_CMD_NAV_WAYPOINT,
        MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        [0.0; 4],
        (1, 1, 5.0),
    );
    let cases = [
        (
            item(
                1,
                MAV_CMD_NAV_LOITER_TURNS,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                [1.0, 0.0, 5.0, 0.0],
                (1, 1, 5.0),
            ),
            MavMissionResult::MAV_MISSION_UNSUPPORTED,
        ),
        (
            item(
                1,
                MAV_CMD_NAV_WAYPOINT,
                MAV_FRAME_LOCAL_NED,
                [0.0; 4],
                (1, 1, 5.0),
            ),
            MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
        ),
        (
            item(
                1,
                MAV_CMD_NAV_WAYPOINT,
                MAV_FRAME_MISSION,
                [0.0; 4],
                (1, 1, 5.0),
            ),
            MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
        ),
        (
            item(
                1,
                MAV_CMD_NAV_WAYPOINT,
                MAV_FRAME_GLOBAL_INT,
                [-1.0, 0.0, 0.0, 0.0],
                (1, 1, 5.0),
            ),
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        (
            item(
                1,
                MAV_CMD_NAV_WAYPOINT,
                MAV_FRAME_GLOBAL_INT,
                [0.0; 4],
                (950_000_000, 1, 5.0),
            ),
            MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
        ),
        (
            item(
                1,
                MAV_CMD_NAV_DELAY,
                MAV_FRAME_MISSION,
                [-1.0, 12.0, 0.0, 0.0],
                (0, 0, 0.0),
            ),
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        (
            item(
                1,
                MAV_CMD_DO_JUMP,
                MAV_FRAME_MISSION,
                [7.0, 2.0, 0.0, 0.0],
                (0, 0, 0.0),
            ),
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        (
            item(
                1,
                MAV_CMD_DO_CHANGE_SPEED,
                MAV_FRAME_MISSION,
                [1.0, f32::INFINITY, 0.0, 0.0],
                (0, 0, 0.0),
            ),
            MavMissionResult::MAV_MISSION_INVALID_PARAM2,
        ),
        (
            item(
                1,
                MAV_CMD_NAV_TAKEOFF,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                [0.0; 4],
                (0, 0, f32::NAN),
            ),
            MavMissionResult::MAV_MISSION_INVALID_PARAM7,
        ),
    ];
    for (bad, why) in cases {
        let out = upload(
            &mut m,
            MavMissionType::MAV_MISSION_TYPE_MISSION,
            &[ok.clone(), bad.clone()],
        );
        assert_eq!(acked(&out).0, why, "{:?} in {:?}", bad.command, bad.frame);
        assert!(crate::testing::mission(&out).is_none());
        assert!(out.messages.iter().any(|m| matches!(
            m,
            super::super::Outgoing::Message(MavMessage::STATUSTEXT(_))
        )));
        assert_eq!(
            format!("{:?}", m.items(MavMissionType::MAV_MISSION_TYPE_MISSION)),
            before,
            "old plan kept"
        );
        assert!(m.upload.is_none());
    }
    // A jump within the mission is fine, repeat −1 is forever.
    let jump = item(
        1,
        MAV_CMD_DO_JUMP,
        MAV_FRAME_MISSION,
        [0.0, -1.0, 0.0, 0.0],
        (0, 0, 0.0),
    );
    let out = upload(
        &mut m,
        MavMissionType::MAV_MISSION_TYPE_MISSION,
        &[ok, jump],
    );
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(
        crate::testing::mission(&out).unwrap()[1],
        MissionItem::Jump {
            to: 0,
            repeat: None
        }
    );
}

#[test]
fn repeats_gaps_timeouts_and_a_lost_ack_are_recovered_from() {
    let mut m = Missions::default();
    let items = square();
    m.poll(10.0, &mut Outbox::default());
    let out = send(
        &mut m,
        GCS,
        count(6, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    assert_eq!(requested(&out), 0);
    let out = send(&mut m, GCS, MavMessage::MISSION_ITEM_INT(items[0].clone()));
    assert_eq!(requested(&out), 1);
    // Item 0 again (our request crossed it): ask for 1 again.
    let out = send(&mut m, GCS, MavMessage::MISSION_ITEM_INT(items[0].clone()));
    assert_eq!(requested(&out), 1);
    // Nothing for a while: asked again after RETRY_S, not before.
    let mut out = Outbox::default();
    m.poll(10.0 + RETRY_S * 0.9, &mut out);
    assert!(out.messages.is_empty());
    m.poll(10.0 + RETRY_S * 1.1, &mut out);
    assert_eq!(requested(&out), 1);
    // The rest, then our ack is lost and the GCS sends the last item again: acked again.
    for it in &items[1..] {
        out = send(&mut m, GCS, MavMessage::MISSION_ITEM_INT(it.clone()));
    }
    let (result, id) = acked(&out);
    assert_eq!(result, MavMissionResult::MAV_MISSION_ACCEPTED);
    let again = send(&mut m, GCS, MavMessage::MISSION_ITEM_INT(items[5].clone()));
    assert_eq!(acked(&again), (MavMissionResult::MAV_MISSION_ACCEPTED, id));
    assert!(
        crate::testing::mission(&again).is_none(),
        "the mission is handed over once"
    );
    // A ground station that goes silent: RETRIES requests, then the upload is given up.
    let out = send(
        &mut m,
        GCS,
        count(6, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    assert_eq!(requested(&out), 0);
    let mut asked = 1;
    let mut t = 20.0;
    let mut last = Outbox::default();
    while m.upload.is_some() && t < 40.0 {
        t += 0.05;
        last = Outbox::default();
        m.poll(t, &mut last);
        if !last.messages.is_empty() && m.upload.is_some() {
            assert_eq!(requested(&last), 0);
            asked += 1;
        }
    }
    assert_eq!(asked, RETRIES);
    assert_eq!(
        acked(&last).0,
        MavMissionResult::MAV_MISSION_OPERATION_CANCELLED
    );
    assert_eq!(m.timeouts, 1);
    assert_eq!(
        m.items(MavMissionType::MAV_MISSION_TYPE_MISSION).len(),
        6,
        "plan kept"
    );
}

#[test]
fn one_uploader_at_a_time_and_an_item_ahead_of_its_turn_is_an_error() {
    let mut m = Missions::default();
    let out = send(
        &mut m,
        GCS,
        count(6, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    assert_eq!(requested(&out), 0);
    let other = (254, 1);
    let out = send(
        &mut m,
        other,
        count(2, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_DENIED);
    let out = send(
        &mut m,
        GCS,
        MavMessage::MISSION_ITEM_INT(square()[3].clone()),
    );
    assert_eq!(
        acked(&out).0,
        MavMissionResult::MAV_MISSION_INVALID_SEQUENCE
    );
    assert!(m.upload.is_none());
    let out = send(
        &mut m,
        GCS,
        count(5000, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_NO_SPACE);
    // The uploader cancels with an ack of its own.
    send(
        &mut m,
        GCS,
        count(6, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    send(
        &mut m,
        GCS,
        MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: 1,
            target_component: 1,
            mavtype: MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            opaque_id: 0,
        }),
    );
    assert!(m.upload.is_none());
}

#[test]
fn fence_and_rally_are_stored_apart_and_cleared_apart() {
    use MavCmd::*;
    use MavFrame::*;
    let mut m = Missions::default();
    upload(&mut m, MavMissionType::MAV_MISSION_TYPE_MISSION, &square());
    let vertex = |seq| MISSION_ITEM_INT_DATA {
        mission_type: MavMissionType::MAV_MISSION_TYPE_FENCE,
        ..item(
            seq,
            MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            MAV_FRAME_GLOBAL_INT,
            [3.0, 0.0, 0.0, 0.0],
            (473_970_000 + seq as i32 * 1000, 85_450_000, 0.0),
        )
    };
    let fence: Vec<_> = (0..3).map(vertex).collect();
    let out = upload(&mut m, MavMissionType::MAV_MISSION_TYPE_FENCE, &fence);
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert!(
        crate::testing::mission(&out).is_none(),
        "a fence is not a mission"
    );
    assert_eq!(
        crate::testing::fence(&out),
        Some(vec![GeoZone::Polygon {
            inclusion: true,
            vertices_deg: (0..3)
                .map(|k| ((473_970_000 + k * 1000) as f64 * 1e-7, 8.545))
                .collect(),
        }]),
        "the fence for the vehicle"
    );
    let rally = [MISSION_ITEM_INT_DATA {
        mission_type: MavMissionType::MAV_MISSION_TYPE_RALLY,
        ..item(
            0,
            MAV_CMD_NAV_RALLY_POINT,
            MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            [0.0; 4],
            (473_970_000, 85_450_000, 20.0),
        )
    }];
    assert_eq!(
        acked(&upload(
            &mut m,
            MavMissionType::MAV_MISSION_TYPE_RALLY,
            &rally
        ))
        .0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    // A waypoint is no fence item.
    let wrong = [MISSION_ITEM_INT_DATA {
        mission_type: MavMissionType::MAV_MISSION_TYPE_FENCE,
        ..square()[1].clone()
    }];
    let wrong = [MISSION_ITEM_INT_DATA {
        seq: 0,
        ..wrong[0].clone()
    }];
    assert_eq!(
        acked(&upload(
            &mut m,
            MavMissionType::MAV_MISSION_TYPE_FENCE,
            &wrong
        ))
        .0,
        MavMissionResult::MAV_MISSION_UNSUPPORTED
    );
    assert_eq!(m.items(MavMissionType::MAV_MISSION_TYPE_MISSION).len(), 6);
    assert_eq!(m.items(MavMissionType::MAV_MISSION_TYPE_FENCE).len(), 3);
    assert_eq!(m.items(MavMissionType::MAV_MISSION_TYPE_RALLY).len(), 1);
    let clear = |kind| {
        MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: 1,
            target_component: 1,
            mission_type: kind,
        })
    };
    let out = send(&mut m, GCS, clear(MavMissionType::MAV_MISSION_TYPE_MISSION));
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(
        crate::testing::mission(&out),
        Some(Vec::new()),
        "the commander's mission cleared too"
    );
    assert_eq!(
        m.items(MavMissionType::MAV_MISSION_TYPE_FENCE).len(),
        3,
        "fence kept"
    );
    assert_eq!(m.opaque_id(MavMissionType::MAV_MISSION_TYPE_MISSION), 0);
    send(&mut m, GCS, clear(MavMissionType::MAV_MISSION_TYPE_ALL));
    assert!(m.items(MavMissionType::MAV_MISSION_TYPE_FENCE).is_empty());
    assert!(m.items(MavMissionType::MAV_MISSION_TYPE_RALLY).is_empty());
}

#[test]
fn the_old_mission_item_uploads_as_the_int_one() {
    let mut m = Missions::default();
    let out = send(
        &mut m,
        GCS,
        count(1, MavMissionType::MAV_MISSION_TYPE_MISSION),
    );
    assert_eq!(requested(&out), 0);
    let old = MISSION_ITEM_DATA {
        param1: 0.0,
        param2: 0.0,
        param3: 0.0,
        param4: 0.0,
        x: 47.3978,
        y: 8.5456,
        z: 15.0,
        seq: 0,
        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
        target_system: 1,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        current: 0,
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
    };
    let out = send(&mut m, GCS, MavMessage::MISSION_ITEM(old));
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    let stored = &m.items(MavMissionType::MAV_MISSION_TYPE_MISSION)[0];
    // f32 degrees resolve 4e-6° here (0.4 m): why MISSION_ITEM_INT exists.
    assert!(
        (stored.x - 473_978_000).abs() <= 50 && (stored.y - 85_456_000).abs() <= 50,
        "{stored:?}"
    );
}

/// A fence plan decodes into zones: polygons of as many vertices as their param1 says,
/// circles of a positive radius, in a global frame; anything else refuses the upload and keeps
/// the previous fence. Clearing the fence clears the vehicle's.
#[test]
fn fence_plans_become_zones_or_are_refused() {
    use MavCmd::*;
    use MavFrame::*;
    let kind = MavMissionType::MAV_MISSION_TYPE_FENCE;
    let fence_item = |seq, command, p1: f32, frame, lat: i32| MISSION_ITEM_INT_DATA {
        mission_type: kind,
        ..item(
            seq,
            command,
            frame,
            [p1, 0.0, 0.0, 0.0],
            (lat, 85_450_000, 0.0),
        )
    };
    let mut good: Vec<_> = (0..4)
        .map(|k| {
            fence_item(
                k,
                MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                4.0,
                MAV_FRAME_GLOBAL_INT,
                473_970_000 + k as i32 * 100,
            )
        })
        .collect();
    good.push(fence_item(
        4,
        MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
        120.0,
        MAV_FRAME_GLOBAL_INT,
        473_970_000,
    ));
    good.push(fence_item(
        5,
        MAV_CMD_NAV_FENCE_RETURN_POINT,
        0.0,
        MAV_FRAME_GLOBAL_INT,
        473_970_000,
    ));
    let zones = decode_fence(&good).unwrap().zones;
    assert_eq!(zones.len(), 2);
    assert!(
        matches!(&zones[0], GeoZone::Polygon { inclusion: false, vertices_deg } if vertices_deg.len() == 4)
    );
    assert!(
        matches!(zones[1], GeoZone::Circle { inclusion: true, radius_m, .. } if radius_m == 120.0)
    );

    let mut m = Missions::default();
    let out = upload(&mut m, kind, &good);
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(crate::testing::fence(&out).as_ref().map(Vec::len), Some(2));
    let bad_cases = [
        // A polygon one vertex short of its count.
        (
            good[..3].to_vec(),
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        // Two vertices.
        (
            (0..2)
                .map(|k| {
                    fence_item(
                        k,
                        MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                        2.0,
                        MAV_FRAME_GLOBAL_INT,
                        473_970_000,
                    )
                })
                .collect(),
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        // A circle, then a polygon whose vertex count is 1e30: found by cargo fuzz (past the
        // first zone the count overflowed as an index, and the polygon's slice panicked).
        (
            std::iter::once(fence_item(
                0,
                MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                50.0,
                MAV_FRAME_GLOBAL_INT,
                473_970_000,
            ))
            .chain((1..4).map(|k| {
                fence_item(
                    k,
                    MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                    1e30,
                    MAV_FRAME_GLOBAL_INT,
                    473_970_000,
                )
            }))
            .collect(),
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        // Circles of negative and of no number radius.
        (
            vec![fence_item(
                0,
                MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
                -5.0,
                MAV_FRAME_GLOBAL_INT,
                473_970_000,
            )],
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        (
            vec![fence_item(
                0,
                MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                f32::NAN,
                MAV_FRAME_GLOBAL_INT,
                473_970_000,
            )],
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        ),
        // A circle in a local frame.
        (
            vec![fence_item(
                0,
                MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
                5.0,
                MAV_FRAME_LOCAL_NED,
                10,
            )],
            MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
        ),
    ];
    for (items, why) in bad_cases {
        let out = upload(&mut m, kind, &items);
        assert_eq!(acked(&out).0, why, "{items:?}");
        assert!(crate::testing::fence(&out).is_none());
        assert_eq!(m.items(kind).len(), 6, "the previous fence is kept");
    }
    let out = send(&mut m, GCS, count(0, kind));
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(crate::testing::fence(&out), Some(Vec::new()));
}

/// MAVSDK's geofence plugin uploads a polygon with, as its placeholder for "no circle", an
/// inclusion circle of radius 0 at (0, 0): taken as PX4 takes it, the circle ignored and said.
#[test]
fn fence_radius_zero_circle_is_no_circle() {
    use MavCmd::*;
    use MavFrame::*;
    let kind = MavMissionType::MAV_MISSION_TYPE_FENCE;
    let fence_item = |seq, command, p1: f32, lat_lon: (i32, i32)| MISSION_ITEM_INT_DATA {
        mission_type: kind,
        ..item(
            seq,
            command,
            MAV_FRAME_GLOBAL_INT,
            [p1, 0.0, 0.0, 0.0],
            (lat_lon.0, lat_lon.1, 0.0),
        )
    };
    let corners = [
        (473_970_000, 85_450_000),
        (473_980_000, 85_450_000),
        (473_980_000, 85_460_000),
    ];
    let mut items: Vec<_> = (0..3)
        .map(|k| {
            fence_item(
                k,
                MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                3.0,
                corners[k as usize],
            )
        })
        .collect();
    items.push(fence_item(
        3,
        MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
        0.0,
        (0, 0),
    ));
    let mut m = Missions::default();
    let out = upload(&mut m, kind, &items);
    assert_eq!(acked(&out).0, MavMissionResult::MAV_MISSION_ACCEPTED);
    let zones = crate::testing::fence(&out).expect("fence set");
    assert_eq!(zones.len(), 1);
    assert!(
        matches!(&zones[0], GeoZone::Polygon { inclusion: true, vertices_deg } if vertices_deg.len() == 3)
    );
    assert!(
        out.said.iter().any(|(_, t)| t.contains("radius 0 ignored")),
        "{:?}",
        out.said
    );
}

/// Places off the Earth, heights below the ground or above the ceiling and places far from
/// home end the upload with the field at fault, and the reason said; what needs home waits
/// for it.
#[test]
fn items_the_vehicle_must_not_fly_are_refused_with_the_field_at_fault() {
    use MavCmd::*;
    use MavFrame::*;
    use MavMissionResult::*;
    let limits = TargetLimits::new(&flight_core::safety::failsafe::SafetyParams::default());
    let origin = LatLonAlt {
        lat_deg: 47.397742,
        lon_deg: 8.545594,
        alt_m: 488.0,
    };
    let wp = |xyz, frame| item(1, MAV_CMD_NAV_WAYPOINT, frame, [0.0; 4], xyz);
    let cases = [
        (
            wp(
                (473_977_420, 85_455_940, 1e30),
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ),
            MAV_MISSION_INVALID_PARAM7,
            false,
        ),
        (
            wp(
                (473_977_420, 85_455_940, -50.0),
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ),
            MAV_MISSION_INVALID_PARAM7,
            false,
        ),
        (
            wp(
                (473_977_420, 85_455_940, f32::INFINITY),
                MAV_FRAME_GLOBAL_INT,
            ),
            MAV_MISSION_INVALID_PARAM7,
            false,
        ),
        (
            wp((473_977_420, 85_455_940, -1e6), MAV_FRAME_GLOBAL_INT),
            MAV_MISSION_INVALID_PARAM7,
            true,
        ),
        (
            wp((473_977_420, 85_455_940, 1e30), MAV_FRAME_GLOBAL_INT),
            MAV_MISSION_INVALID_PARAM7,
            true,
        ),
        (
            wp(
                (-800_000_000, 400_000_000, 10.0),
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ),
            MAV_MISSION_INVALID_PARAM5_X,
            true,
        ),
    ];
    for (bad, result, needs_home) in cases {
        for home in [false, true] {
            let mut m = Missions {
                bounds: Some(MissionBounds {
                    limits,
                    home: home.then_some((origin, Vector3::zeros())),
                }),
                ..Missions::default()
            };
            let ok = item(
                0,
                MAV_CMD_NAV_WAYPOINT,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                [0.0; 4],
                (473_977_420, 85_455_940, 10.0),
            );
            let out = upload(
                &mut m,
                MavMissionType::MAV_MISSION_TYPE_MISSION,
                &[ok, bad.clone()],
            );
            if needs_home && !home {
                assert_eq!(
                    acked(&out).0,
                    MAV_MISSION_ACCEPTED,
                    "{bad:?}: checked when home is known"
                );
                continue;
            }
            assert_eq!(acked(&out).0, result, "{bad:?}, home known: {home}");
            let said = crate::tests::statustexts(&out);
            assert!(said[0].starts_with("mission item 1 refused: "), "{said:?}");
            assert!(m.items(MavMissionType::MAV_MISSION_TYPE_MISSION).is_empty());
        }
    }
}
