//! The ground contact in the whole simulator: standing, touching down, rocking, wind, long steps.
use crate::GRAVITY_M_S2;
use crate::airframe::Airframe;
use crate::body::BodyState;
use crate::environment::WindConfig;
use crate::sensors::{SensorConfig, SensorPreset};
use crate::sim::{SimConfig, Simulator};
use nalgebra::{UnitQuaternion, Vector3};

fn shipped(name: &str) -> Airframe {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    Airframe::load(&dir.join(format!("{name}.toml"))).unwrap()
}

fn world(wind_north_m_s: f64, dt_s: f64) -> SimConfig {
    let wind = WindConfig {
        mean_ned_m_s: [wind_north_m_s, 0.0, 0.0],
        ..WindConfig::default()
    };
    SimConfig {
        dt_s,
        sensors: SensorConfig::preset(SensorPreset::Ideal),
        wind,
        ..SimConfig::default()
    }
}

fn tilt_deg(q: &UnitQuaternion<f64>) -> f64 {
    q.transform_vector(&Vector3::z())
        .angle(&Vector3::z())
        .to_degrees()
}

/// Motors off for `steps`; the largest attitude change in one step (°), and the attitude the
/// truth's body rates integrate to from `q0` (what a perfect gyro would).
fn coast(sim: &mut Simulator, steps: usize) -> (f64, UnitQuaternion<f64>) {
    let dt = sim.config().dt_s;
    let mut integrated = sim.truth().body.q_ned_from_frd;
    let mut largest: f64 = 0.0;
    for _ in 0..steps {
        let before = sim.truth().body.q_ned_from_frd;
        sim.step(&[0.0; 16]);
        let b = sim.truth().body;
        largest = largest.max(before.angle_to(&b.q_ned_from_frd).to_degrees());
        integrated *= UnitQuaternion::from_scaled_axis(b.rate_frd_rad_s * dt);
    }
    (largest, integrated)
}

#[test]
fn every_airframe_stands_settled_on_its_feet() {
    for name in ["quad_x", "quad_plus", "hexa_x", "octa_x", "dodeca"] {
        let a = shipped(name);
        let mut sim = Simulator::new(&a, world(0.0, 0.001), BodyState::default()).unwrap();
        let start = sim.truth().body;
        assert!(sim.truth().landed, "{name}");
        assert!(start.pos_ned_m.z.abs() < 0.005, "{name}: {start:?}");
        assert!(tilt_deg(&start.q_ned_from_frd) < 0.05, "{name}: {start:?}");
        coast(&mut sim, 10_000);
        let t = sim.truth();
        assert!(t.landed && sim.stats().touchdowns == 0, "{name}");
        assert!((t.body.pos_ned_m - start.pos_ned_m).norm() < 1e-6, "{name}");
        let f = sim.sample_sensors().accel_frd_m_s2;
        assert!(
            (f - Vector3::new(0.0, 0.0, -GRAVITY_M_S2)).norm() < 1e-6,
            "{name}: at rest the accelerometer feels gravity alone: {f:?}"
        );
    }
}

