//! The embedded simulator: `sitl`'s physics in-process, behind the same typed boundary as an
//! external simulator or a flight board. Each exchange's HIL messages are folded straight into a
//! frame, and the answer taken as it would be read from `HIL_ACTUATOR_CONTROLS`, without the
//! bytes in between but with the messages' quantisation ([`SimulatorEnd::frame_update`],
//! [`hil::ActuatorCommand::as_sent`]). It runs the same [`SimulatorEnd`] as the `sitl` process,
//! so one seed flies the same flight in-process and over UDP.

use super::SensorLink;
use super::frames::{Received, close};
use anyhow::{Context, Result};
use hil::control::Control;
use hil::{ActuatorCommand, SensorUpdate, SimulatorEnd};
use sitl_core::sim::{Event, SimConfig, Simulator};
use sitl_core::truth_csv::TruthCsv;
use sitl_core::{Airframe, BodyState};
use std::io;
use std::path::Path;
use std::time::{Duration, Instant};

/// HIL exchange rate (Hz), as `sitl`'s default.
pub const EXCHANGE_HZ: f64 = 250.0;

/// The simulator as a sensor link.
pub struct EmbeddedSim {
    end: SimulatorEnd,
    /// What the exchanges so far have told the autopilot's side.
    update: SensorUpdate,
    pacer: WallClockPacer,
    /// Its own MAVLink endpoint (`--sim-control`): weather, clock, truth.
    control: Option<Control>,
    truth: Option<TruthCsv>,
    truth_error: Option<io::Error>,
    first: bool,
}

impl EmbeddedSim {
    /// A simulator of `airframe` with `sensors` seeded by `seed`, paced at `speed` × real time
    /// (`None`: as fast as lockstep allows), writing ground truth to `truth_csv` at 100 Hz.
    #[cfg(test)]
    pub fn new(
        airframe: &Airframe,
        seed: u64,
        sensors: sitl_core::sensors::SensorPreset,
        speed: Option<f64>,
        truth_csv: Option<&Path>,
    ) -> Result<Self> {
        let config = SimConfig {
            seed,
            sensors: sitl_core::sensors::SensorConfig::preset(sensors),
            ..SimConfig::default()
        };
        Self::with_world(airframe, config, &[], speed, truth_csv)
    }

    /// A simulator of `airframe` in the world `config` describes (seed, sensors, home, wind),
    /// with `events` scheduled (faults, gusts: the batch runs), otherwise as [`Self::new`].
    pub fn with_world(
        airframe: &Airframe,
        config: SimConfig,
        events: &[Event],
        speed: Option<f64>,
        truth_csv: Option<&Path>,
    ) -> Result<Self> {
        let mut sim = Simulator::new(airframe, config, BodyState::default())?;
        sim.schedule(events)?;
        Self::around(sim, speed, truth_csv)
    }

    /// The link around a simulator built and scheduled (a scenario's), otherwise as
    /// [`Self::with_world`].
    pub fn around(sim: Simulator, speed: Option<f64>, truth_csv: Option<&Path>) -> Result<Self> {
        let rotors = sim.airframe().rotors.len();
        let truth = truth_csv
            .map(|p| {
                TruthCsv::create(p, 100.0, rotors)
                    .with_context(|| format!("creating truth CSV {}", p.display()))
            })
            .transpose()?;
        Ok(Self {
            end: SimulatorEnd::new(sim, EXCHANGE_HZ),
            update: SensorUpdate::default(),
            pacer: WallClockPacer {
                anchor: None,
                speed,
            },
            control: None,
            truth,
            truth_error: None,
            first: true,
        })
    }

    /// Served with its own MAVLink endpoint, whose clock (if offered) paces it from now on.
    pub fn with_control(mut self, control: Control) -> Self {
        self.control = Some(control);
        self
    }

    /// Answers the control endpoint and applies the weather it set; whether the clock lets
    /// simulated time run now, waiting up to `timeout` for it to if not (a paused clock).
    fn clock_runs(&mut self, timeout: Duration) -> bool {
        let Some(control) = self.control.as_mut() else {
            return true;
        };
        let mut waited = false;
        loop {
            for action in control.poll(self.end.sim()) {
                self.end.sim_mut().apply(action);
            }
            let t_s = self.end.sim().time_s();
            let Some(pace) = control.pace() else {
                return true;
            };
            if !pace.holds(t_s) {
                self.pacer.set_speed(pace.speedup_at(t_s), t_s);
                return true;
            }
            if waited {
                // Held: from now on, as if the clock had started when it resumes.
                self.pacer.anchor = None;
                return false;
            }
            control.wait(timeout);
            waited = true;
        }
    }

    /// Steps physics over one exchange with the last command, without a frame.
    fn advance_world(&mut self) {
        let truth = &mut self.truth;
        let result = self.end.advance(|sim| match truth.as_mut() {
            Some(csv) => csv.record(&sim.truth(), sim.rotor_speeds()),
            None => Ok(()),
        });
        if let Err(e) = result {
            // Keep flying; the error is reported at the end.
            self.truth_error.get_or_insert(e);
            self.truth = None;
        }
    }

    /// The world goes on while its sensor frames are lost: physics over `exchanges` exchange
    /// intervals with the last command (sensor-loss tests).
    #[cfg(test)]
    pub fn advance_silently(&mut self, exchanges: usize) {
        for _ in 0..exchanges {
            self.advance_world();
        }
    }

