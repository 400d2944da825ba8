//! Parses a state as `sitl --json` writes it, N times: `tools/bench_cost.py` counts its
//! instructions per parse under callgrind.
use hil::json::PhysicsState;
use nalgebra::{UnitQuaternion, Vector3};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1000);
    // Values as a flight computes them: most need all 17 digits to read back exactly.
    let third = |x: f64| x / 3.0;
    let v = |x: f64, y: f64, z: f64| Vector3::new(third(x), third(y), third(z));
    let state = PhysicsState {
        timestamp_s: 0.001 * 12004.0,
        gyro_frd_rad_s: v(0.0123, -0.0234, 0.3456),
        accel_frd_m_s2: v(0.1234, 0.2345, -29.4),
        pos_ned_m: v(3.123, -4.234, -5.534),
        vel_ned_m_s: v(0.5123, 0.0123, -1.0123),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(0.1, -0.2, 2.0),
        battery: Some((third(47.7), third(37.5))),
        airspeed_m_s: Some(third(21.7)),
    };
    let text = state.to_json();
    let mut sum = 0.0;
    for _ in 0..n {
        sum += PhysicsState::parse_latest(text.as_bytes()).map_or(0.0, |s| s.timestamp_s);
    }
    println!("{} bytes, sum {sum}", text.len());
}