/// The old ground levelled a tilted vehicle in one step with no rate; the legs turn it over
/// tens of steps at rates the gyro measures. A 3 m/s touchdown 20° tilted (a hard one) turns it
/// at most 0.3° in a 1 ms step (300°/s), and the rates add up to the attitude.
#[test]
fn a_tilted_touchdown_turns_the_body_as_its_gyro_measures_and_counts_once() {
    let a = shipped("quad_x");
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -0.3),
        vel_ned_m_s: Vector3::new(0.0, 0.0, 2.0),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(20f64.to_radians(), 0.0, 0.3),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&a, world(0.0, 0.001), initial).unwrap();
    let (largest_step_deg, integrated) = coast(&mut sim, 3000);
    let t = sim.truth();
    println!(
        "tilted touchdown at {:.2} m/s: largest step {largest_step_deg:.3}°, rest tilt {:.3}°",
        sim.stats().last_touchdown_speed_m_s,
        tilt_deg(&t.body.q_ned_from_frd)
    );
    assert_eq!(
        sim.stats().touchdowns,
        1,
        "a bounce is not a second touchdown"
    );
    assert!(sim.stats().last_touchdown_speed_m_s > 2.0);
    assert!(largest_step_deg < 0.4, "{largest_step_deg}°");
    let gyro_error_deg = integrated.angle_to(&t.body.q_ned_from_frd).to_degrees();
    assert!(
        gyro_error_deg < 0.01,
        "the rates add up to the attitude: {gyro_error_deg}°"
    );
    assert!(t.landed && tilt_deg(&t.body.q_ned_from_frd) < 0.5, "{t:?}");
    assert!(t.body.rate_frd_rad_s.norm() < 1e-3, "at rest: {t:?}");
    let (_, _, yaw) = t.body.q_ned_from_frd.euler_angles();
    assert!((yaw - 0.3).abs() < 0.01, "heading kept: {yaw}");
}

#[test]
fn a_vehicle_set_down_tilted_rocks_onto_its_feet() {
    let a = shipped("hexa_x");
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -0.1),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(0.0, -25f64.to_radians(), 0.0),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&a, world(0.0, 0.001), initial).unwrap();
    let mut fastest: f64 = 0.0;
    for _ in 0..3000 {
        sim.step(&[0.0; 6]);
        fastest = fastest.max(sim.truth().body.rate_frd_rad_s.norm().to_degrees());
    }
    let t = sim.truth();
    assert!(fastest > 20.0, "it rocks, turning over time: {fastest}°/s");
    assert!(t.landed && tilt_deg(&t.body.q_ned_from_frd) < 0.5, "{t:?}");
}

/// Legs 0.19 m apart under a centre of mass 0.1 m up: a 10 m/s wind (5.5 N of drag) leans the
/// quad on its downwind legs and friction holds it; 25 m/s (25 N, over the 11 N its stance
/// bears) tips it over onto its arms.
#[test]
fn wind_on_the_ground_leans_a_vehicle_or_tips_it_over() {
    let a = shipped("quad_x");
    for (wind, tips) in [(10.0, false), (25.0, true)] {
        let mut sim = Simulator::new(&a, world(wind, 0.001), BodyState::default()).unwrap();
        let start = sim.truth().body.pos_ned_m;
        coast(&mut sim, 20_000);
        let b = sim.truth().body;
        let tilt = tilt_deg(&b.q_ned_from_frd);
        println!(
            "{wind} m/s on the ground: tilt {tilt:.2}°, moved {:.4} m",
            (b.pos_ned_m - start).norm()
        );
        assert_eq!(tilt > 90.0, tips, "{wind} m/s: tilt {tilt}°");
        if !tips {
            assert!(tilt < 3.0 && (b.pos_ned_m - start).norm() < 0.02, "{b:?}");
        }
        assert!(
            sim.truth().landed && b.pos_ned_m.z.abs() < 0.2,
            "on the ground: {b:?}"
        );
    }
}

/// A 20 ms step would make a 5 mm sag's spring ring beyond what an explicit integrator carries:
/// the spring is softened to keep 4π steps a bounce, and the vehicle stands and lands.
#[test]
fn long_steps_soften_the_legs_and_stay_stable() {
    let a = shipped("quad_x");
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -1.0),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&a, world(0.0, 0.02), initial).unwrap();
    coast(&mut sim, 500);
    let t = sim.truth();
    assert!(t.landed && t.body.pos_ned_m.z.abs() < 0.1, "{t:?}");
    assert!(t.body.vel_ned_m_s.norm() < 1e-3 && tilt_deg(&t.body.q_ned_from_frd) < 0.1);
    assert_eq!(sim.stats().touchdowns, 1);
}
