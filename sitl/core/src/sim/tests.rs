use super::*;

const SHIPPED: [&str; 5] = ["quad_x", "quad_plus", "hexa_x", "octa_x", "dodeca"];

fn shipped(name: &str) -> Airframe {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    Airframe::load(&dir.join(format!("{name}.toml"))).unwrap()
}

use crate::powertrain::steady_wrench;
use crate::sensors::{SensorHealth, SensorKind};
use crate::sensors::{SensorPreset, fields};
use nalgebra::DVector;

fn config(preset: SensorPreset) -> SimConfig {
    SimConfig {
        sensors: SensorConfig::preset(preset),
        ..SimConfig::default()
    }
}

fn airborne(name: &str, preset: SensorPreset) -> Simulator {
    let a = shipped(name);
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -10.0),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&a, config(preset), initial).unwrap();
    let hover = sim.hover_speeds();
    sim.set_rotor_speeds(&hover);
    sim
}

/// At the analytic hover speeds (Lewis (4.30) of B⁺[−W,0,0,0]), held through the inverse motor
/// curve as the battery sags, every airframe stays put: < 1 mm over 10 s.
#[test]
fn hover_equilibrium_holds_position_for_every_airframe() {
    for name in SHIPPED {
        let mut sim = airborne(name, SensorPreset::Ideal);
        let p0 = sim.truth().body.pos_ned_m;
        for _ in 0..10_000 {
            let u = sim.hover_commands();
            sim.step(&u);
        }
        let t = sim.truth();
        let drift = (t.body.pos_ned_m - p0).norm();
        println!(
            "hover 10 s {name:>9}: drift {drift:.2e} m, tilt {:.2e} rad, battery {:.2} V",
            t.body.q_ned_from_frd.angle(),
            t.battery_voltage_v
        );
        assert!(drift < 1e-3, "{name}: drifted {drift} m");
        assert!(
            t.battery_voltage_v < 4.2 * sim.airframe().battery.cells as f64,
            "the battery must have sagged"
        );
    }
}

#[test]
fn free_fall_without_drag_is_exact_and_with_drag_reaches_terminal_speed() {
    let mut a = shipped("quad_x");
    a.drag.linear_n_s_m = [0.0; 3];
    a.drag.quadratic_n_s2_m2 = [0.0; 3];
    let start = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -1000.0),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&a, config(SensorPreset::Ideal), start).unwrap();
    for _ in 0..3000 {
        sim.step(&[0.0; 4]);
    }
    let z = sim.truth().body.pos_ned_m.z + 1000.0;
    assert!((z - 0.5 * GRAVITY_M_S2 * 9.0).abs() < 1e-6, "fell {z} m");
    // The accelerometer of a falling body reads zero specific force.
    let f = sim.sample_sensors().accel_frd_m_s2;
    assert!(f.norm() < 1e-6, "{f:?}");

    // With drag: m g = c₁ v + c₂ v² along body z.
    let a = shipped("quad_x");
    let mut sim = Simulator::new(&a, config(SensorPreset::Ideal), start).unwrap();
    for _ in 0..30_000 {
        sim.step(&[0.0; 4]);
    }
    let (c1, c2, w) = (
        a.drag.linear_n_s_m[2],
        a.drag.quadratic_n_s2_m2[2],
        a.weight_n(),
    );
    let v_terminal = (-c1 + (c1 * c1 + 4.0 * c2 * w).sqrt()) / (2.0 * c2);
    let v = sim.truth().body.vel_ned_m_s.z;
    assert!((v / v_terminal - 1.0).abs() < 1e-3, "{v} vs {v_terminal}");
}

