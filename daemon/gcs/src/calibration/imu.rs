//! The gyro, accelerometer and level-horizon calibrations said as PX4 says them: `[cal]
//! calibration started: 2 gyro|accel|level`, `[cal] progress <N>` (0–100: MAVSDK takes a
//! number above 100 for an instruction), the six-side texts QGroundControl follows (`[cal]
//! pending: back front left right up down`, `[cal] <side> orientation detected`, `[cal] <side>
//! side done, rotate to a different side`, `[cal] <side> side already completed`, `[cal]
//! detected motion, hold still...`), and the end. A result becomes `CAL_GYRO0_*`,
//! `CAL_ACC0_*` or `SENS_BOARD_X_OFF`/`Y_OFF`, flown at once and saved.

use super::super::{GroundStation, Outbox};
use crate::telemetry::Telemetry;
use flight_core::sensors::imu_calibrator::{
    ImuCalKind, ImuCalResult, ImuCalState, ImuCalStatus, Side,
};
use mavlink::dialects::common::MavSeverity;

/// What has been said of an IMU calibration run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(in crate::calibration) struct Said {
    run: u32,
    percent: u8,
    sides_done: u8,
    measuring: Option<Side>,
    restarts: u16,
    repeated: u16,
    ended: bool,
}

/// The sides not done, as PX4 lists them (`" back front …"`).
fn pending(done: u8) -> String {
    Side::ALL
        .iter()
        .filter(|s| done & s.bit() == 0)
        .map(|s| format!(" {}", s.name()))
        .collect()
}

impl GroundStation {
    /// Says what changed in the IMU calibration `t` shows since the last call.
    pub(in crate::calibration) fn report_imu_calibration(
        &mut self,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let Some(s) = t.vehicle.as_ref().and_then(|v| v.imu_cal) else {
            return;
        };
        let info = MavSeverity::MAV_SEVERITY_INFO;
        let kind = s.kind.name();
        let said = &mut self.cal_said.imu;
        if s.run != said.run {
            *said = Said {
                run: s.run,
                ..Said::default()
            };
            out.say(info, &format!("[cal] calibration started: 2 {kind}"));
            match s.kind {
                ImuCalKind::Accel => {
                    out.say(info, &format!("[cal] pending:{}", pending(0)));
                    out.say(info, "[cal] hold vehicle still on a pending side");
                }
                ImuCalKind::Level => {
                    out.say(info, "[cal] put the vehicle on a level surface, hold still")
                }
                ImuCalKind::Gyro => out.say(info, "[cal] hold the vehicle still"),
            }
        }
        if said.ended {
            return;
        }
        if s.restarts > said.restarts {
            // The first, then every fifth: a hand that keeps moving is told, not flooded.
            if said.restarts == 0 || s.restarts / 5 > said.restarts / 5 {
                out.say(info, "[cal] detected motion, hold still...");
            }
            said.restarts = s.restarts;
        }
        if s.repeated.0 > said.repeated {
            said.repeated = s.repeated.0;
            if let Some(side) = s.repeated.1 {
                out.say(
                    info,
                    &format!("[cal] {} side already completed", side.name()),
                );
            }
        }
        if s.measuring != said.measuring {
            said.measuring = s.measuring;
            if let Some(side) = s.measuring {
                out.say(info, &format!("[cal] {} orientation detected", side.name()));
                out.say(
                    info,
                    &format!("[cal] Hold still, measuring {} side", side.name()),
                );
            }
        }
        let new_sides = s.sides_done & !said.sides_done;
        for side in Side::ALL
            .into_iter()
            .filter(|side| new_sides & side.bit() != 0)
        {
            out.say(
                info,
                &format!(
                    "[cal] {} side done, rotate to a different side",
                    side.name()
                ),
            );
        }
        said.sides_done = s.sides_done;
        // Progress in steps of 10 % (each side for the accelerometer); 100 with the result.
        let step = s.percent / 10 * 10;
        if s.percent < 100 && (step > said.percent || (new_sides != 0 && s.percent > said.percent))
        {
            said.percent = s.percent;
            out.say(info, &format!("[cal] progress <{}>", s.percent));
        }
        if new_sides != 0 && s.state == ImuCalState::Collecting {
            out.say(info, &format!("[cal] pending:{}", pending(s.sides_done)));
        }
        match s.state {
            ImuCalState::Collecting => return,
            ImuCalState::Succeeded(r) => self.imu_calibrated(&s, &r, out),
            ImuCalState::Failed(f) => out.say(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                &format!("[cal] calibration failed: {kind}: {f}"),
            ),
            ImuCalState::Cancelled => out.say(info, "[cal] calibration cancelled"),
        }
        self.cal_said.imu.ended = true;
    }

