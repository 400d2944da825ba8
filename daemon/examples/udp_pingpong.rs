//! The ceiling of a lockstep exchange over loopback UDP: two processes bouncing datagrams of
//! the sizes a HIL exchange carries (a sensor frame out, an actuator answer back), one at a
//! time. `tools/bench.sh` runs it next to a `sitl` ↔ `autopilot` flight and compares.
//!
//! ```text
//! udp_pingpong echo 127.0.0.1:14999          # one process: answers every datagram
//! udp_pingpong ping 127.0.0.1:14999 5        # the other: round trips for 5 s, prints the rate
//! ```
//!
//! A last argument `WORK_US` makes each side spin that long between receiving and sending, as
//! the simulator (physics) and the autopilot (a flight-core step) compute between theirs: the
//! ceiling of an exchange that carries that much work.

use std::net::UdpSocket;
use std::time::{Duration, Instant};

/// A sensor frame (HIL_SENSOR with GPS and ESC status) and its answer, in bytes.
const FRAME_BYTES: usize = 220;
const ANSWER_BYTES: usize = 96;

fn main() -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let usage = || {
        eprintln!(
            "usage: udp_pingpong echo ADDR [WORK_US] | udp_pingpong ping ADDR SECONDS [WORK_US]"
        );
        std::process::exit(2)
    };
    let (Some(mode), Some(addr)) = (args.get(1), args.get(2)) else {
        usage()
    };
    let mut buf = [0u8; 2048];
    let work_arg = if mode == "echo" { 3 } else { 4 };
    let work = Duration::from_secs_f64(
        args.get(work_arg)
            .and_then(|s| s.parse::<f64>().ok())
            .unwrap_or(0.0)
            * 1e-6,
    );
    let spin = |d: Duration| {
        let t = Instant::now();
        while t.elapsed() < d {
            std::hint::spin_loop();
        }
    };
    match mode.as_str() {
        "echo" => {
            let socket = UdpSocket::bind(addr)?;
            // Stop by itself when the other side has gone quiet.
            socket.set_read_timeout(Some(Duration::from_secs(3)))?;
            let answer = [0u8; ANSWER_BYTES];
            while let Ok((_, from)) = socket.recv_from(&mut buf) {
                spin(work);
                socket.send_to(&answer, from)?;
            }
            Ok(())
        }
        "ping" => {
            let seconds: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5.0);
            let socket = UdpSocket::bind("127.0.0.1:0")?;
            socket.connect(addr)?;
            socket.set_read_timeout(Some(Duration::from_secs(1)))?;
            let frame = [0u8; FRAME_BYTES];
            // Until the echo process is up: its port may refuse a first datagram or two.
            let waiting = Instant::now();
            while socket
                .send(&frame)
                .and_then(|_| socket.recv(&mut buf))
                .is_err()
            {
                if waiting.elapsed() > Duration::from_secs(5) {
                    eprintln!("udp_pingpong: no echo from {addr}");
                    std::process::exit(1);
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let started = Instant::now();
            let mut trips = 0u64;
            while started.elapsed().as_secs_f64() < seconds {
                socket.send(&frame)?;
                socket.recv(&mut buf)?;
                spin(work);
                trips += 1;
            }
            let rate = trips as f64 / started.elapsed().as_secs_f64();
            println!("udp_pingpong round_trips_per_s={rate:.0} trips={trips}");
            Ok(())
        }
        _ => usage(),
    }
}
