//! Parses a state as `sitl --json` writes it, N times: `tools/bench_cost.py` counts its
//! instructions per parse under callgrind.
use hil::json::PhysicsState;
use nalgebra::{UnitQuaternion, Vector3};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1000);
    let state = PhysicsState {
        timestamp_s: 12.004,
        gyro_frd_rad_s: Vector3::new(0.0123456789, -0.0234567891, 0.3456789123),
        accel_frd_m_s2: Vector3::new(0.1234567891, 0.2345678912, -9.8123456789),
        pos_ned_m: Vector3::new(3.123456789, -4.23456789, -5.53456789),
        vel_ned_m_s: Vector3::new(0.5123456789, 0.0123456789, -1.0123456789),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(0.1, -0.2, 2.0),
        battery: Some((15.9123456789, 12.5123456789)),
        airspeed_m_s: Some(7.25123456789),
    };
    let text = state.to_json();
    let mut sum = 0.0;
    for _ in 0..n {
        sum += PhysicsState::parse_latest(text.as_bytes()).map_or(0.0, |s| s.timestamp_s);
    }
    println!("{} bytes, sum {sum}", text.len());
}