/// The force model, rotor by rotor, equals the effectiveness matrix B the mixer will invert:
/// [F_z, M_x, M_y, M_z] = B · T for arbitrary speeds, on every airframe. This is the test that
/// catches motor order and spin-direction mistakes.
#[test]
fn rotor_wrench_equals_the_effectiveness_matrix() {
    let mut rng = crate::rng::Rng::stream(3, 3);
    for name in SHIPPED {
        let a = shipped(name);
        let b = a.effectiveness();
        for _ in 0..20 {
            let speeds: Vec<f64> = a
                .rotors
                .iter()
                .map(|r| rng.uniform() * r.max_speed_rad_s)
                .collect();
            let thrust = DVector::from_iterator(
                speeds.len(),
                a.rotors
                    .iter()
                    .zip(&speeds)
                    .map(|(r, &w)| r.thrust_n(1.1, w)),
            );
            let expected = &b * thrust;
            let got = steady_wrench(&a, &speeds, 1.1);
            for k in 0..4 {
                assert!(
                    (got[k] - expected[k]).abs() < 1e-9 * (1.0 + expected[k].abs()),
                    "{name} row {k}"
                );
            }
        }
    }
}

fn run(sim: &mut Simulator, u: &[f64], steps: usize) {
    for _ in 0..steps {
        sim.step(u);
    }
}

/// Sign conventions: front rotors faster → nose up (positive pitch rate); left faster → roll right;
/// ccw rotors faster → yaw right (docs/conventions.md: a ccw rotor's reaction torque is +z).
#[test]
fn differential_thrust_turns_the_way_the_conventions_say() {
    // quad_x: 1 front-right ccw, 2 rear-left ccw, 3 front-left cw, 4 rear-right cw.
    let cases: [([f64; 4], usize, f64); 3] = [
        ([1.0, -1.0, 1.0, -1.0], 1, 1.0), // front up → pitch rate q > 0 (nose up)
        ([-1.0, 1.0, 1.0, -1.0], 0, 1.0), // left up → roll rate p > 0
        ([1.0, 1.0, -1.0, -1.0], 2, 1.0), // ccw up → yaw rate r > 0
    ];
    for (delta, axis, sign) in cases {
        let mut sim = airborne("quad_x", SensorPreset::Ideal);
        let mut u = [0.0; 4];
        let hover = sim.hover_commands();
        for i in 0..4 {
            u[i] = hover[i] + 0.03 * delta[i];
        }
        run(&mut sim, &u, 200);
        let w = sim.truth().body.rate_frd_rad_s;
        assert!(sign * w[axis] > 0.1, "axis {axis}: {w:?}");
        for other in (0..3).filter(|&k| k != axis) {
            assert!(
                w[other].abs() < 0.05 * w[axis].abs(),
                "axis {axis} leaks into {other}: {w:?}"
            );
        }
    }
}

#[test]
fn vehicle_rests_on_the_ground_lifts_off_and_touches_down() {
    let a = shipped("quad_x");
    let mut sim = Simulator::new(&a, config(SensorPreset::Ideal), BodyState::default()).unwrap();
    assert!(sim.truth().landed);
    run(&mut sim, &[0.2; 4], 2000); // below hover: stays down, the legs a little less loaded
    let t = sim.truth();
    assert!(t.landed && t.body.pos_ned_m.z.abs() < 0.005, "{t:?}");
    assert!(t.body.vel_ned_m_s.norm() < 1e-6, "{t:?}");
    let f = sim.sample_sensors().accel_frd_m_s2;
    assert!(
        (f - Vector3::new(0.0, 0.0, -GRAVITY_M_S2)).norm() < 1e-6,
        "resting accel {f:?}"
    );
    run(&mut sim, &[0.8; 4], 1500); // climb
    let t = sim.truth();
    assert!(
        !t.landed && t.body.pos_ned_m.z < -1.0,
        "{:?}",
        t.body.pos_ned_m
    );
    run(&mut sim, &[0.0; 4], 5000); // fall back: bounces on its legs, one touchdown
    let t = sim.truth();
    assert!(t.landed && t.body.pos_ned_m.z.abs() < 0.005, "{t:?}");
    assert_eq!(sim.stats().touchdowns, 1);
    assert!(sim.stats().last_touchdown_speed_m_s > 2.0);
}

