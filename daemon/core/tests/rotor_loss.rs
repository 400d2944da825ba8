//! A quad that loses a rotor in flight, in lockstep with the simulator: the whole autopilot
//! (detection, the switch to the reduced-attitude controller, the failsafe's landing, the
//! touchdown and the disarm) on the simulator's `typical` sensors.
#![allow(clippy::unwrap_used, missing_docs)]

use airframe::MAX_ROTORS;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{AutoFlight, Autopilot};
use flight_core::commander::{FlightMode, LandedState};
use flight_core::mission::{MissionAltitude, MissionPoint};
use flight_core::params::FlightParams;
use flight_core::sample::StepOutput;
use nalgebra::Vector3;
use navmath::geo::LocalFrame;
use sitl_core::environment::WindConfig;
use sitl_core::sim::{SimAction, SimConfig, Simulator, TruthState};

mod common;
use common::airframe;

/// The flight before the cut.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Before {
    /// Hovering at 10 m.
    Hover,
    /// Flying north at 5 m/s, 10 m up.
    Forward,
    /// Hovering at 10 m in a 5 m/s wind from the west with turbulence.
    Wind,
    /// Hovering at 10 m, 30 m north of home (for a Return).
    Away,
}

/// The spin-up after the cut (s): the estimate's errors are counted apart in it.
const SPIN_UP_S: f64 = 2.0;

/// `RTL_RETURN_ALT` of the Return's flights (m; the default).
const RETURN_ALT_M: f64 = 30.0;

/// Height above which the estimate's errors are counted (m).
const CONTACT_M: f64 = 0.3;

/// One flight: the airframe, the rotor cut (0-based), the flight before, the seed, and whether
/// the ESCs report the rotors' speeds.
#[derive(Debug, Clone, Copy)]
struct Case<'a> {
    name: &'a str,
    rotor: usize,
    before: Before,
    seed: u64,
    esc_telemetry: bool,
}

/// What one flight came to.
#[derive(Debug, Default)]
struct Outcome {
    /// The failure declared: the rotor (0-based) and the time after the cut (s).
    detected: Option<(usize, f64)>,
    /// Flying on three rotors (the core's reduced-attitude controller).
    spinning: bool,
    /// Largest height below the set-point in the air after the cut (m; below the height at the
    /// cut while the set-point is above it: the landing's own descent is not a loss).
    alt_loss_m: f64,
    /// Largest horizontal distance from the point of the cut while in the air (m).
    departure_m: f64,
    /// Horizontal distance of the touchdown from the point of the cut (m).
    landed_from_cut_m: f64,
    /// Fastest vertical speed of the touchdowns after the cut (m/s; a bounce is one more).
    touchdown_m_s: f64,
    /// Disarmed on the ground.
    disarmed: bool,
    /// Mean and largest yaw rate from 3 s after the cut to the touchdown (rad/s).
    mean_yaw_rate: f64,
    max_yaw_rate: f64,
    /// Largest tilt of the body's z from the vertical in the air after the cut (deg).
    peak_tilt_deg: f64,
    /// The failsafe's Land flew it.
    landed_by_land: bool,
    /// The failsafe's Return flew it.
    returned: bool,
    /// Largest body rate after the cut (rad/s, the truth: what the gyro must read).
    max_rate: f64,
    /// Time from the cut to the disarm (s).
    down_after_s: f64,
    /// Horizontal distance of the touchdown from home (m).
    landed_from_home_m: f64,
    /// The estimator's largest tilt error in the spin-up's first [`SPIN_UP_S`] (deg).
    spin_up_tilt_error_deg: f64,
    /// The estimator in the air after the spin-up: the largest error of its tilt (deg), of its
    /// heading (deg), of its horizontal position (m) and of its velocity (m/s).
    errors: [f64; 4],
    /// The same four over the hover's last 3 s before the cut.
    before_errors: [f64; 4],
    /// Samples of the estimate judged in the spin-up and after it.
    error_samples: [usize; 2],
    /// Highest height in the air after the cut (m).
    max_alt_m: f64,
    /// Largest tilt on the ground, from the first touch to the disarm (deg): a spinning quad's
    /// legs catch on the ground.
    ground_tilt_deg: f64,
}

/// Keeps in `largest` the larger of each of its errors and `e`'s.
fn keep_largest(largest: &mut [f64; 4], e: [f64; 4]) {
    for (l, e) in largest.iter_mut().zip(e) {
        *l = l.max(e);
    }
}

