//! Onboard calibration on MAVLink, as PX4 speaks it: `MAV_CMD_PREFLIGHT_CALIBRATION` starts
//! one (`commands/preflight.rs`; every param 0 cancels one), acknowledged when the control loop
//! has started it; progress and the end are `STATUSTEXT`s in the `[cal]` words QGroundControl
//! and MAVSDK's calibration plugin parse (`[cal] calibration started: 2 mag`, `[cal] progress
//! <N>`, `[cal] calibration done: mag`, `[cal] calibration failed: …`, `[cal] calibration
//! cancelled`; any other `[cal]` text is an instruction). This file says the magnetometer's,
//! whose result is also a `MAG_CAL_REPORT`; [`imu`] the gyro's, the accelerometer's and the
//! level horizon's. A calibration that succeeds becomes its parameters — here
//! `CAL_MAG0_XOFF`…`ZOFF`, `CAL_MAG0_XSCALE`…, `CAL_MAG0_XODIAG`… and `CAL_MAG0_ID` — all
//! together, each announced in `PARAM_VALUE`, flown at once and saved to the parameter store.

use super::{GroundStation, HostAction, Outbox};
use crate::telemetry::Telemetry;
use flight_core::sensors::mag_calibrator::{MagCalFailure, MagCalResult, MagCalState};
use mavlink::dialects::common::*;

/// The calibration protocol's version in its start message (QGroundControl checks it).
const STARTED: &str = "[cal] calibration started: 2 mag";

mod imu;

/// What has been said of a calibration run: its number, the progress shown, whether its end was.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Shown {
    run: u32,
    percent: u8,
    ended: bool,
}

/// What has been said of the calibrations.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Said {
    mag: Shown,
    imu: imu::Said,
}

impl GroundStation {
    /// Says what changed in the calibrations `t` shows since the last call.
    pub(super) fn report_calibration(&mut self, t: &Telemetry, out: &mut Outbox) {
        self.report_mag_calibration(t, out);
        self.report_imu_calibration(t, out);
    }

    /// Says what changed in the magnetometer calibration.
    fn report_mag_calibration(&mut self, t: &Telemetry, out: &mut Outbox) {
        let Some(s) = t.vehicle.as_ref().and_then(|v| v.mag_cal) else {
            return;
        };
        let info = MavSeverity::MAV_SEVERITY_INFO;
        if s.run != self.cal_said.mag.run {
            self.cal_said.mag = Shown {
                run: s.run,
                ..Shown::default()
            };
            out.say(info, STARTED);
            out.say(info, "[cal] Rotate the vehicle through every orientation");
        }
        if self.cal_said.mag.ended {
            return;
        }
        if s.percent > self.cal_said.mag.percent && s.state == MagCalState::Collecting {
            self.cal_said.mag.percent = s.percent;
            out.say(info, &format!("[cal] progress <{}>", s.percent));
        }
        match s.state {
            MagCalState::Collecting => return,
            MagCalState::Succeeded(r) => self.calibrated(&r, out),
            MagCalState::Failed(f) => {
                out.say(
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &format!("[cal] calibration failed: {f}"),
                );
                out.send(report(None, failure_status(&f), 0.0));
            }
            MagCalState::Cancelled => out.say(info, "[cal] calibration cancelled"),
        }
        self.cal_said.mag.ended = true;
    }

    /// A calibration's result `values` become their parameters, all or none — each as a float
    /// parameter travels (what a ground station reads back is what is flown), the `_ID`s as
    /// integers — flown, saved, and the end said (`[cal] progress <100>`, `[cal] calibration
    /// done: <kind>`); a refusal is the caller's to say.
    fn set_calibration(
        &mut self,
        kind: &str,
        values: &[(&str, f64)],
        out: &mut Outbox,
    ) -> Result<(), flight_core::params::ParamRejection> {
        let values: Vec<(&str, f64)> = values
            .iter()
            .map(|&(n, v)| {
                (
                    n,
                    if n.ends_with("_ID") {
                        v
                    } else {
                        v as f32 as f64
                    },
                )
            })
            .collect();
        self.params.set_many(&values, out)?;
        out.actions.push(HostAction::ParamsChanged);
        out.actions.push(HostAction::SaveParams);
        out.say(MavSeverity::MAV_SEVERITY_INFO, "[cal] progress <100>");
        let done = format!("[cal] calibration done: {kind}");
        out.say(MavSeverity::MAV_SEVERITY_INFO, &done);
        Ok(())
    }