/// A tumble turns the vehicle by hand through every orientation — its down axis reaches all 26
/// directions of a cube's faces, edges and corners — the gyro and accelerometer feel it as a
/// hand's turns (rates that integrate to the attitude, the specific force −g in the body), and
/// at the end it stands level where it was, heading kept.
#[test]
fn a_tumble_turns_the_vehicle_through_every_orientation_and_sets_it_down() {
    let a = shipped("quad_x");
    let mut sim = Simulator::new(&a, config(SensorPreset::Ideal), BodyState::default()).unwrap();
    sim.schedule(&[Event {
        t_s: 1.0,
        action: SimAction::Tumble { duration_s: 60.0 },
    }])
    .unwrap();
    let mut seen = std::collections::HashSet::new();
    let mut integrated = UnitQuaternion::identity();
    let mut worst_accel: f64 = 0.0;
    for _ in 0..64_000 {
        sim.step(&[0.0; 4]);
        let body = sim.truth().body;
        integrated *= UnitQuaternion::from_scaled_axis(body.rate_frd_rad_s * 1e-3);
        let f = sim.sample_sensors().accel_frd_m_s2;
        let g_body =
            body.q_ned_from_frd
                .inverse_transform_vector(&Vector3::new(0.0, 0.0, -GRAVITY_M_S2));
        worst_accel = worst_accel.max((f - g_body).norm());
        let down = body.q_ned_from_frd.transform_vector(&Vector3::z());
        let cell = down.map(|x| (x * 1.5).round() as i8);
        if cell != Vector3::zeros() {
            seen.insert((cell.x.signum(), cell.y.signum(), cell.z.signum()));
        }
        if sim.time_s() > 30.0 && sim.time_s() < 30.002 {
            let err = integrated.angle_to(&body.q_ned_from_frd);
            assert!(err < 1e-3, "gyro integrates to the attitude: {err} rad");
        }
    }
    assert_eq!(seen.len(), 26, "{seen:?}");
    // Gravity, and the lever arm's ω × (ω × r) and ω̇ × r of a hand's turns (≈ 1 rad/s).
    println!("tumble: accelerometer off gravity by {worst_accel:.4} m/s² at most");
    assert!(
        worst_accel < 0.1,
        "held still: the accelerometer feels gravity alone"
    );
    let t = sim.truth();
    assert!(t.landed && t.body.pos_ned_m.z.abs() < 0.005, "{t:?}");
    let (roll, pitch, _) = t.body.q_ned_from_frd.euler_angles();
    assert!(roll.abs() < 1e-4 && pitch.abs() < 1e-4, "{roll} {pitch}");
    assert!(t.body.rate_frd_rad_s.norm() < 1e-6);
    // Set down without a jump: the gyro's turns still add up to the attitude.
    let err = integrated.angle_to(&t.body.q_ned_from_frd);
    assert!(
        err < 1e-3,
        "gyro integrates to the level attitude: {err} rad"
    );
}

#[test]
fn bad_actuator_values_are_clamped_and_counted() {
    let mut sim = airborne("quad_x", SensorPreset::Ideal);
    sim.step(&[f64::NAN, 1.5, -0.2, f64::INFINITY]);
    let s = sim.stats();
    assert_eq!((s.nonfinite_commands, s.clamped_commands), (2, 2));
    assert!(sim.truth().body.pos_ned_m.iter().all(|x| x.is_finite()));
}

#[test]
fn motor_lag_is_first_order_with_the_airframe_time_constant() {
    let mut sim = airborne("quad_x", SensorPreset::Ideal);
    sim.set_rotor_speeds(&[0.0; 4]);
    let tau = sim.airframe().rotors[0].time_constant_s;
    let steps = (tau / sim.config().dt_s).round() as usize;
    let v = sim.truth().battery_voltage_v;
    run(&mut sim, &[0.5; 4], steps);
    let target = Rotors::commanded_speed(&sim.airframe().rotors[0], 0.5, v);
    let frac = sim.rotor_speeds()[0] / target;
    assert!(
        (frac - (1.0 - (-1.0f64).exp())).abs() < 0.01,
        "reached {frac} of target after τ"
    );
}

