//! A scenario's events checked and made into the simulator's: each at its time, and, for one
//! that lasts (`duration_s`), the event that undoes it.

use super::EventFile;
use crate::sensors::{SensorHealth, SensorKind};
use crate::sim::{Event, SimAction};
use ::airframe::config::Checker;
use nalgebra::Vector3;

/// Event `i` of the file checked into `c` and added to `out`: its action, then the one that
/// ends it when it lasts.
pub(super) fn resolve_event(c: &mut Checker, i: usize, e: &EventFile, out: &mut Vec<Event>) {
    let key = format!("events[{i}]");
    let (t_s, action) = action_of(c, &key, e);
    out.push(Event { t_s, action });
    if let Some((d, undo)) = undo_of(e) {
        c.positive(format!("{key}.duration_s"), d);
        out.push(Event {
            t_s: t_s + d,
            action: undo,
        });
    }
    c.non_negative(format!("{key}.t_s"), t_s);
}

/// The event's time and action, its values checked into `c` under `key`.
fn action_of(c: &mut Checker, key: &str, e: &EventFile) -> (f64, SimAction) {
    match e {
        EventFile::MotorFail { t_s, motor } => {
            let index = motor.saturating_sub(1);
            (*t_s, SimAction::MotorFail { index })
        }
        EventFile::MotorThrust {
            t_s,
            motor,
            effectiveness,
        } => {
            c.within(format!("{key}.effectiveness"), *effectiveness, 0.0, 1.0);
            let action = SimAction::MotorEffectiveness {
                index: motor.saturating_sub(1),
                effectiveness: *effectiveness,
            };
            (*t_s, action)
        }
        EventFile::MotorRestore { t_s, motor } => {
            let index = motor.saturating_sub(1);
            (*t_s, SimAction::MotorRestore { index })
        }
        EventFile::SensorOff { t_s, sensor, .. } => (*t_s, health(*sensor, SensorHealth::Off)),
        EventFile::SensorStuck { t_s, sensor, .. } => (*t_s, health(*sensor, SensorHealth::Stuck)),
        EventFile::GpsFixLoss { t_s, .. } => (*t_s, SimAction::GpsFixLost(true)),
        EventFile::MagDisturbance {
            t_s,
            field_ned_gauss,
            ..
        } => {
            c.finite(format!("{key}.field_ned_gauss"), field_ned_gauss);
            let field = Vector3::from(*field_ned_gauss);
            (*t_s, SimAction::MagDisturbance(field))
        }
        EventFile::ForcePulse {
            t_s,
            force_ned_n: v,
            duration_s: d,
        } => {
            let (force_ned_n, duration_s) = pulse(c, key, "force_ned_n", v, *d);
            let action = SimAction::ForcePulse {
                force_ned_n,
                duration_s,
            };
            (*t_s, action)
        }
        EventFile::TorquePulse {
            t_s,
            torque_frd_n_m: v,
            duration_s: d,
        } => {
            let (torque_frd_n_m, duration_s) = pulse(c, key, "torque_frd_n_m", v, *d);
            let action = SimAction::TorquePulse {
                torque_frd_n_m,
                duration_s,
            };
            (*t_s, action)
        }
        EventFile::Gust {
            t_s,
            peak_ned_m_s: v,
            duration_s: d,
        } => {
            let (peak_ned_m_s, duration_s) = pulse(c, key, "peak_ned_m_s", v, *d);
            let action = SimAction::Gust {
                peak_ned_m_s,
                duration_s,
            };
            (*t_s, action)
        }
        EventFile::Wind {
            t_s,
            mean_ned_m_s,
            turbulence_w20_m_s,
        } => (*t_s, wind(c, key, mean_ned_m_s, *turbulence_w20_m_s)),
        EventFile::Tumble { t_s, duration_s } => {
            c.positive(format!("{key}.duration_s"), *duration_s);
            let duration_s = *duration_s;
            (*t_s, SimAction::Tumble { duration_s })
        }
    }
}

/// What ends an event that lasts: after how long (s), and the action.
fn undo_of(e: &EventFile) -> Option<(f64, SimAction)> {
    match e {
        EventFile::SensorOff {
            sensor, duration_s, ..
        }
        | EventFile::SensorStuck {
            sensor, duration_s, ..
        } => duration_s.map(|d| (d, health(*sensor, SensorHealth::Ok))),
        EventFile::GpsFixLoss { duration_s, .. } => {
            duration_s.map(|d| (d, SimAction::GpsFixLost(false)))
        }
        EventFile::MagDisturbance { duration_s, .. } => {
            duration_s.map(|d| (d, SimAction::MagDisturbance(Vector3::zeros())))
        }
        _ => None,
    }
}

/// A sensor put in `health`.
fn health(sensor: SensorKind, health: SensorHealth) -> SimAction {
    SimAction::Sensor { sensor, health }
}

/// A pulse's or gust's vector (`name`) and duration, checked into `c`.
fn pulse(
    c: &mut Checker,
    key: &str,
    name: &str,
    v: &[f64; 3],
    duration_s: f64,
) -> (Vector3<f64>, f64) {
    c.finite(format!("{key}.{name}"), v);
    c.positive(format!("{key}.duration_s"), duration_s);
    (Vector3::from(*v), duration_s)
}

/// A change of the wind, its values checked into `c`.
fn wind(c: &mut Checker, key: &str, mean_ned_m_s: &[f64; 3], turbulence: f64) -> SimAction {
    c.finite(format!("{key}.mean_ned_m_s"), mean_ned_m_s);
    c.within(format!("{key}.turbulence_w20_m_s"), turbulence, 0.0, 40.0);
    SimAction::Wind {
        mean_ned_m_s: Vector3::from(*mean_ned_m_s),
        turbulence_w20_m_s: turbulence,
    }
}
