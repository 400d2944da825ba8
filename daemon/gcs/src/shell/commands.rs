//! The shell's commands, with PX4's names and syntax where PX4 has the command: each turns a
//! line into text, and what changes the vehicle goes to it as the ground station's commands
//! do (answered later in the shell).

use crate::telemetry::Telemetry;
use crate::{AckTo, Delivery, GroundStation, HostAction, Outbox, Reply};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::FlightMode;
use flight_core::params::FlightParams;
use flight_core::safety::failure_injection::Injection;
use mavlink::dialects::common::MavCmd;
use std::fmt::Write;

const HELP: &str = "\
commands:
  help                          this list
  ver                           the autopilot's version
  status                        mode, armed, estimator, sensors, loop timing
  top                           the loop's and the sensors' timing
  param show [PATTERN]          parameters (PATTERN: a name, * any characters)
  param set NAME VALUE          set a parameter (kept in the store)
  commander arm|disarm [-f]     arm, disarm (-f: forced)
  commander takeoff|land|rtl|hold
  commander mode NAME           a PX4 mode name: posctl, mission, auto:loiter, orbit, ...
  failure UNIT TYPE [-i N]      inject a failure (SYS_FAILURE_EN): gyro accel mag baro gps
                                motor; ok off stuck
  listener TOPIC [N]            N samples (5) at 10 Hz: attitude, position, imu, battery
  reboot                        restart the autopilot (disarmed)
";

/// A `listener` printing samples of a live quantity.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Listener {
    topic: Topic,
    left: u32,
    next_s: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Topic {
    Attitude,
    Position,
    Imu,
    Battery,
}

impl Listener {
    /// A sample if one is due at `now_s`, and whether it was the last.
    pub(crate) fn sample(&mut self, now_s: f64, t: &Telemetry) -> (String, bool) {
        if now_s < self.next_s || self.left == 0 {
            return (String::new(), self.left == 0);
        }
        self.next_s = now_s + 0.1;
        self.left -= 1;
        let out = t.estimate();
        let text = match self.topic {
            Topic::Attitude => match out.and_then(|o| o.attitude) {
                Some(a) => {
                    let (r, p, y) = a.q.euler_angles();
                    format!(
                        "attitude t={:.3} roll={:.2} pitch={:.2} yaw={:.2} deg\n",
                        t.link.t_s,
                        r.to_degrees(),
                        p.to_degrees(),
                        y.to_degrees()
                    )
                }
                None => "attitude: no estimate\n".into(),
            },
            Topic::Position => match out.map(|o| o.translation) {
                Some(tr) => format!(
                    "position t={:.3} ned=[{:.2} {:.2} {:.2}] m vel=[{:.2} {:.2} {:.2}] m/s\n",
                    t.link.t_s,
                    tr.pos_ned_m.x,
                    tr.pos_ned_m.y,
                    tr.pos_ned_m.z,
                    tr.vel_ned_m_s.x,
                    tr.vel_ned_m_s.y,
                    tr.vel_ned_m_s.z
                ),
                None => "position: no estimate\n".into(),
            },
            Topic::Imu => match t.vehicle.as_ref().and_then(|v| v.held_sample) {
                Some(s) => format!(
                    "imu t={:.3} gyro=[{:.4} {:.4} {:.4}] rad/s accel=[{:.3} {:.3} {:.3}] m/s^2\n",
                    t.link.t_s, s.gyro.x, s.gyro.y, s.gyro.z, s.accel.x, s.accel.y, s.accel.z
                ),
                None => "imu: no sample\n".into(),
            },
            Topic::Battery => format!(
                "battery t={:.3} {:.2} V remaining {}\n",
                t.link.t_s,
                t.vehicle.as_ref().map_or(0.0, |v| v.battery_v),
                t.vehicle
                    .and_then(|v| v.battery.remaining)
                    .map_or("-".into(), |r| format!("{:.0} %", r * 100.0))
            ),
        };
        (text, self.left == 0)
    }
}