#[test]
fn same_seed_gives_identical_streams_and_another_seed_does_not() {
    let trace = |seed: u64| {
        let a = shipped("hexa_x");
        let cfg = SimConfig {
            seed,
            wind: WindConfig {
                mean_ned_m_s: [3.0, 1.0, 0.0],
                turbulence_w20_m_s: 8.0,
                roughness_m: None,
            },
            ..SimConfig::default()
        };
        let initial = BodyState {
            pos_ned_m: Vector3::new(0.0, 0.0, -5.0),
            ..BodyState::default()
        };
        let mut sim = Simulator::new(&a, cfg, initial).unwrap();
        let mut out = Vec::new();
        for _ in 0..3000 {
            let u = sim.hover_commands();
            sim.step(&u);
            let f = sim.sample_sensors().clone();
            out.extend(
                f.accel_frd_m_s2
                    .iter()
                    .chain(f.gyro_frd_rad_s.iter())
                    .chain(f.mag_frd_gauss.iter())
                    .map(|x| x.to_bits()),
            );
            out.extend(sim.truth().body.pos_ned_m.iter().map(|x| x.to_bits()));
        }
        out
    };
    assert_eq!(trace(11), trace(11));
    assert_ne!(trace(11), trace(12));
}

#[test]
fn sensor_rates_and_fields_updated() {
    let mut sim = airborne("quad_x", SensorPreset::Typical);
    let (mut mag, mut baro, mut gps, mut imu) = (0, 0, 0, 0);
    for _ in 0..2000 {
        let u = sim.hover_commands();
        sim.step(&u);
        let f = sim.sample_sensors();
        imu += (f.fields_updated & fields::ACCEL == fields::ACCEL) as u32;
        mag += (f.fields_updated & fields::MAG != 0) as u32;
        baro += (f.fields_updated & fields::BARO == fields::BARO) as u32;
        gps += f.gps.is_some() as u32;
    }
    // First samples at t = 1 ms, then one per period through t = 2 s inclusive.
    assert_eq!((imu, mag, baro), (2000, 201, 101));
    assert!((19..=20).contains(&gps), "gps {gps}");
}

/// Typical gyro noise is N/√Δt per sample; the accelerometer at hover sees −g plus vibration.
#[test]
fn typical_noise_matches_its_density() {
    let mut sim = airborne("quad_x", SensorPreset::Typical);
    let cfg = sim.config().sensors.clone();
    let n = 20_000;
    let mut gyro = Vec::with_capacity(n);
    for _ in 0..n {
        let u = sim.hover_commands();
        sim.step(&u);
        gyro.push(sim.sample_sensors().gyro_frd_rad_s.x);
    }
    let mean = gyro.iter().sum::<f64>() / n as f64;
    let sd = (gyro.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    let expected = cfg.gyro_noise_density / sim.config().dt_s.sqrt();
    assert!(
        (sd / expected - 1.0).abs() < 0.05,
        "gyro σ {sd} vs {expected}"
    );
    assert!(
        (mean - sim.sensors().gyro_bias().x).abs() < 5e-4,
        "bias {mean}"
    );
}

/// Castillo (75) calibration m = R E Rᵀ (m_raw − offset), whose R E Rᵀ is our S⁻¹, recovers the
/// body-frame field from the distorted reading.
#[test]
fn magnetometer_distortion_is_inverted_by_castillo_calibration() {
    let mut cfg = config(SensorPreset::Ideal);
    let noisy = SensorConfig::preset(SensorPreset::Noisy);
    cfg.sensors.mag_hard_iron = noisy.mag_hard_iron;
    cfg.sensors.mag_soft_iron = noisy.mag_soft_iron;
    let q = UnitQuaternion::from_euler_angles(0.3, -0.5, 2.0);
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -10.0),
        q_ned_from_frd: q,
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&shipped("quad_x"), cfg.clone(), initial).unwrap();
    sim.step(&[0.0; 4]);
    let raw = sim.sample_sensors().mag_frd_gauss;
    let body = sim.truth().body.q_ned_from_frd.inverse() * cfg.earth_field.ned();
    let calibrated =
        cfg.sensors.mag_soft_iron.try_inverse().unwrap() * (raw - cfg.sensors.mag_hard_iron);
    assert!((calibrated - body).norm() < 1e-12);
    assert!((raw - body).norm() > 0.05, "the distortion must be visible");
}