/// The estimate's errors against the truth: tilt (deg), heading (deg), horizontal position (m),
/// velocity (m/s). `origin_frame` keeps the estimator's local frame once it has an origin.
fn estimate_errors(
    out: &StepOutput,
    truth: &TruthState,
    origin_frame: &mut Option<LocalFrame>,
) -> Option<[f64; 4]> {
    let a = out.attitude?;
    let tr = &out.translation;
    let origin = tr.origin?;
    let body = &truth.body;
    let tilt = (a.q * Vector3::z()).angle(&(body.q_ned_from_frd * Vector3::z()));
    // Heading: the body's x projected on the horizontal (meaningful while the tilt is small).
    let x_of = |q: &nalgebra::UnitQuaternion<f64>| {
        let x = q * Vector3::x();
        x.y.atan2(x.x)
    };
    let d = x_of(&a.q) - x_of(&body.q_ned_from_frd);
    let heading = d.sin().atan2(d.cos()).abs();
    // The estimate's position is from its own origin (the first GPS fix): through the globe to
    // the simulator's home frame.
    let frame = origin_frame.get_or_insert_with(|| LocalFrame::new(origin));
    let at = truth.home.to_ned(&frame.to_geodetic(&tr.pos_ned_m));
    let position = (at - body.pos_ned_m).xy().norm();
    let velocity = (tr.vel_ned_m_s - body.vel_ned_m_s).norm();
    Some([tilt.to_degrees(), heading.to_degrees(), position, velocity])
}