impl GroundStation {
    /// Runs one line; the text to print (a command passed to the vehicle prints its answer
    /// when it comes).
    pub(super) fn run_line(&mut self, line: &str, t: &Telemetry, out: &mut Outbox) -> String {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] => String::new(),
            ["help"] => HELP.into(),
            ["ver", ..] => format!(
                "autopilot {} (Rust), MAVLink 2, PX4 custom modes\n",
                env!("CARGO_PKG_VERSION")
            ),
            ["status"] => status(t, self.sample_rate.hz()),
            ["top"] => top(t, self.sample_rate.hz()),
            ["param", "show"] => self.param_show("*"),
            ["param", "show", pattern] => self.param_show(pattern),
            ["param", "set", name, value] => self.param_set(name, value, out),
            ["commander", rest @ ..] => match commander(rest) {
                Ok(cmd) => self.for_vehicle(cmd, out),
                Err(e) => format!("{e}\n"),
            },
            ["failure", unit, kind, rest @ ..] => match failure(unit, kind, rest) {
                Ok(i) => self.for_vehicle(AutopilotCommand::InjectFailure(i), out),
                Err(e) => format!("{e}\n"),
            },
            ["listener", topic, rest @ ..] => {
                let topic = match *topic {
                    "attitude" | "vehicle_attitude" => Topic::Attitude,
                    "position" | "vehicle_local_position" => Topic::Position,
                    "imu" | "sensor_combined" => Topic::Imu,
                    "battery" | "battery_status" => Topic::Battery,
                    other => return format!("listener: no topic {other}\n"),
                };
                let n = match rest {
                    [] => 5,
                    [n] => match n.parse::<u32>() {
                        Ok(n) if (1..=100).contains(&n) => n,
                        _ => return "listener: N from 1 to 100\n".into(),
                    },
                    _ => return "usage: listener TOPIC [N]\n".into(),
                };
                self.shell.listener = Some(Listener {
                    topic,
                    left: n,
                    next_s: 0.0,
                });
                String::new()
            }
            ["reboot"] => {
                if t.status().is_some_and(|s| s.armed) {
                    return "reboot refused: armed\n".into();
                }
                if !self.reboot_allowed {
                    return "reboot refused: not allowed here\n".into();
                }
                out.actions.push(HostAction::Reboot);
                "rebooting\n".into()
            }
            [other, ..] => format!("{other}: command not found (help lists them)\n"),
        }
    }

    /// A command for the vehicle, its answer printed in the shell (the prompt after it).
    fn for_vehicle(&mut self, cmd: AutopilotCommand, out: &mut Outbox) -> String {
        let Some((_, system, component)) = self.shell.peer else {
            return String::new();
        };
        let to = AckTo {
            command: MavCmd::MAV_CMD_USER_1,
            system,
            component,
            reply: Reply::Shell,
        };
        out.request(cmd, Delivery::Answered(to));
        self.shell.pending = true;
        String::new()
    }

    fn param_show(&self, pattern: &str) -> String {
        let values = self.params.values();
        let mut text = String::new();
        let mut n = 0;
        for (_, m) in FlightParams::metadata().filter(|(_, m)| matches(pattern, m.name)) {
            let v = values.value(m.name).unwrap_or(f64::NAN);
            let _ = writeln!(text, "{:<18} {v}", m.name);
            n += 1;
        }
        let _ = writeln!(text, "{n} parameters");
        text
    }

    fn param_set(&mut self, name: &str, value: &str, out: &mut Outbox) -> String {
        let upper = name.to_ascii_uppercase();
        let Ok(v) = value.parse::<f64>() else {
            return format!("param set: {value} is not a number\n");
        };
        match self.params.set_many(&[(upper.as_str(), v)], out) {
            Ok(()) => {
                out.actions.push(HostAction::ParamsChanged);
                out.actions.push(HostAction::SaveParams);
                format!("{upper} = {v}\n")
            }
            Err(e) => format!("param set: {e}\n"),
        }
    }
}