#[test]
fn gps_reports_the_position_of_its_latency_ago_and_baro_the_isa_altitude() {
    let mut cfg = config(SensorPreset::Ideal);
    cfg.sensors.gps_latency_s = 0.2;
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -20.0),
        vel_ned_m_s: Vector3::new(5.0, 0.0, 0.0),
        ..BodyState::default()
    };
    let mut a = shipped("quad_x");
    a.drag.linear_n_s_m = [0.0; 3];
    a.drag.quadratic_n_s2_m2 = [0.0; 3];
    let mut sim = Simulator::new(&a, cfg.clone(), initial).unwrap();
    let hover = sim.hover_speeds();
    sim.set_rotor_speeds(&hover);
    let mut history = Vec::new();
    let mut checked = 0;
    for _ in 0..1000 {
        let u = sim.hover_commands();
        sim.step(&u);
        history.push((sim.time_usec(), sim.truth().body.pos_ned_m));
        let f = sim.sample_sensors().clone();
        if let Some(fix) = f.gps {
            assert!(sim.time_usec() - fix.time_usec == 200_000);
            let (_, then) = history.iter().find(|(t, _)| *t == fix.time_usec).unwrap();
            let ned = cfg.home.ned_to(&fix.position);
            assert!((ned - then).norm() < 1e-6, "{ned:?} vs {then:?}");
            checked += 1;
        }
        if f.fields_updated & fields::PRESSURE_ALT != 0 {
            let truth_alt = cfg.home.alt_m - sim.truth().body.pos_ned_m.z;
            assert!((f.pressure_alt_m - truth_alt).abs() < 1e-6);
        }
    }
    assert!(checked >= 7);
}

#[test]
fn lever_arm_adds_centripetal_acceleration() {
    // IMU 0.1 m forward of the CG, body spinning about z at 3 rad/s in free fall: the
    // accelerometer feels −ω² r = 0.9 m/s² toward the centre (Zabunov (53)).
    let mut a = shipped("quad_x");
    a.imu_position_frd_m = Vector3::new(0.1, 0.0, 0.0);
    a.drag.rotational_n_m_s_rad = [0.0; 3];
    a.drag.linear_n_s_m = [0.0; 3];
    a.drag.quadratic_n_s2_m2 = [0.0; 3];
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -100.0),
        rate_frd_rad_s: Vector3::new(0.0, 0.0, 3.0),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&a, config(SensorPreset::Ideal), initial).unwrap();
    sim.step(&[0.0; 4]);
    let f = sim.sample_sensors().accel_frd_m_s2;
    assert!((f - Vector3::new(-0.9, 0.0, 0.0)).norm() < 1e-6, "{f:?}");
}

#[test]
fn scheduled_motor_failure_stops_the_rotor_and_makes_the_vehicle_fall() {
    let mut sim = airborne("quad_x", SensorPreset::Ideal);
    sim.schedule(&[Event {
        t_s: 0.5,
        action: SimAction::MotorFail { index: 0 },
    }])
    .unwrap();
    assert!(
        sim.schedule(&[Event {
            t_s: 0.5,
            action: SimAction::MotorFail { index: 4 }
        }])
        .is_err()
    );
    for _ in 0..1500 {
        let u = sim.hover_commands();
        sim.step(&u);
    }
    assert!(sim.rotor_speeds()[0] < 1.0);
    assert!(
        sim.truth().body.q_ned_from_frd.angle() > 0.5,
        "a quad losing a rotor must tumble"
    );
}

