//! The autopilot's side of the HIL link: messages in, a flight-core step per sensor frame, the
//! `HIL_ACTUATOR_CONTROLS` answer out. The same for the embedded simulator and the UDP link.

use anyhow::{Context, Result};
use flight_core::control::position::PositionSetpoint;
use flight_core::core::{FlightCore, FlightCoreConfig, SensorSample, StepOutput};
use flight_core::estimator::translation::GpsMeasurement;
use flight_core::failsafe::{BlindDescent, HoverCommands};
use flight_core::geo::LatLonAlt;
use flight_core::params::FlightParams;
use flight_core::sequence::{FlightSequence, Phase, SequenceInput, SequenceParams};
use hil::SensorUpdate;
use mavlink::dialects::common::MavMessage;
use nalgebra::Vector3;
use sitl_core::Airframe;

use crate::flight_csv::FlightCsv;
use crate::score::FlightScore;

/// The vehicle: flight core, flight sequence and what has arrived since the last frame.
pub struct Vehicle {
    core: FlightCore,
    sequence: FlightSequence,
    update: SensorUpdate,
    last: Option<StepOutput>,
    last_answer: Option<(u64, MavMessage)>,
    repeated_frames: u64,
    rotors: usize,
    nominal_v: f64,
    score: FlightScore,
    csv: Option<FlightCsv>,
    csv_error: Option<std::io::Error>,
    hover: HoverCommands,
    blind: Option<BlindDescent>,
    last_t_usec: u64,
}

/// One step's result.
pub struct Step {
    /// The answer to send.
    pub message: MavMessage,
    /// The flight core's output.
    pub output: StepOutput,
    /// Time of the frame (s).
    pub t_s: f64,
}

impl Vehicle {
    /// A vehicle of `airframe` flying the sequence to `takeoff_m`, hovering `hover_s`.
    pub fn new(
        airframe: &Airframe,
        params: &FlightParams,
        takeoff_m: f64,
        hover_s: f64,
    ) -> Result<Self> {
        Ok(Self {
            core: FlightCore::new(airframe, FlightCoreConfig::from_params(params, airframe))
                .context("building the mixer")?,
            sequence: FlightSequence::new(SequenceParams {
                takeoff_alt_m: takeoff_m,
                takeoff_speed_m_s: 1.5,
                hover_s,
                spool_s: 1.0,
                land_speed_m_s: 0.7,
                final_speed_m_s: 0.3,
                final_height_m: 2.0,
            }),
            update: SensorUpdate::default(),
            last: None,
            last_answer: None,
            repeated_frames: 0,
            rotors: airframe.rotors.len(),
            nominal_v: 3.8 * airframe.battery.cells as f64,
            score: FlightScore::new(takeoff_m),
            csv: None,
            csv_error: None,
            hover: HoverCommands::new(2.0),
            blind: None,
            last_t_usec: 0,
        })
    }

    /// Writes a flight-data row per frame to `csv` from now on.
    pub fn log_to(&mut self, csv: FlightCsv) {
        self.csv = Some(csv);
    }

    /// Flushes the flight-data CSV, reporting the first write error of the flight.
    pub fn finish_log(&mut self) -> Result<()> {
        if let Some(e) = self.csv_error.take() {
            return Err(e).context("writing the flight-data CSV");
        }
        if let Some(csv) = self.csv.as_mut() {
            csv.flush().context("writing the flight-data CSV")?;
        }
        Ok(())
    }

    /// The sequence's phase.
    pub fn phase(&self) -> Phase {
        self.sequence.phase()
    }

    /// The flight's figures against the simulator's truth, where it sends one.
    pub fn score(&self) -> &FlightScore {
        &self.score
    }

    /// Sensor frames that repeated or went back in time, answered or dropped without a step.
    pub fn repeated_frames(&self) -> u64 {
        self.repeated_frames
    }

    /// Lands now.
    pub fn request_land(&mut self) {
        self.sequence.request_land();
    }

    /// The sensor frames stopped: the estimate is invalid from now on. On the ground the motors
    /// stop; in the air an open-loop descent begins on the recent hover commands. Returns
    /// whether the vehicle is in the air.
    pub fn sensors_stopped(&mut self) -> bool {
        let in_air = self.sequence.sensors_stopped();
        if in_air {
            let (height, down) = self.last.map_or((0.0, 0.0), |o| {
                let t = &o.translation;
                (self.sequence.home().z - t.pos_ned_m.z, t.vel_ned_m_s.z)
            });
            let d = BlindDescent::new(self.hover.get(), height, down);
            tracing::error!(
                height_m = format!("{height:.1}"),
                "sensor frames stopped in the air: estimator invalid; descending open-loop on the hover commands, motors stop in {:.1} s",
                d.stop_after_s()
            );
            self.blind = Some(d);
        } else if self.sequence.phase() == Phase::Done {
            tracing::error!("sensor frames stopped on the ground: estimator invalid; disarmed");
        }
        in_air
    }

