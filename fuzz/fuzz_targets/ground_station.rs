//! The ground-station protocol fed structured messages (`arbitrary`-derived), so that real
//! command ids, real parameter names and whole mission and fence uploads are reached, not only
//! random bytes: each command the vehicle answers with any parameters, as `COMMAND_LONG` or
//! `COMMAND_INT`; `PARAM_SET` of every parameter with any value and type; uploads by the book of
//! any items; any other message of the dialect from raw bytes; polls. The commands the protocol
//! passes on are carried out by an autopilot; each message arrives on one of four links. No
//! panic; the parameters stay valid.
#![no_main]
// The deprecated commands are still answered, so still fuzzed.
#![allow(deprecated)]

use arbitrary::Arbitrary;
use autopilot_fuzz::Vehicle;
use flight_core::params::FlightParams;
use gcs::testing::{command_int, command_long};
use libfuzzer_sys::fuzz_target;
use mavlink::dialects::common::*;
use mavlink::{MavHeader, MavlinkVersion, Message};

/// Mission item commands and frames the vehicle knows, and a few it does not.
const ITEM_COMMANDS: [MavCmd; 12] = [
    MavCmd::MAV_CMD_NAV_WAYPOINT,
    MavCmd::MAV_CMD_NAV_TAKEOFF,
    MavCmd::MAV_CMD_NAV_LAND,
    MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MavCmd::MAV_CMD_NAV_LOITER_TIME,
    MavCmd::MAV_CMD_NAV_LOITER_UNLIM,
    MavCmd::MAV_CMD_NAV_DELAY,
    MavCmd::MAV_CMD_DO_CHANGE_SPEED,
    MavCmd::MAV_CMD_DO_JUMP,
    MavCmd::MAV_CMD_DO_SET_HOME,
    MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
];
const FRAMES: [MavFrame; 5] = [
    MavFrame::MAV_FRAME_GLOBAL,
    MavFrame::MAV_FRAME_GLOBAL_INT,
    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    MavFrame::MAV_FRAME_MISSION,
];
const PLANS: [MavMissionType; 3] = [
    MavMissionType::MAV_MISSION_TYPE_MISSION,
    MavMissionType::MAV_MISSION_TYPE_FENCE,
    MavMissionType::MAV_MISSION_TYPE_RALLY,
];

#[derive(Arbitrary, Debug)]
struct Item {
    command: u8,
    frame: u8,
    p: [f32; 4],
    x: i32,
    y: i32,
    z: f32,
}

#[derive(Arbitrary, Debug)]
enum Action {
    Command {
        which: u8,
        p: [f32; 7],
        as_int: bool,
        x: i32,
        y: i32,
        frame: u8,
    },
    ParamSet {
        which: u16,
        value: f32,
        int: bool,
    },
    Upload {
        plan: u8,
        items: Vec<Item>,
    },
    Raw {
        id: u16,
        payload: Vec<u8>,
    },
    /// Bytes typed into the MAVLink shell.
    Shell {
        flags: u8,
        bytes: Vec<u8>,
    },
    Poll {
        dt_ms: u16,
    },
}

#[derive(Arbitrary, Debug)]
struct Input {
    armed: bool,
    /// The link each action arrives on (of four).
    links: Vec<u8>,
    actions: Vec<Action>,
}

fn pick<T: Copy>(table: &[T], k: impl Into<usize>) -> T {
    table[k.into() % table.len()]
}

fn message(a: &Action) -> Vec<MavMessage> {
    match a {
        Action::Command {
            which,
            p,
            as_int,
            x,
            y,
            frame,
        } => {
            let answered: Vec<_> = gcs::answered_commands().collect();
            let command = pick(&answered, *which);
            vec![if *as_int {
                let p = [p[0], p[1], p[2], p[3], 0.0, 0.0, p[6]];
                command_int(command, p, *x, *y, pick(&FRAMES, *frame))
            } else {
                command_long(command, *p, (1, 1))
            }]
        }
        Action::ParamSet { which, value, int } => {
            let names: Vec<&str> = FlightParams::metadata().map(|(_, m)| m.name).collect();
            let name = pick(&names, *which);
            let mut id = [0u8; 16];
            id[..name.len()].copy_from_slice(name.as_bytes());
            vec![MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: *value,
                target_system: 1,
                target_component: 1,
                param_id: id.into(),
                param_type: if *int {
                    MavParamType::MAV_PARAM_TYPE_INT32
                } else {
                    MavParamType::MAV_PARAM_TYPE_REAL32
                },
            })]
        }
        Action::Upload { plan, items } => {
            let mission_type = pick(&PLANS, *plan);
            let mut m = vec![MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: items.len() as u16,
                target_system: 1,
                target_component: 1,
                mission_type,
                opaque_id: 0,
            })];
            m.extend(items.iter().enumerate().map(|(seq, it)| {
                MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                    param1: it.p[0],
                    param2: it.p[1],
                    param3: it.p[2],
                    param4: it.p[3],
                    x: it.x,
                    y: it.y,
                    z: it.z,
                    seq: seq as u16,
                    command: pick(&ITEM_COMMANDS, it.command),
                    target_system: 1,
                    target_component: 1,
                    frame: pick(&FRAMES, it.frame),
                    current: 0,
                    autocontinue: 1,
                    mission_type,
                })
            }));
            m
        }
        Action::Raw { id, payload } => MavMessage::parse(MavlinkVersion::V2, (*id).into(), payload)
            .into_iter()
            .collect(),
        Action::Shell { flags, bytes } => {
            let mut data = [0u8; 70];
            let n = bytes.len().min(70);
            data[..n].copy_from_slice(&bytes[..n]);
            vec![MavMessage::SERIAL_CONTROL(SERIAL_CONTROL_DATA {
                baudrate: 0,
                timeout: 0,
                device: SerialControlDev::SERIAL_CONTROL_DEV_SHELL,
                flags: SerialControlFlag::from_bits_truncate(*flags),
                count: bytes.len().min(255) as u8,
                data,
                target_system: 0,
                target_component: 0,
            })]
        }
        Action::Poll { .. } => Vec::new(),
    }
}

fuzz_target!(|input: Input| {
    let mut v = Vehicle::new(input.armed);
    let header = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    };
    let mut out = gcs::Outbox::default();
    let mut now_s = 1.0;
    for (k, a) in input.actions.iter().take(64).enumerate() {
        let link = input.links.get(k).map_or(0, |l| l % 4);
        for m in message(a) {
            match &m {
                // The shell, as the links' task routes it.
                MavMessage::SERIAL_CONTROL(d) => {
                    let allowed = link != 3;
                    v.gcs
                        .on_serial_control(link, &header, d, allowed, &v.telemetry, &mut out)
                }
                _ => v
                    .gcs
                    .on_link_message(link, &header, &m, &v.telemetry, &mut out),
            }
            v.carry_out(&mut out);
        }
        if let Action::Poll { dt_ms } = a {
            now_s += f64::from(*dt_ms) * 1e-3;
        }
        v.gcs.poll(now_s, &v.telemetry, &mut out);
        v.carry_out(&mut out);
    }
    v.assert_params_valid();
});