    /// A calibration's result becomes the parameters, flown and saved.
    fn calibrated(&mut self, r: &MagCalResult, out: &mut Outbox) {
        let values = self.params.values();
        let strength = values.attitude.mag_intensity_gauss;
        let id = match values.attitude.mag_calibration_id {
            0 => 1.0,
            id => id as f64,
        };
        let c = &r.correction;
        let names = [
            ("CAL_MAG0_XOFF", r.offset.x),
            ("CAL_MAG0_YOFF", r.offset.y),
            ("CAL_MAG0_ZOFF", r.offset.z),
            ("CAL_MAG0_XSCALE", c[(0, 0)]),
            ("CAL_MAG0_YSCALE", c[(1, 1)]),
            ("CAL_MAG0_ZSCALE", c[(2, 2)]),
            ("CAL_MAG0_XODIAG", c[(0, 1)]),
            ("CAL_MAG0_YODIAG", c[(0, 2)]),
            ("CAL_MAG0_ZODIAG", c[(1, 2)]),
            ("CAL_MAG0_ID", id),
        ];
        match self.set_calibration("mag", &names, out) {
            Ok(()) => {
                let fitness_mg = r.residual_rms * strength * 1000.0;
                out.send(report(Some(r), MagCalStatus::MAG_CAL_SUCCESS, fitness_mg));
            }
            Err(e) => {
                out.say(
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &format!("[cal] calibration failed: {e}"),
                );
                out.send(report(None, MagCalStatus::MAG_CAL_FAILED, 0.0));
            }
        }
    }
}

fn failure_status(f: &MagCalFailure) -> MagCalStatus {
    match f {
        MagCalFailure::ResidualTooHigh { .. } => MagCalStatus::MAG_CAL_FAILED_RESIDUALS_HIGH,
        MagCalFailure::OutOfRange => MagCalStatus::MAG_CAL_FAILED_OFFSETS,
        _ => MagCalStatus::MAG_CAL_FAILED,
    }
}