/// The case's quad takes off to 10 m, flies as the case says, loses its rotor and flies on under
/// `params` until it has landed and disarmed (at most 150 s of simulated time).
fn lose_a_rotor(case: Case, params: &FlightParams) -> Outcome {
    let Case {
        name,
        rotor,
        before,
        seed,
        esc_telemetry,
    } = case;
    let a = airframe(name);
    let wind = if before == Before::Wind {
        WindConfig {
            mean_ned_m_s: [0.0, 5.0, 0.0],
            turbulence_w20_m_s: 5.0,
            roughness_m: None,
        }
    } else {
        WindConfig::default()
    };
    let cfg = SimConfig {
        seed,
        wind,
        ..SimConfig::default()
    };
    let mut sim = Simulator::new(&a, cfg, sitl_core::BodyState::default()).unwrap();
    let auto = AutoFlight {
        takeoff_m: 10.0,
        hover_s: f64::INFINITY,
    };
    let mut autopilot = Autopilot::new(&a, params, Some(auto)).unwrap();
    let mut commands = [0.0; MAX_ROTORS];
    let mut o = Outcome::default();
    let (mut hover_since, mut cut_at) = (None::<f64>, None::<(f64, Vector3<f64>)>);
    let (mut yaw_sum, mut yaw_n) = (0.0, 0usize);
    let (mut asked_away, mut settled_since) = (false, None::<f64>);
    let mut origin_frame = None;
    let (mut touchdowns, mut touched) = (0, false);
    while sim.time_s() < 150.0 {
        let out = common::autopilot_interval(
            &mut sim,
            &mut autopilot,
            &mut commands,
            a.rotors.len(),
            esc_telemetry,
        );
        let t = sim.time_s();
        let truth = sim.truth();
        let body = truth.body;
        let status = autopilot.status();
        let Some(est) = autopilot.state().estimate else {
            continue;
        };
        if let Some(f) = est.motor_failure {
            let after = cut_at.map_or(-1.0, |(c, _)| t - c);
            o.detected.get_or_insert((f.rotor, after));
        }
        let errors = estimate_errors(&est, &truth, &mut origin_frame);
        match cut_at {
            None => {
                let up = status.landed == LandedState::InAir && -body.pos_ned_m.z > 9.7;
                if up && hover_since.is_none() {
                    hover_since = Some(t);
                }
                if hover_since.is_none() {
                    continue;
                }
                if before != Before::Hover && before != Before::Wind && !asked_away {
                    // Forward: 500 m north at 5 m/s; away: 30 m north, to hover there.
                    let (north, speed) = match before {
                        Before::Forward => (500.0, Some(5.0)),
                        _ => (30.0, None),
                    };
                    let to = truth
                        .home
                        .to_geodetic(&Vector3::new(north, 0.0, body.pos_ned_m.z));
                    autopilot
                        .command(AutopilotCommand::Reposition {
                            at: MissionPoint {
                                lat_lon_deg: Some((to.lat_deg, to.lon_deg)),
                                alt: Some(MissionAltitude::AboveHome(10.0)),
                            },
                            speed_m_s: speed,
                            yaw_rad: None,
                            change_mode: true,
                        })
                        .unwrap();
                    asked_away = true;
                }
                // The last 3 s before the cut (the forward flight's at speed).
                let settled = match before {
                    Before::Forward => body.vel_ned_m_s.x > 4.9,
                    Before::Away => {
                        (body.pos_ned_m.xy() - Vector3::new(30.0, 0.0, 0.0).xy()).norm() < 0.5
                            && body.vel_ned_m_s.norm() < 0.2
                    }
                    _ => true,
                };
                if !settled {
                    settled_since = None;
                    o.before_errors = [0.0; 4];
                    continue;
                }
                let s0 = *settled_since.get_or_insert(t);
                if let Some(e) = errors {
                    keep_largest(&mut o.before_errors, e);
                }
                if t > s0 + 3.0 {
                    sim.apply(SimAction::MotorFail { index: rotor });
                    cut_at = Some((t, body.pos_ned_m));
                    // A spool-up or a gust may have touched the ground before: count from here.
                    touchdowns = sim.stats().touchdowns;
                }
            }
            Some((c, at)) => {
                o.spinning |= status.spinning;
                o.landed_by_land |= status.mode == FlightMode::Land;
                o.returned |= status.mode == FlightMode::Rtl;
                o.max_rate = o.max_rate.max(body.rate_frd_rad_s.norm());
                let stats = sim.stats();
                if stats.touchdowns > touchdowns {
                    touchdowns = stats.touchdowns;
                    touched = true;
                    o.touchdown_m_s = o.touchdown_m_s.max(stats.last_touchdown_speed_m_s);
                }
                let off = body.pos_ned_m - at;
                // In the air: until the first touch of the ground (a spinning vehicle's legs
                // may lift off it again as it settles).
                if !truth.landed && !touched {
                    // Below the set-point's descent (the landing's own is not a loss).
                    let asked = match out.setpoint {
                        flight_core::control::Setpoint::Position(p) => p.pos_ned_m.z,
                        _ => at.z,
                    };
                    o.alt_loss_m = o.alt_loss_m.max(body.pos_ned_m.z - asked.max(at.z));
                    o.departure_m = o.departure_m.max(off.xy().norm());
                    o.max_alt_m = o.max_alt_m.max(-body.pos_ned_m.z);
                    let tilt = (body.q_ned_from_frd * Vector3::z()).angle(&Vector3::z());
                    o.peak_tilt_deg = o.peak_tilt_deg.max(tilt.to_degrees());
                    // Above the ground: the legs' touch is judged in touchdown.rs.
                    let errors = errors.filter(|_| -body.pos_ned_m.z > CONTACT_M);
                    if let (Some(e), true) = (errors, t < c + SPIN_UP_S) {
                        o.spin_up_tilt_error_deg = o.spin_up_tilt_error_deg.max(e[0]);
                        o.error_samples[0] += 1;
                    } else if let Some(e) = errors {
                        keep_largest(&mut o.errors, e);
                        o.error_samples[1] += 1;
                    }
                    if t > c + 3.0 {
                        let r = body.rate_frd_rad_s.z.abs();
                        yaw_sum += r;
                        yaw_n += 1;
                        o.max_yaw_rate = o.max_yaw_rate.max(r);
                    }
                }
                if touched {
                    let tilt = (body.q_ned_from_frd * Vector3::z()).angle(&Vector3::z());
                    o.ground_tilt_deg = o.ground_tilt_deg.max(tilt.to_degrees());
                }
                if !status.armed {
                    o.disarmed = truth.landed;
                    o.landed_from_cut_m = off.xy().norm();
                    o.landed_from_home_m = body.pos_ned_m.xy().norm();
                    o.down_after_s = t - c;
                    break;
                }
            }
        }
    }
    o.mean_yaw_rate = yaw_sum / yaw_n.max(1) as f64;
    o
}

/// The worst of a set of flights.
#[derive(Debug, Default)]
struct Worst {
    flights: usize,
    detect_s: f64,
    alt_loss_m: f64,
    departure_m: f64,
    landed_from_cut_m: f64,
    landed_from_home_m: f64,
    touchdown_m_s: f64,
    peak_tilt_deg: f64,
    ground_tilt_deg: f64,
    max_rate: f64,
    down_after_s: f64,
    yaw_rate_sum: f64,
    max_yaw_rate: f64,
    /// Tilt, heading, position and velocity errors after the cut and before it.
    errors: [f64; 4],
    before_errors: [f64; 4],
    spin_up_tilt_error_deg: f64,
    /// The lowest of the flights' highest heights after the cut.
    least_max_alt_m: f64,
}