    /// A calibration's result becomes its parameters, flown and saved.
    fn imu_calibrated(&mut self, s: &ImuCalStatus, r: &ImuCalResult, out: &mut Outbox) {
        let imu = self.params.values().imu;
        let id = |id: u32| if id == 0 { 1.0 } else { f64::from(id) };
        let values: Vec<(&str, f64)> = match *r {
            ImuCalResult::Gyro { offset: o } => vec![
                ("CAL_GYRO0_XOFF", o.x),
                ("CAL_GYRO0_YOFF", o.y),
                ("CAL_GYRO0_ZOFF", o.z),
                ("CAL_GYRO0_ID", id(imu.gyro_id)),
            ],
            ImuCalResult::Accel {
                offset: o,
                scale: k,
            } => vec![
                ("CAL_ACC0_XOFF", o.x),
                ("CAL_ACC0_YOFF", o.y),
                ("CAL_ACC0_ZOFF", o.z),
                ("CAL_ACC0_XSCALE", k.x),
                ("CAL_ACC0_YSCALE", k.y),
                ("CAL_ACC0_ZSCALE", k.z),
                ("CAL_ACC0_ID", id(imu.accel_id)),
            ],
            ImuCalResult::Level {
                roll_deg,
                pitch_deg,
            } => vec![
                ("SENS_BOARD_X_OFF", roll_deg),
                ("SENS_BOARD_Y_OFF", pitch_deg),
            ],
        };
        let kind = s.kind.name();
        if let Err(e) = self.set_calibration(kind, &values, out) {
            out.say(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                &format!("[cal] calibration failed: {kind}: {e}"),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::super::super::tests::{statustexts, telemetry};
    use super::*;
    use flight_core::commander::FlightMode;
    use flight_core::sensors::imu_calibrator::ImuCalFailure;
    use mavlink::dialects::common::MavType;
    use nalgebra::Vector3;

    fn poll(g: &mut GroundStation, s: ImuCalStatus) -> Vec<String> {
        let mut t = telemetry(false, FlightMode::Loiter);
        t.vehicle.as_mut().unwrap().imu_cal = Some(s);
        let mut out = Outbox::default();
        g.report_calibration(&t, &mut out);
        statustexts(&out)
    }

    fn accel(run: u32) -> ImuCalStatus {
        ImuCalStatus::new(run, ImuCalKind::Accel)
    }

    /// PX4's six-side texts, each once, in order, and the result in `CAL_ACC0_*`.
    #[test]
    fn the_six_sides_are_said_as_px4_says_them_and_the_result_is_flown() {
        let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
        assert_eq!(
            poll(&mut g, accel(4)),
            [
                "[cal] calibration started: 2 accel",
                "[cal] pending: back front left right up down",
                "[cal] hold vehicle still on a pending side",
            ]
        );
        let measuring = ImuCalStatus {
            measuring: Some(Side::Down),
            ..accel(4)
        };
        assert_eq!(
            poll(&mut g, measuring),
            [
                "[cal] down orientation detected",
                "[cal] Hold still, measuring down side"
            ]
        );
        assert!(poll(&mut g, measuring).is_empty(), "said once");
        let done = ImuCalStatus {
            sides_done: Side::Down.bit(),
            percent: 17,
            repeated: (1, Some(Side::Down)),
            restarts: 1,
            ..accel(4)
        };
        assert_eq!(
            poll(&mut g, done),
            [
                "[cal] detected motion, hold still...",
                "[cal] down side already completed",
                "[cal] down side done, rotate to a different side",
                "[cal] progress <17>",
                "[cal] pending: back front left right up",
            ]
        );
        let result = ImuCalResult::Accel {
            offset: Vector3::new(0.25, -0.5, 0.125),
            scale: Vector3::new(1.0, 0.75 + 0.25, 1.0),
        };
        let texts = poll(
            &mut g,
            ImuCalStatus {
                state: ImuCalState::Succeeded(result),
                sides_done: 0b11_1111,
                percent: 100,
                ..done
            },
        );
        assert!(
            texts.ends_with(&[
                "[cal] progress <100>".into(),
                "[cal] calibration done: accel".into()
            ]),
            "{texts:?}"
        );
        let imu = g.parameters().values().imu;
        assert_eq!(
            (imu.accel_offset_x, imu.accel_offset_y, imu.accel_id),
            (0.25, -0.5, 1)
        );
        // A failure and a cancel, each said once with its reason.
        let failed = ImuCalStatus {
            kind: ImuCalKind::Gyro,
            state: ImuCalState::Failed(ImuCalFailure::Motion(21)),
            ..accel(5)
        };
        let texts = poll(&mut g, failed).concat();
        assert!(
            texts.starts_with("[cal] calibration started: 2 gyro"),
            "{texts}"
        );
        assert!(texts.ends_with("[cal] calibration failed: gyro: motion during calibration (21 restarts), hold it still"), "{texts}");
        assert!(poll(&mut g, failed).is_empty());
    }
}