    /// The simulator's truth now.
    #[cfg(test)]
    pub fn truth(&self) -> sitl_core::sim::TruthState {
        self.end.sim().truth()
    }

    /// The simulated accelerometer's bias now (m/s², FRD).
    #[cfg(test)]
    pub fn accel_bias(&self) -> nalgebra::Vector3<f64> {
        self.end.sim().sensors().accel_bias()
    }

    /// Simulated time (s).
    pub fn time_s(&self) -> f64 {
        self.end.sim().time_s()
    }

    /// Writes the rest of the truth CSV.
    pub fn finish(&mut self) -> Result<()> {
        if let Some(e) = self.truth_error.take() {
            return Err(e).context("writing the truth CSV");
        }
        if let Some(csv) = self.truth.as_mut() {
            csv.flush().context("writing the truth CSV")?;
        }
        Ok(())
    }
}

/// Keeps simulated time at `speed` × the wall clock's from an anchor, moved whenever the pace
/// changes or the clock held (no burst to catch up).
struct WallClockPacer {
    /// A wall-clock instant and the simulated time due then.
    anchor: Option<(Instant, f64)>,
    /// × real time; `None`: unpaced.
    speed: Option<f64>,
}

impl WallClockPacer {
    /// Paces at `speed` from simulated time `t_s` on, if it changed.
    fn set_speed(&mut self, speed: Option<f64>, t_s: f64) {
        if speed != self.speed {
            self.speed = speed;
            self.anchor = Some((Instant::now(), t_s));
        }
    }

    /// Sleeps until simulated time `t_s` is due.
    fn wait_until(&mut self, t_s: f64) {
        let Some(f) = self.speed else { return };
        let (at, from_s) = *self.anchor.get_or_insert_with(|| (Instant::now(), t_s));
        let due = at + Duration::from_secs_f64((t_s - from_s).max(0.0) / f);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
}

impl SensorLink for EmbeddedSim {
    /// Steps physics over one exchange with the last answer (lockstep: the answer, or the last
    /// command if none came, as `sitl` does on a timeout) and hands over the next frame.
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        if !self.first {
            if !self.clock_runs(timeout) {
                return Ok(false);
            }
            self.advance_world();
        }
        self.first = false;
        self.pacer.wait_until(self.end.sim().time_s());
        self.end.frame_update(&mut self.update);
        into.frames.extend(close(&mut self.update));
        Ok(true)
    }

    fn send(&mut self, command: &ActuatorCommand) -> io::Result<()> {
        self.end.apply(command);
        Ok(())
    }

    fn describe(&self) -> String {
        "sim".into()
    }

    fn silence_clock_s(&self) -> Option<f64> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hil::control::params::Pace;
    use mavlink::dialects::common::{MavMessage, MavParamType, PARAM_SET_DATA};
    use sitl_core::environment::WindConfig;
    use std::net::UdpSocket;

    /// A script's PARAM_SET of `name` to the endpoint at `to`.
    fn set(script: &UdpSocket, to: std::net::SocketAddr, name: &str, value: f32) {
        let mut out = Vec::new();
        hil::Encoder::with_ids(255, 190).push(
            &mut out,
            &MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: value,
                target_system: 1,
                target_component: 25,
                param_id: name.into(),
                param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
            }),
        );
        script.send_to(&out, to).unwrap();
    }

    /// Frames taken until the link holds (at most `limit`).
    fn frames_until_held(sim: &mut EmbeddedSim, limit: usize) -> usize {
        let mut into = Received::default();
        (0..limit)
            .take_while(|_| sim.receive(Duration::from_millis(20), &mut into).unwrap())
            .count()
    }

    /// Paused after its first frame, the world holds (the loop's wait ends with no frame); a
    /// stretch set on the endpoint runs exactly that long, unpaced, and holds again; resumed,
    /// it runs on.
    #[test]
    fn a_paused_clock_holds_runs_a_stretch_and_resumes() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
        let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
        let control = Control::bind("127.0.0.1:0".parse().unwrap(), &WindConfig::default(), true)
            .unwrap()
            .with_clock(Pace::new(Some(1.0), true));
        let to = control.local_addr().unwrap();
        let mut sim = EmbeddedSim::new(
            &airframe,
            1,
            sitl_core::sensors::SensorPreset::Ideal,
            Some(1.0),
            None,
        )
        .unwrap()
        .with_control(control);
        assert_eq!(
            frames_until_held(&mut sim, 10),
            1,
            "the first frame, then held"
        );
        assert_eq!(sim.time_s(), 0.0);
        let script = UdpSocket::bind("127.0.0.1:0").unwrap();
        // 0.2 s at 250 exchanges a second: 50 frames.
        set(&script, to, "SIM_RUN_S", 0.2);
        assert_eq!(frames_until_held(&mut sim, 1000), 50);
        assert!((sim.time_s() - 0.2).abs() < 1e-9, "{}", sim.time_s());
        assert_eq!(frames_until_held(&mut sim, 10), 0, "held again");
        set(&script, to, "SIM_SPEEDUP", 0.0);
        set(&script, to, "SIM_PAUSE", 0.0);
        assert_eq!(frames_until_held(&mut sim, 100), 100, "running, unpaced");
    }
}