#[test]
fn torque_pulse_is_felt_and_ends() {
    let mut sim = airborne("quad_x", SensorPreset::Ideal);
    sim.apply(SimAction::TorquePulse {
        torque_frd_n_m: Vector3::new(0.029 * 40.0, 0.0, 0.0),
        duration_s: 0.1,
    });
    for _ in 0..100 {
        let u = sim.hover_commands();
        sim.step(&u);
    }
    let p = sim.truth().body.rate_frd_rad_s.x;
    assert!(
        (p - 4.0).abs() < 0.1,
        "40 rad/s² for 0.1 s gives ≈ 4 rad/s, got {p}"
    );
    for _ in 0..100 {
        let u = sim.hover_commands();
        sim.step(&u);
    }
    assert!(
        (sim.truth().body.rate_frd_rad_s.x - p).abs() < 0.1,
        "the pulse must end"
    );
}

#[test]
fn sensor_faults_silence_freeze_and_lose_fix() {
    let mut sim = airborne("quad_x", SensorPreset::Typical);
    let hover = |s: &mut Simulator| {
        let u = s.hover_commands();
        s.step(&u);
        s.sample_sensors().clone()
    };
    for _ in 0..300 {
        hover(&mut sim);
    }
    sim.apply(SimAction::Sensor {
        sensor: SensorKind::Mag,
        health: SensorHealth::Off,
    });
    sim.apply(SimAction::Sensor {
        sensor: SensorKind::Imu,
        health: SensorHealth::Stuck,
    });
    sim.apply(SimAction::GpsFixLost(true));
    let fault_usec = sim.time_usec();
    let first = hover(&mut sim);
    let mut gps_seen = 0;
    for _ in 0..300 {
        let f = hover(&mut sim);
        assert_eq!(f.fields_updated & fields::MAG, 0, "mag is off");
        assert_ne!(
            f.fields_updated & fields::ACCEL,
            0,
            "a stuck IMU still reports"
        );
        assert_eq!(f.accel_frd_m_s2, first.accel_frd_m_s2, "stuck: same value");
        // Solutions computed before the fault are still in the receiver's latency queue.
        if let Some(fix) = f.gps.filter(|g| g.time_usec > fault_usec) {
            assert_eq!((fix.fix_type, fix.satellites), (1, 0));
            gps_seen += 1;
        }
    }
    assert!(gps_seen > 0, "the receiver keeps reporting, without a fix");
    sim.apply(SimAction::Sensor {
        sensor: SensorKind::Imu,
        health: SensorHealth::Ok,
    });
    assert_ne!(hover(&mut sim).accel_frd_m_s2, first.accel_frd_m_s2);
}

/// A stand-in for an external flight-dynamics model: the same rigid body, integrated by RK4
/// from the loads held over the step, assembled rotor by rotor the way JSBSim's model applies
/// them (thrust at each hub, each yaw moment, the aerodynamic force and moment). No ground.
struct HeldLoads {
    airframe: Airframe,
    mass: MassProperties,
    body: BodyState,
}

impl ExternalBody for HeldLoads {
    fn advance(&mut self, l: &StepLoads) -> Result<ExternalBodyStep, ExternalBodyError> {
        let mut force = l.aero_force_frd_n;
        let mut moment = l.aero_moment_frd_n_m;
        for (i, r) in self.airframe.rotors.iter().enumerate() {
            let thrust = Vector3::new(0.0, 0.0, -l.rotor.thrust_n[i]);
            force += thrust;
            moment += r.position_frd_m.cross(&thrust) + Vector3::z() * l.rotor.yaw_moment_n_m[i];
        }
        let m = self.mass;
        let accel = |s: &BodyState| Accel {
            lin_ned_m_s2: s.q_ned_from_frd.transform_vector(&force) / m.mass_kg
                + Vector3::z() * GRAVITY_M_S2,
            ang_frd_rad_s2: m.angular_accel(&s.rate_frd_rad_s, &moment),
        };
        let before = self.body;
        self.body = Integrator::Rk4.step(&self.body, l.dt_s, accel);
        Ok(ExternalBodyStep {
            body: self.body,
            specific_force_frd_m_s2: force / m.mass_kg,
            ang_accel_frd_rad_s2: (self.body.rate_frd_rad_s - before.rate_frd_rad_s) / l.dt_s,
            on_ground: false,
        })
    }
}