    /// The answer to send while the frames are silent, `silence_s` after the last one: the
    /// blind descent's commands, else motors off.
    pub fn silent_answer(&mut self, silence_s: f64) -> MavMessage {
        let t_usec = self.last_t_usec + (silence_s * 1e6) as u64;
        if let Some(d) = &self.blind {
            if let Some(c) = d.commands(silence_s) {
                return hil::actuator_controls(t_usec, &c[..self.rotors], true);
            }
            tracing::error!("blind descent over: motors stopped");
            self.blind = None;
            self.sequence.disarmed();
        }
        hil::actuator_controls(t_usec, &[0.0; airframe::MAX_ROTORS][..self.rotors], false)
    }

    /// The sensor frames are back: the loops fly again (the sequence keeps descending).
    pub fn sensors_resumed(&mut self) {
        if self.blind.take().is_some() {
            tracing::warn!("sensor frames back: descending closed-loop");
        }
    }

    /// Folds one message in; a complete sensor frame runs a step and returns the answer.
    pub fn on_message(&mut self, msg: &MavMessage) -> Option<Step> {
        if !self.update.absorb(msg) {
            return None;
        }
        let u = &mut self.update;
        let (t_usec, gyro, accel) = (u.time_usec?, u.gyro_frd?, u.accel_frd?);
        if let (Some((t_last, answer)), Some(output)) = (&self.last_answer, self.last)
            && t_usec <= *t_last
        {
            // A frame seen before (a lockstep simulator resends until it hears an answer; a
            // serial line delivers what queued before the port was opened): answer it again
            // without stepping; an older one is stale and dropped.
            self.repeated_frames += 1;
            u.mag_frd = None;
            u.pressure_alt_m = None;
            u.gps = None;
            u.rotor_speed_rad_s = None;
            u.truth = None;
            return (t_usec == *t_last).then(|| Step {
                message: answer.clone(),
                output,
                t_s: t_usec as f64 * 1e-6,
            });
        }
        let sample = SensorSample {
            t_usec,
            gyro,
            accel,
            mag: u.mag_frd.take(),
            baro_alt_m: u.pressure_alt_m.take(),
            gps: u.gps.take().map(|g| GpsMeasurement {
                fix_type: g.fix_type,
                position: LatLonAlt {
                    lat_deg: g.lat_deg,
                    lon_deg: g.lon_deg,
                    alt_m: g.alt_m,
                },
                vel_ned_m_s: g.vel_ned_m_s,
                h_acc_m: g.h_acc_m,
            }),
            battery_v: u.battery_v.unwrap_or(self.nominal_v),
            rotor_speed_rad_s: u.rotor_speed_rad_s.take(),
        };
        let t_s = t_usec as f64 * 1e-6;
        let (setpoint, armed) = match &self.last {
            Some(e) => {
                let ready = e.attitude.is_some_and(|a| a.valid)
                    && e.translation.horizontal_valid
                    && e.translation.vertical_valid;
                self.sequence.update(&SequenceInput {
                    t_s,
                    ready,
                    horizontal_valid: e.translation.horizontal_valid,
                    pos_ned_m: e.translation.pos_ned_m,
                    vel_ned_m_s: e.translation.vel_ned_m_s,
                })
            }
            None => (
                PositionSetpoint {
                    pos_ned_m: Vector3::zeros(),
                    vel_ned_m_s: Vector3::zeros(),
                    accel_ned_m_s2: Vector3::zeros(),
                    yaw_rad: 0.0,
                },
                false,
            ),
        };
        if self.sequence.phase() == Phase::Armed {
            // Spooling up on the ground: the position loop starts fresh at take-off.
            self.core.reset_position_loop();
        }
        let truth = self.update.truth.take();
        let output = self.core.step(&sample, &setpoint, armed);
        if armed {
            let dt = t_usec.saturating_sub(self.last_t_usec) as f64 * 1e-6;
            self.hover.update(&output.commands, dt);
        } else {
            self.hover.reset();
        }
        self.last_t_usec = t_usec;
        self.last = Some(output);
        if let Some(truth) = &truth {
            let estimate = output.attitude.map(|a| a.q);
            self.score
                .add(truth, estimate, self.sequence.phase(), armed);
        }
        if let Some(csv) = self.csv.as_mut() {
            let phase = self.sequence.phase();
            if let Err(e) = csv.record(
                t_s,
                phase,
                armed,
                &setpoint,
                &output,
                truth.as_ref(),
                &self.score,
            ) {
                // A full disk must not stop the flight: stop logging, report at the end.
                tracing::error!("flight-data CSV: {e}; logging stopped");
                self.csv = None;
                self.csv_error = Some(e);
            }
        }
        let message = hil::actuator_controls(t_usec, &output.commands[..self.rotors], armed);
        self.last_answer = Some((t_usec, message.clone()));
        Some(Step {
            message,
            output,
            t_s,
        })
    }
}
