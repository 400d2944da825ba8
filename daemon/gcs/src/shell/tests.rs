//! The shell typed into as clients type: lines in pieces, `\r\n`, backspace, any bytes.

use super::*;
use crate::Reply;
use crate::testing::telemetry;
use flight_core::commander::FlightMode;

const SHELL: SerialControlDev = SerialControlDev::SERIAL_CONTROL_DEV_SHELL;

fn typed(bytes: &[u8], flags: SerialControlFlag) -> SERIAL_CONTROL_DATA {
    let mut data = [0u8; 70];
    let n = bytes.len().min(70);
    data[..n].copy_from_slice(&bytes[..n]);
    SERIAL_CONTROL_DATA {
        baudrate: 0,
        timeout: 0,
        device: SHELL,
        flags,
        count: n as u8,
        data,
        target_system: 0,
        target_component: 0,
    }
}

fn header() -> MavHeader {
    MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    }
}

/// Types `text` in pieces of `piece` bytes; the text printed back.
fn session(g: &mut GroundStation, text: &[u8], piece: usize) -> String {
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    let respond = SerialControlFlag::SERIAL_CONTROL_FLAG_RESPOND
        | SerialControlFlag::SERIAL_CONTROL_FLAG_EXCLUSIVE;
    for chunk in text.chunks(piece.max(1)) {
        g.on_serial_control(0, &header(), &typed(chunk, respond), true, &t, &mut out);
    }
    for k in 0..50 {
        g.shell_poll(k as f64 * 0.05, &t, &mut out);
    }
    let mut printed = Vec::new();
    for (link, m) in &out.streamed {
        if let Outgoing::Message(MavMessage::SERIAL_CONTROL(r)) = m {
            assert_eq!(*link, 0);
            assert!(
                r.flags
                    .contains(SerialControlFlag::SERIAL_CONTROL_FLAG_REPLY)
            );
            assert!(r.count <= 70 && r.target_system == 255 && r.target_component == 190);
            printed.extend_from_slice(&r.data[..usize::from(r.count)]);
        }
    }
    String::from_utf8(printed).unwrap()
}

#[test]
fn lines_typed_in_any_pieces_run_and_print_with_a_prompt() {
    for piece in [1, 3, 70] {
        let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
        let text = session(&mut g, b"ver\r\nparam show MPC_XY_C*\nhelpx\x08\n", piece);
        assert!(text.starts_with("nsh> ver\n"), "{text:?}");
        assert!(text.contains("autopilot "), "{text:?}");
        assert!(
            text.contains("MPC_XY_CRUISE      5\n1 parameters\n"),
            "{text:?}"
        );
        assert!(text.contains("helpx\x08 \x08\ncommands:"), "{text:?}");
        assert!(text.ends_with("nsh> "), "{text:?}");
        assert_eq!(text.matches("nsh> ").count(), 4, "{text:?}");
    }
}

#[test]
fn commands_for_the_vehicle_go_to_it_and_bad_input_is_answered() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    let respond = SerialControlFlag::SERIAL_CONTROL_FLAG_RESPOND;
    for line in [
        &b"commander arm\n"[..],
        b"failure gps off -i 1\n",
        b"commander mode orbit\n",
    ] {
        g.on_serial_control(0, &header(), &typed(line, respond), true, &t, &mut out);
    }
    assert_eq!(crate::testing::requested(&out).len(), 3);
    assert!(
        crate::testing::requested(&out)
            .iter()
            .all(|(_, to)| to.reply == Reply::Shell)
    );
    let no = flight_core::commander::ArmingDenial::NoSensorData;
    g.answered(
        crate::testing::requested(&out)[0].1,
        Err(no.into()),
        &mut out,
    );
    let text = session(&mut g, b"", 1);
    assert!(
        text.contains("refused: arming refused: no sensor data yet\nnsh> "),
        "{text:?}"
    );
    // Every byte, and lines far too long: answered, never a panic.
    let all: Vec<u8> = (0..=255u8).chain(std::iter::repeat_n(b'a', 500)).collect();
    let text = session(
        &mut g,
        &[&all[..], b"\ncommander fly\nparam set NOPE 1\n"].concat(),
        70,
    );
    assert!(text.contains("command not found"), "{text:?}");
    assert!(
        text.contains("commander: usage") || text.contains("usage: commander"),
        "{text:?}"
    );
    assert!(text.contains("param set: "), "{text:?}");
}

#[test]
fn a_refused_endpoint_gets_the_reason_and_an_empty_message_closes() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    let respond = SerialControlFlag::SERIAL_CONTROL_FLAG_RESPOND;
    g.on_serial_control(0, &header(), &typed(b"ver\n", respond), false, &t, &mut out);
    assert!(crate::testing::requested(&out).is_empty() && g.shell.peer.is_none());
    assert_eq!(out.streamed.len(), 1, "the reason only");
    g.on_serial_control(0, &header(), &typed(b"", respond), true, &t, &mut out);
    assert!(g.shell.peer.is_some());
    g.on_serial_control(
        0,
        &header(),
        &typed(b"", SerialControlFlag::empty()),
        true,
        &t,
        &mut out,
    );
    assert!(g.shell.peer.is_none(), "closed");
}

#[test]
fn a_command_for_the_vehicle_holds_the_prompt_until_its_answer_and_floods_are_bounded() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    let respond = SerialControlFlag::SERIAL_CONTROL_FLAG_RESPOND;
    g.on_serial_control(
        0,
        &header(),
        &typed(b"commander arm\n", respond),
        true,
        &t,
        &mut out,
    );
    let to = crate::testing::requested(&out)[0].1;
    assert_eq!((to.system, to.component), (255, 190));
    g.answered(to, Ok(()), &mut out);
    let text = session(&mut g, b"", 1);
    assert_eq!(text, "nsh> commander arm\naccepted\nnsh> ");
    // A client that types and never reads: what waits stays bounded, the loss said.
    let flood =
        b"help\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\nhelp\n";
    for _ in 0..100 {
        g.on_serial_control(0, &header(), &typed(flood, respond), true, &t, &mut out);
    }
    assert!(
        g.shell.output.len() <= OUTPUT_MAX + 20,
        "{}",
        g.shell.output.len()
    );
    let waiting: Vec<u8> = g.shell.output.iter().copied().collect();
    assert!(String::from_utf8_lossy(&waiting).contains("[output dropped]"));
}