/// `MAG_CAL_REPORT`: the result if the calibration succeeded (then saved to the store).
fn report(r: Option<&MagCalResult>, status: MagCalStatus, fitness_mg: f64) -> MavMessage {
    let (o, c) = r.map_or((Default::default(), Default::default()), |r| {
        (r.offset, r.correction)
    });
    MavMessage::MAG_CAL_REPORT(MAG_CAL_REPORT_DATA {
        fitness: fitness_mg as f32,
        ofs_x: o.x as f32,
        ofs_y: o.y as f32,
        ofs_z: o.z as f32,
        diag_x: c[(0, 0)] as f32,
        diag_y: c[(1, 1)] as f32,
        diag_z: c[(2, 2)] as f32,
        offdiag_x: c[(0, 1)] as f32,
        offdiag_y: c[(0, 2)] as f32,
        offdiag_z: c[(1, 2)] as f32,
        compass_id: 0,
        cal_mask: 1,
        cal_status: status,
        autosaved: r.is_some() as u8,
        orientation_confidence: 0.0,
        old_orientation: MavSensorOrientation::MAV_SENSOR_ROTATION_NONE,
        new_orientation: MavSensorOrientation::MAV_SENSOR_ROTATION_NONE,
        // The overall scale the correction applies: the cube root of its determinant.
        scale_factor: c.determinant().cbrt() as f32,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::super::tests::{
        acks, command_long, gcs_header, param_values, statustexts, telemetry,
    };
    use super::super::{AutopilotCommand, Outgoing};
    use super::*;
    use flight_core::commander::FlightMode;
    use flight_core::sensors::imu_calibrator::ImuCalKind;
    use flight_core::sensors::mag_calibrator::MagCalStatus as Progress;
    use nalgebra::{Matrix3, Vector3};

    fn command(g: &mut GroundStation, p: [f32; 7]) -> Outbox {
        let mut out = Outbox::default();
        let t = telemetry(false, FlightMode::Loiter);
        let c = command_long(MavCmd::MAV_CMD_PREFLIGHT_CALIBRATION, p, (1, 1));
        g.on_message(&gcs_header(), &c, &t, &mut out);
        out
    }

    #[test]
    fn each_calibration_is_started_on_command_and_all_zeros_cancel() {
        let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
        let out = command(&mut g, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            crate::testing::requested(&out)[0].0,
            AutopilotCommand::CalibrateMag
        );
        // As MAVSDK sends it: the reserved params 6 and 7 NaN.
        let out = command(&mut g, [0.0, 1.0, 0.0, 0.0, 0.0, f32::NAN, f32::NAN]);
        assert_eq!(
            crate::testing::requested(&out)[0].0,
            AutopilotCommand::CalibrateMag
        );
        assert!(
            acks(&out).is_empty(),
            "acknowledged when the control loop has started it"
        );
        let out = command(&mut g, [0.0; 7]);
        assert_eq!(
            crate::testing::requested(&out)[0].0,
            AutopilotCommand::CancelCalibration
        );
        // QGroundControl's radio setup: param4 1, RC input off until every param is 0.
        let out = command(&mut g, [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            crate::testing::requested(&out)[0].0,
            AutopilotCommand::CalibrateRadio
        );
        // As MAVSDK asks for the others: gyro param1 1, accelerometer param5 1, level param5 2.
        for (p, kind) in [
            (
                [1.0, 0.0, 0.0, 0.0, 0.0, f32::NAN, f32::NAN],
                ImuCalKind::Gyro,
            ),
            (
                [0.0, 0.0, 0.0, 0.0, 1.0, f32::NAN, f32::NAN],
                ImuCalKind::Accel,
            ),
            (
                [0.0, 0.0, 0.0, 0.0, 2.0, f32::NAN, f32::NAN],
                ImuCalKind::Level,
            ),
        ] {
            let out = command(&mut g, p);
            assert_eq!(
                crate::testing::requested(&out)[0].0,
                AutopilotCommand::CalibrateImu(kind)
            );
        }
        // Two at once, the barometer, a quick accelerometer: refused, said why.
        for (p, why) in [
            ([0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0], "one at a time"),
            (
                [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
                "param3 = 1 is not calibrated onboard",
            ),
            (
                [0.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0],
                "param5 = 4 is not calibrated onboard",
            ),
        ] {
            let out = command(&mut g, p);
            assert!(crate::testing::requested(&out).is_empty());
            assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_UNSUPPORTED);
            assert!(statustexts(&out).concat().contains(why), "{why}");
        }
    }

    fn poll(g: &mut GroundStation, cal: Progress) -> Outbox {
        let mut t = telemetry(false, FlightMode::Loiter);
        t.vehicle.as_mut().unwrap().mag_cal = Some(cal);
        let mut out = Outbox::default();
        g.report_calibration(&t, &mut out);
        out
    }

    fn collecting(run: u32, percent: u8) -> Progress {
        Progress {
            run,
            state: MagCalState::Collecting,
            percent,
            covered: 26 * percent as usize / 100,
            samples: 10 * percent as usize,
        }
    }

    /// PX4's `[cal]` texts in order, each once; the result in the parameters (all ten
    /// announced), flown and saved, and in `MAG_CAL_REPORT`.
    #[test]
    fn progress_and_the_result_are_said_once_and_the_result_becomes_the_parameters() {
        let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
        let out = poll(&mut g, collecting(1, 0));
        assert_eq!(
            statustexts(&out),
            [
                STARTED,
                "[cal] Rotate the vehicle through every orientation"
            ]
        );
        assert_eq!(
            statustexts(&poll(&mut g, collecting(1, 38))),
            ["[cal] progress <38>"]
        );
        assert!(poll(&mut g, collecting(1, 38)).messages.is_empty());
        let soft = Matrix3::new(0.93, -0.04, 0.02, -0.04, 1.05, -0.03, 0.02, -0.03, 0.98);
        let result = MagCalResult {
            offset: Vector3::new(0.12, -0.08, 0.2),
            correction: soft,
            residual_rms: 0.016,
            coverage: 26,
            samples: 1500,
        };
        let done = Progress {
            state: MagCalState::Succeeded(result),
            percent: 100,
            ..collecting(1, 100)
        };
        let out = poll(&mut g, done);
        assert_eq!(
            statustexts(&out),
            ["[cal] progress <100>", "[cal] calibration done: mag"]
        );
        let p = &g.parameters().values().attitude;
        assert_eq!(
            p.mag_offset,
            [0.12f32 as f64, -0.08f32 as f64, 0.2f32 as f64]
        );
        assert!((p.mag_correction() - soft).norm() < 1e-6);
        assert_eq!(p.mag_calibration_id, 1, "0 before: the first device");
        let names: Vec<String> = param_values(&out)
            .iter()
            .map(|v| v.param_id.to_str().unwrap().to_owned())
            .collect();
        assert_eq!(names.len(), 10);
        assert!(
            names.iter().all(|n| n.starts_with("CAL_MAG0_")),
            "{names:?}"
        );
        assert_eq!(
            out.actions,
            [HostAction::ParamsChanged, HostAction::SaveParams]
        );
        let stored: Vec<&str> = g.parameters().store().names().collect();
        assert!(stored.contains(&"CAL_MAG0_XODIAG"), "{stored:?}");
        let report = out.messages.iter().find_map(|m| match m {
            Outgoing::Message(MavMessage::MAG_CAL_REPORT(r)) => Some(r),
            _ => None,
        });
        let r = report.unwrap();
        assert_eq!(r.cal_status, MagCalStatus::MAG_CAL_SUCCESS);
        assert_eq!((r.ofs_x, r.diag_y, r.offdiag_z), (0.12, 1.05, -0.03));
        assert!(
            (r.fitness - 7.68).abs() < 0.01,
            "RMS residual in mG: {}",
            r.fitness
        );
        assert_eq!(r.autosaved, 1);
        // Said once: the telemetry keeps showing the ended run.
        assert!(poll(&mut g, done).messages.is_empty());
    }

    #[test]
    fn a_failure_and_a_cancel_are_said_and_change_no_parameter() {
        let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
        let before = g.parameters().clone();
        // A run first seen ended (the poll missed its start): started, then its end.
        let failed = Progress {
            state: MagCalState::Failed(MagCalFailure::TimedOut { covered: 12 }),
            ..collecting(2, 46)
        };
        let out = poll(&mut g, failed);
        let texts = statustexts(&out);
        assert_eq!(texts[0], STARTED);
        // Longer than a STATUSTEXT: in chunks that reassemble.
        assert!(
            texts
                .concat()
                .ends_with("[cal] calibration failed: timed out, 12 of 26 directions seen"),
            "{texts:?}"
        );
        assert!(out.messages.iter().any(|m| matches!(
            m,
            Outgoing::Message(MavMessage::MAG_CAL_REPORT(r))
                if r.cal_status == MagCalStatus::MAG_CAL_FAILED && r.autosaved == 0
        )));
        let cancelled = Progress {
            state: MagCalState::Cancelled,
            ..collecting(3, 20)
        };
        let texts = statustexts(&poll(&mut g, cancelled));
        assert_eq!(texts.last().unwrap(), "[cal] calibration cancelled");
        assert_eq!(g.parameters(), &before);
    }
}
