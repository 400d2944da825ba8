use super::*;

fn answers(rx: &mut UbloxReceiver, class: u8, id: u8, payload: &[u8]) -> Vec<UbxFrame> {
    let mut sent = Vec::new();
    ubx_frame::write(class, id, payload, &mut sent);
    let mut out = Vec::new();
    rx.receive(&sent, &mut out);
    let mut frames = Vec::new();
    UbxReader::default().push(&out, &mut frames);
    frames
}

fn ack(ok: bool, class: u8, id: u8) -> UbxFrame {
    UbxFrame {
        class: 0x05,
        id: u8::from(ok),
        payload: vec![class, id],
    }
}

#[test]
fn a_valset_with_a_key_it_does_not_know_is_refused_whole() {
    let mut rx = UbloxReceiver::new(ReceiverModel::M9);
    let mut p = vec![0, 1, 0, 0];
    p.extend(KEY_UART1_BAUD.to_le_bytes());
    p.extend(115_200u32.to_le_bytes());
    p.extend(0x2099_9999u32.to_le_bytes());
    p.push(1);
    assert_eq!(answers(&mut rx, 0x06, 0x8A, &p), [ack(false, 0x06, 0x8A)]);
    assert_eq!(rx.baud(), 38_400, "nothing of it applied");
    p.truncate(12);
    assert_eq!(answers(&mut rx, 0x06, 0x8A, &p), [ack(true, 0x06, 0x8A)]);
    assert_eq!(rx.baud(), 115_200);
}

#[test]
fn each_generation_takes_its_own_interfaces() {
    let mut prt = vec![1, 0, 0, 0, 0xC0, 0x08, 0, 0];
    prt.extend(57_600u32.to_le_bytes());
    prt.extend([0x03, 0, 0x01, 0, 0, 0, 0, 0]);
    let mut m10 = UbloxReceiver::new(ReceiverModel::M10);
    assert_eq!(
        answers(&mut m10, 0x06, 0x00, &prt),
        [ack(false, 0x06, 0x00)]
    );
    let mut m8 = UbloxReceiver::new(ReceiverModel::M8);
    assert_eq!(answers(&mut m8, 0x06, 0x00, &prt), [ack(true, 0x06, 0x00)]);
    assert_eq!(m8.baud(), 57_600);
    assert_eq!(
        answers(&mut m8, 0x06, 0x8A, &[0, 1, 0, 0]),
        [ack(false, 0x06, 0x8A)]
    );
    let version = answers(&mut m8, 0x0A, 0x04, &[]);
    assert_eq!(version.len(), 1);
    assert_eq!(version[0].payload.len(), 40 + 3 * 30);
}

#[test]
fn the_time_of_week_counts_from_sunday_in_gps_time() {
    // 2026-11-29 was a Sunday: 00:00:00 UTC is 18 s into the GPS week.
    assert_eq!(gps_time_of_week_ms(1_795_910_400_000_000), 18_000);
}