impl Worst {
    /// Counts in one flight.
    fn take(&mut self, o: &Outcome) {
        self.least_max_alt_m = if self.flights == 0 {
            o.max_alt_m
        } else {
            self.least_max_alt_m.min(o.max_alt_m)
        };
        self.flights += 1;
        self.detect_s = self.detect_s.max(o.detected.map_or(f64::INFINITY, |d| d.1));
        self.alt_loss_m = self.alt_loss_m.max(o.alt_loss_m);
        self.departure_m = self.departure_m.max(o.departure_m);
        self.landed_from_cut_m = self.landed_from_cut_m.max(o.landed_from_cut_m);
        self.landed_from_home_m = self.landed_from_home_m.max(o.landed_from_home_m);
        self.touchdown_m_s = self.touchdown_m_s.max(o.touchdown_m_s);
        self.max_rate = self.max_rate.max(o.max_rate);
        self.peak_tilt_deg = self.peak_tilt_deg.max(o.peak_tilt_deg);
        self.ground_tilt_deg = self.ground_tilt_deg.max(o.ground_tilt_deg);
        self.down_after_s = self.down_after_s.max(o.down_after_s);
        self.yaw_rate_sum += o.mean_yaw_rate;
        self.max_yaw_rate = self.max_yaw_rate.max(o.max_yaw_rate);
        self.spin_up_tilt_error_deg = self.spin_up_tilt_error_deg.max(o.spin_up_tilt_error_deg);
        keep_largest(&mut self.errors, o.errors);
        keep_largest(&mut self.before_errors, o.before_errors);
    }

    /// Prints the figures of `what`.
    fn print(&self, what: &str) {
        let [t, h, p, v] = self.errors;
        let [bt, bh, bp, bv] = self.before_errors;
        println!(
            "{what}, {} flights: found within {:.3} s; below the set-point (the cut's height if lower) ≤ {:.2} m, up to ≥ {:.1} m; from the cut ≤ {:.2} m in the air, ≤ {:.2} m at touchdown ({:.2} m from home); touchdown ≤ {:.2} m/s; tilt ≤ {:.0}° in the air (the spin-up), ≤ {:.0}° on the ground; body rate ≤ {:.1} rad/s; down within {:.1} s; yaw rate {:.1} rad/s mean, {:.1} rad/s peak\n    the estimate: tilt ≤ {:.1}° in the spin-up; in the air after it (before the cut): tilt ≤ {t:.2}° ({bt:.2}°), heading ≤ {h:.1}° ({bh:.1}°), horizontal position ≤ {p:.2} m ({bp:.2} m), velocity ≤ {v:.2} m/s ({bv:.2} m/s)",
            self.flights,
            self.detect_s,
            self.alt_loss_m,
            self.least_max_alt_m,
            self.departure_m,
            self.landed_from_cut_m,
            self.landed_from_home_m,
            self.touchdown_m_s,
            self.peak_tilt_deg,
            self.ground_tilt_deg,
            self.max_rate,
            self.down_after_s,
            self.yaw_rate_sum / self.flights.max(1) as f64,
            self.max_yaw_rate,
            self.spin_up_tilt_error_deg
        );
    }
}

/// The parameters flown: the defaults, the simulator's magnetometer calibrated.
fn params() -> FlightParams {
    let mut p = FlightParams::default();
    p.attitude.mag_calibration_id = flight_core::sensors::mag_check::SIMULATED_MAG_ID;
    p
}

/// The largest estimate errors asserted, in the spin-up and after it: tilt (deg), heading (deg),
/// horizontal position (m) and velocity (m/s). Before the cut they are 0.58°, 0.6°, 0.76 m (in
/// forward flight; 0.33 m in a hover) and 0.11 m/s.
const SPIN_UP_TILT_ERROR_DEG: f64 = 2.0;
const ERRORS_AT_SPIN: [f64; 4] = [1.5, 5.0, 1.5, 0.5];

