//! Endpoint URLs: the instance's port offset, the options every endpoint takes, and the ones
//! refused.
#![allow(clippy::unwrap_used)]

use super::endpoint::{Endpoint, EndpointSpec};

#[test]
fn endpoints_parse_with_the_instance_offset() {
    let e = Endpoint::parse("udpout://127.0.0.1:14550?bind=18570", 2).unwrap();
    assert_eq!(
        e,
        Endpoint::UdpOut {
            target: "127.0.0.1:14552".parse().unwrap(),
            bind: "127.0.0.1:18572".parse().unwrap(),
        }
    );
    // QGroundControl's port, shared by every vehicle (PX4's multi-vehicle ports).
    let e = Endpoint::parse("udpout://127.0.0.1:14550?bind=18570&shared", 2).unwrap();
    assert_eq!(
        e,
        Endpoint::UdpOut {
            target: "127.0.0.1:14550".parse().unwrap(),
            bind: "127.0.0.1:18572".parse().unwrap(),
        }
    );
    // Pushing to another host: reachable from it; an address named is taken as it is.
    let e = Endpoint::parse("udpout://192.168.1.20:14550?bind=18570", 0).unwrap();
    assert_eq!(
        e,
        Endpoint::UdpOut {
            target: "192.168.1.20:14550".parse().unwrap(),
            bind: "0.0.0.0:18570".parse().unwrap(),
        }
    );
    let e = Endpoint::parse("udpout://192.168.1.20:14550?bind=192.168.1.5:18570", 1).unwrap();
    assert_eq!(
        e,
        Endpoint::UdpOut {
            target: "192.168.1.20:14551".parse().unwrap(),
            bind: "192.168.1.5:18571".parse().unwrap(),
        }
    );
    assert_eq!(
        Endpoint::parse("udpout://127.0.0.1:14550", 0).unwrap(),
        Endpoint::UdpOut {
            target: "127.0.0.1:14550".parse().unwrap(),
            bind: "127.0.0.1:0".parse().unwrap(),
        }
    );
    let e = Endpoint::parse("tcpin://0.0.0.0:5760", 1).unwrap();
    assert_eq!(
        e,
        Endpoint::TcpIn {
            bind: "0.0.0.0:5761".parse().unwrap()
        }
    );
    assert_eq!(
        Endpoint::parse("serial:///dev/ttyUSB0?baud=921600", 3).unwrap(),
        Endpoint::Serial {
            path: "/dev/ttyUSB0".into(),
            baud: 921_600
        }
    );
    assert_eq!(
        Endpoint::parse("serial:///dev/ttyACM0", 0).unwrap(),
        Endpoint::Serial {
            path: "/dev/ttyACM0".into(),
            baud: 57_600
        },
        "a telemetry radio's rate by default"
    );
    for bad in [
        "udp://1.2.3.4:5",
        "udpout://localhost",
        "udpin://0.0.0.0:1?bind=3",
        "udpin://0.0.0.0:1?shared",
        "tcpin://0.0.0.0:1?shared",
        "udpout://1.2.3.4:5?speed=9",
        "serial://?baud=57600",
        "serial:///dev/ttyS0?baud=fast",
        "serial:///dev/ttyS0?baud=0",
        "serial:///dev/ttyS0?bind=3",
    ] {
        assert!(Endpoint::parse(bad, 0).is_err(), "{bad}");
    }
}

#[test]
fn endpoint_options_trusted_and_allow_lists_parse_on_every_kind() {
    let e = EndpointSpec::parse("udpin://127.0.0.1:14560?trusted&sysids=255,250", 1).unwrap();
    assert_eq!(
        e.endpoint,
        Endpoint::UdpIn {
            bind: "127.0.0.1:14561".parse().unwrap()
        }
    );
    assert!(e.options.trusted);
    assert_eq!(e.options.allowed_systems, [255, 250]);
    let e = EndpointSpec::parse("udpout://127.0.0.1:14550?sysids=255&bind=18570", 0).unwrap();
    assert_eq!(
        e.endpoint,
        Endpoint::UdpOut {
            target: "127.0.0.1:14550".parse().unwrap(),
            bind: "127.0.0.1:18570".parse().unwrap(),
        },
        "the endpoint's own options are kept"
    );
    assert!(!e.options.trusted);
    let e = EndpointSpec::parse("serial:///dev/ttyACM0?baud=115200&trusted", 0).unwrap();
    assert!(e.options.trusted && e.options.allowed_systems.is_empty());
    assert_eq!(e.options.streams, gcs::StreamSet::Normal);
    // PX4's stream sets; a port 0 is any port, never offset by the instance.
    let e = EndpointSpec::parse("udpin://127.0.0.1:0?mode=onboard", 3).unwrap();
    assert_eq!(e.options.streams, gcs::StreamSet::Onboard);
    assert_eq!(
        e.endpoint,
        Endpoint::UdpIn {
            bind: "127.0.0.1:0".parse().unwrap()
        }
    );
    for bad in [
        "udpin://0.0.0.0:1?mode=fast",
        "udpin://0.0.0.0:1?sysids=0",
        "udpin://0.0.0.0:1?sysids=256",
        "udpin://0.0.0.0:1?sysids=255,x",
        "udpin://0.0.0.0:1?trusted=yes",
        "tcpin://0.0.0.0:1?sysids=",
    ] {
        assert!(EndpointSpec::parse(bad, 0).is_err(), "{bad}");
    }
}