/// Whether `name` matches `pattern` (`*`: any characters; case-insensitive).
fn matches(pattern: &str, name: &str) -> bool {
    let (p, n) = (pattern.to_ascii_uppercase(), name.to_ascii_uppercase());
    let (p, n) = (p.as_bytes(), n.as_bytes());
    // The greedy wildcard match: back to the last star on a mismatch.
    let (mut i, mut j, mut star, mut mark) = (0, 0, None, 0);
    while j < n.len() {
        if i < p.len() && p[i] == n[j] {
            (i, j) = (i + 1, j + 1);
        } else if i < p.len() && p[i] == b'*' {
            (star, mark, i) = (Some(i), j, i + 1);
        } else if let Some(s) = star {
            (i, mark) = (s + 1, mark + 1);
            j = mark;
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == b'*')
}

/// What the shell cannot run, in its answer's words.
#[derive(Debug, thiserror::Error)]
enum Unrunnable {
    #[error("usage: commander arm|disarm [-f] | takeoff|land|rtl|hold | mode NAME")]
    CommanderUsage,
    #[error("commander: no mode {0}")]
    NoMode(String),
    #[error("usage: failure UNIT TYPE [-i N]")]
    FailureUsage,
    #[error("failure: no unit {0}")]
    NoUnit(String),
    #[error("failure: no type {0}")]
    NoType(String),
    #[error("failure: instance {0}")]
    NoInstance(String),
    #[error("failure: {0}")]
    Injection(#[from] flight_core::safety::failure_injection::Refusal),
}

/// `commander …`, as PX4's.
fn commander(args: &[&str]) -> Result<AutopilotCommand, Unrunnable> {
    Ok(match args {
        ["arm"] => AutopilotCommand::Arm { force: false },
        ["arm", "-f"] => AutopilotCommand::Arm { force: true },
        ["disarm"] => AutopilotCommand::Disarm { force: false },
        ["disarm", "-f"] => AutopilotCommand::Disarm { force: true },
        ["takeoff"] => AutopilotCommand::Takeoff(None),
        ["land"] => AutopilotCommand::SetMode(FlightMode::Land),
        ["rtl"] => AutopilotCommand::SetMode(FlightMode::Rtl),
        ["hold"] => AutopilotCommand::SetMode(FlightMode::Loiter),
        ["mode", name] => AutopilotCommand::SetMode(mode(name)?),
        _ => return Err(Unrunnable::CommanderUsage),
    })
}

/// A mode by PX4's `commander mode` name.
fn mode(name: &str) -> Result<FlightMode, Unrunnable> {
    Ok(match name.to_ascii_lowercase().as_str() {
        "manual" => FlightMode::Manual,
        "stabilized" => FlightMode::Stabilized,
        "altctl" => FlightMode::Altctl,
        "posctl" => FlightMode::Posctl,
        "orbit" | "posctl:orbit" => FlightMode::Orbit,
        "offboard" => FlightMode::Offboard,
        "auto:mission" | "mission" => FlightMode::Mission,
        "auto:loiter" | "loiter" | "hold" => FlightMode::Loiter,
        "auto:rtl" | "rtl" => FlightMode::Rtl,
        "auto:takeoff" | "takeoff" => FlightMode::Takeoff,
        "auto:land" | "land" => FlightMode::Land,
        "auto:follow_target" | "follow_target" => FlightMode::FollowTarget,
        other => return Err(Unrunnable::NoMode(other.into())),
    })
}

/// `failure UNIT TYPE [-i N]`, as PX4's.
fn failure(unit: &str, kind: &str, rest: &[&str]) -> Result<Injection, Unrunnable> {
    let unit = match unit {
        "gyro" => 0.0,
        "accel" => 1.0,
        "mag" => 2.0,
        "baro" => 3.0,
        "gps" => 4.0,
        "motor" => 101.0,
        other => return Err(Unrunnable::NoUnit(other.into())),
    };
    let kind = match kind {
        "ok" => 0.0,
        "off" => 1.0,
        "stuck" => 2.0,
        other => return Err(Unrunnable::NoType(other.into())),
    };
    let instance = match rest {
        [] => 0.0,
        ["-i", n] => n
            .parse::<u8>()
            .map_err(|_| Unrunnable::NoInstance((*n).into()))?
            .into(),
        _ => return Err(Unrunnable::FailureUsage),
    };
    Ok(Injection::decode(unit, kind, instance)?)
}

fn status(t: &Telemetry, sample_hz: Option<f64>) -> String {
    let mut text = String::new();
    match t.status() {
        Some(s) => {
            let _ = writeln!(
                text,
                "mode: {}  armed: {}  landed: {:?}  failsafe: {}",
                s.mode.name(),
                if s.armed { "yes" } else { "no" },
                s.landed,
                s.failsafe_action
                    .map_or("none".into(), |(a, c)| format!("{a:?} ({c:?})"))
            );
        }
        None => text.push_str("mode: - (no sensor data yet)\n"),
    }
    match t.estimate() {
        Some(o) => {
            let tr = o.translation;
            let _ = writeln!(
                text,
                "estimator: attitude {}  horizontal {}  vertical {}",
                if o.attitude.is_some_and(|a| a.valid) {
                    "valid"
                } else {
                    "not valid"
                },
                if tr.horizontal_valid {
                    "valid"
                } else {
                    "not valid"
                },
                if tr.vertical_valid {
                    "valid"
                } else {
                    "not valid"
                }
            );
        }
        None => text.push_str("estimator: not running\n"),
    }
    text.push_str(&top(t, sample_hz));
    text
}

fn top(t: &Telemetry, sample_hz: Option<f64>) -> String {
    let mut text = format!(
        "sensors: {} frames, {} Hz, {}\n",
        t.link.frames,
        sample_hz.map_or("-".into(), |h| format!("{h:.1}")),
        if t.link.sensors_silent {
            "SILENT"
        } else {
            "arriving"
        }
    );
    let _ = match t.link.loop_stats {
        Some(l) => writeln!(
            text,
            "loop: {} ticks; jitter p50 {} us, p99 {} us, max {} us; work max {} us; overruns {}",
            l.ticks, l.jitter_p50_us, l.jitter_p99_us, l.jitter_max_us, l.work_max_us, l.overruns
        ),
        None => writeln!(text, "loop: lockstep (one step per sensor frame)"),
    };
    text
}