/// The loads handed to an external model are the whole wrench: a body that integrates them
/// on its own follows the built-in physics through a climb, a roll and a yaw manoeuvre in a
/// 5 m/s wind to within 0.1 % of the distance flown (only the drag and gyroscopic terms, held
/// over each step there, differ).
#[test]
fn an_external_body_fed_the_step_loads_flies_like_the_built_in_physics() {
    for name in ["quad_x", "hexa_x", "dodeca"] {
        let mut cfg = config(SensorPreset::Ideal);
        cfg.wind.mean_ned_m_s = [0.0, 5.0, 0.0];
        let a = shipped(name);
        let initial = BodyState {
            pos_ned_m: Vector3::new(0.0, 0.0, -30.0),
            ..BodyState::default()
        };
        let mut built_in = Simulator::new(&a, cfg.clone(), initial).unwrap();
        let mut external = Simulator::new(&a, cfg, initial).unwrap();
        let hover = built_in.hover_speeds();
        built_in.set_rotor_speeds(&hover);
        external.set_rotor_speeds(&hover);
        let mut body = HeldLoads {
            airframe: a.clone(),
            mass: *built_in.mass_properties(),
            body: initial,
        };
        let n = a.rotors.len();
        for k in 0..3000 {
            let mut u = built_in.hover_commands();
            // Rotor 1 up for a second, then every other rotor down: tilt, climb, yaw.
            if k < 1000 {
                u[0] += 0.03;
            } else if k < 2000 {
                for c in u.iter_mut().step_by(2) {
                    *c -= 0.02;
                }
            }
            built_in.step(&u[..n]);
            external.step_with(&u[..n], &mut body).unwrap();
        }
        let (b, e) = (built_in.truth(), external.truth());
        let dp = (b.body.pos_ned_m - e.body.pos_ned_m).norm();
        let dq = b.body.q_ned_from_frd.angle_to(&e.body.q_ned_from_frd);
        let moved = (b.body.pos_ned_m - initial.pos_ned_m).norm();
        println!("{name:>7}: moved {moved:.2} m, apart {dp:.2e} m and {dq:.2e} rad after 3 s");
        assert!(
            moved > 1.0 && b.body.q_ned_from_frd.angle() > 0.1,
            "{name}: a manoeuvre"
        );
        assert!(
            dp < 1e-3 * moved && dq < 2e-3,
            "{name}: {dp} m, {dq} rad apart"
        );
        assert_eq!(b.time_usec, e.time_usec);
        assert!((b.battery_remaining - e.battery_remaining).abs() < 1e-6);
    }
}

/// The hand puts the vehicle on each face in turn and holds it still there — the accelerometer
/// reads g on that face's axis, the gyro nothing — then sets it down upright and lets go.
#[test]
fn the_hand_places_the_vehicle_on_each_face_and_sets_it_down() {
    let a = shipped("quad_x");
    let mut sim = Simulator::new(&a, config(SensorPreset::Ideal), BodyState::default()).unwrap();
    for face in Face::ALL {
        sim.apply(SimAction::Place { face });
        run(&mut sim, &[0.0; 4], ((PLACE_S + 0.5) * 1000.0) as usize);
        let f = sim.sample_sensors();
        let expected = -face.down_axis() * GRAVITY_M_S2;
        assert!(
            (f.accel_frd_m_s2 - expected).norm() < 1e-6,
            "{face:?}: {}",
            f.accel_frd_m_s2
        );
        assert!(f.gyro_frd_rad_s.norm() < 1e-9, "held still");
        assert!(sim.truth().landed);
    }
    sim.apply(SimAction::SetDown);
    run(&mut sim, &[0.0; 4], 3000);
    let (roll, pitch, _) = sim.truth().body.q_ned_from_frd.euler_angles();
    assert!(roll.abs() < 1e-9 && pitch.abs() < 1e-9);
    assert!(sim.hand.is_none(), "let go");
}