/// What every flight of `c` must show: the right rotor found within `found_within_s`, the quad
/// spinning on its other three (the body rate within the ±2000°/s gyro's range, the spin-up's
/// tilt short of the crash check's 60°), the estimate holding, and the failsafe's action flown
/// to a touchdown and a disarm. From a hover (or for a Return) it falls at most 2 m below its
/// set-point and touches down at 1.5 m/s at most, within 3 m of the point of the cut (of home);
/// from 5 m/s forward and in a 5 m/s wind with turbulence it falls at most 2.5 m and touches
/// down at 2 m/s at most.
fn assert_flown(c: &Case, o: &Outcome, found_within_s: f64) {
    let case = format!("{c:?}: {o:?}");
    let (found, after) = o.detected.unwrap_or_else(|| panic!("not found: {case}"));
    assert!(
        found == c.rotor && (0.0..=found_within_s).contains(&after),
        "{case}"
    );
    assert!(o.spinning, "{case}");
    assert!(
        o.peak_tilt_deg < 60.0 && o.max_rate < 2000f64.to_radians(),
        "{case}"
    );
    assert!(o.error_samples.iter().all(|&n| n > 0), "{case}");
    assert!(o.spin_up_tilt_error_deg <= SPIN_UP_TILT_ERROR_DEG, "{case}");
    for (e, bound) in o.errors.iter().zip(ERRORS_AT_SPIN) {
        assert!(*e <= bound, "{case}");
    }
    match c.before {
        Before::Hover => {
            assert!(o.disarmed && o.landed_by_land, "{case}");
            assert!(o.alt_loss_m <= 2.0 && o.departure_m <= 3.0, "{case}");
            assert!(
                o.landed_from_cut_m <= 3.0 && o.touchdown_m_s <= 1.5,
                "{case}"
            );
        }
        Before::Away => {
            // Below the cut's height: the climb's set-point is above it.
            assert!(o.disarmed && o.returned, "{case}");
            assert!(
                o.alt_loss_m <= 2.0 && o.max_alt_m >= RETURN_ALT_M - 1.0,
                "{case}"
            );
            assert!(
                o.landed_from_home_m <= 3.0 && o.touchdown_m_s <= 1.5,
                "{case}"
            );
        }
        Before::Forward | Before::Wind => {
            assert!(o.disarmed && o.landed_by_land, "{case}");
            assert!(o.alt_loss_m <= 2.5 && o.touchdown_m_s <= 2.0, "{case}");
        }
    }
}

/// Flies each rotor of `quad_x` and `quad_plus` cut in turn from each of `befores`, over
/// `seeds`, asserts every flight and prints the worst figures of each set.
fn fly_every_rotor(
    befores: &[Before],
    seeds: u64,
    esc_telemetry: bool,
    params: &FlightParams,
    found_within_s: f64,
) {
    for name in ["quad_x", "quad_plus"] {
        for &before in befores {
            let mut w = Worst::default();
            for rotor in 0..4 {
                for seed in 1..=seeds {
                    let c = Case {
                        name,
                        rotor,
                        before,
                        seed,
                        esc_telemetry,
                    };
                    let o = lose_a_rotor(c, params);
                    assert_flown(&c, &o, found_within_s);
                    w.take(&o);
                }
            }
            let esc = if esc_telemetry {
                ""
            } else {
                ", no ESC telemetry"
            };
            w.print(&format!(
                "{name}, {before:?}{esc}, each rotor cut, {seeds} seeds"
            ));
        }
    }
}

/// The case: each rotor of `quad_x` and `quad_plus` cut in turn, five seeds each, on
/// the simulator's `typical` sensors (ESC telemetry at 50 Hz), from a hover at 10 m, 5 m/s
/// forward and a 5 m/s wind with turbulence; `COM_ACT_FAIL_ACT` left at its warning, so the
/// spinning quad's Land flies it down. Found within 0.25 s; the rest is [`assert_flown`].
#[test]
fn a_quad_that_loses_a_rotor_spins_on_three_and_lands() {
    let all = [Before::Hover, Before::Forward, Before::Wind];
    fly_every_rotor(&all, 5, true, &params(), 0.25);
}

/// Without ESC telemetry only the thrust imbalance can tell: a quad's stopping rotor is found
/// within 0.05 s all the same, and every flight meets the same bounds (three seeds).
#[test]
fn without_esc_telemetry_the_imbalance_finds_it_as_fast() {
    let all = [Before::Hover, Before::Forward, Before::Wind];
    fly_every_rotor(&all, 3, false, &params(), 0.05);
}

/// `COM_ACT_FAIL_ACT` 3: a quad hovering 30 m from home that loses a rotor flies the Return on
/// three rotors (the climb to `RTL_RETURN_ALT`, the way home, the landing) and touches down
/// within 3 m of home (three seeds).
#[test]
fn a_quad_on_three_rotors_flies_the_return_home() {
    let mut p = params();
    p.safety.motor_failure_action = 3;
    p.commander.rtl_return_alt_m = RETURN_ALT_M;
    fly_every_rotor(&[Before::Away], 3, true, &p, 0.25);
}
