//! Flying without the IMU: a frozen IMU while armed, and sensor samples that stop. Without it no
//! loop can close: the hover commands hold a moment, then the blind descent
//! ([`crate::safety::blind_descent`]) brings the vehicle down open-loop.

use super::{Autopilot, AutopilotOutput, StepKind};
use crate::safety::blind_descent::BlindDescent;
use airframe::MAX_ROTORS;

/// What to tell the rotors while the sensor samples are silent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SilentAnswer {
    /// The time the answer stands for (µs): the last sample's and the silence since.
    pub t_usec: u64,
    /// The blind descent's commands, else zeros.
    pub commands: [f64; MAX_ROTORS],
    /// Motors armed.
    pub armed: bool,
}

impl Autopilot {
    /// The sensor samples stopped: the estimate is invalid from now on. On the ground the
    /// motors stop; in the air an open-loop descent begins on the recent hover commands.
    /// Returns whether the vehicle is in the air.
    pub fn sensors_stopped(&mut self) -> bool {
        if let Some(c) = self.imu_cal.as_mut() {
            c.sensors_stopped();
        }
        let in_air = self.blind_descent("sensor frames stopped");
        self.publish();
        in_air
    }

    /// The sensor samples are back: the loops fly again (the commander keeps descending).
    pub fn sensors_resumed(&mut self) {
        if self.blind.take().is_some() {
            tracing::warn!("sensor frames back: descending closed-loop");
        }
        self.publish();
    }

    /// What to tell the rotors while the samples are silent, `silence_s` after the last one:
    /// the blind descent's commands, else motors off.
    pub fn silent_answer(&mut self, silence_s: f64) -> SilentAnswer {
        let t_usec = self.last_t_usec() + (silence_s * 1e6) as u64;
        if let Some(d) = &self.blind {
            if let Some(commands) = d.commands(silence_s) {
                return SilentAnswer {
                    t_usec,
                    commands,
                    armed: true,
                };
            }
            self.blind_descent_over();
            self.publish();
        }
        SilentAnswer {
            t_usec,
            commands: [0.0; MAX_ROTORS],
            armed: false,
        }
    }

    /// The estimate is lost for `why`: on the ground the motors stop, in the air the blind
    /// descent begins. Whether the vehicle is in the air.
    fn blind_descent(&mut self, why: &str) -> bool {
        let in_air = self.commander.sensors_stopped();
        if in_air {
            let home_down = self.commander.home().map_or(0.0, |h| h.z);
            let (height, down) = self.estimate().map_or((0.0, 0.0), |o| {
                let t = &o.translation;
                (home_down - t.pos_ned_m.z, t.vel_ned_m_s.z)
            });
            let d = BlindDescent::new(self.hover.get(), height, down);
            tracing::error!(
                height_m = format!("{height:.1}"),
                "{why} in the air: estimator invalid; descending open-loop on the hover commands, motors stop in {:.1} s",
                d.stop_after_s()
            );
            self.blind = Some(d);
        } else if !self.commander.armed() {
            tracing::error!("{why} on the ground: estimator invalid; disarmed");
            self.check_end();
        }
        in_air
    }

    /// The blind descent has run its time: the motors stop.
    fn blind_descent_over(&mut self) {
        tracing::error!("blind descent over: motors stopped");
        self.blind = None;
        self.commander.disarmed();
        self.check_end();
    }

    /// A frozen IMU while armed: the estimator would integrate the same reading over and over
    /// and the rate loop fight a rate that never changes. A repeated reading is suspect: that
    /// sample is answered with the hover commands, the loops untouched. Repeated long enough
    /// ([`crate::sensors::monitor::SensorMonitor`]) it is lost: the samples are answered as if
    /// they had gone silent (the blind descent in the air, motors off on the ground), and the
    /// IMU is not trusted again before the motors stop. `None`: fly this sample as usual;
    /// `Some(None)`: motors off.
    pub(super) fn imu_frozen(&mut self, t_usec: u64) -> Option<Option<[f64; MAX_ROTORS]>> {
        match self.imu_frozen_since_usec {
            None if !(self.commander.armed() && self.monitor.imu_repeating()) => None,
            None if !self.monitor.lost().imu => Some(Some(self.hover.get())),
            _ => {
                let since = match self.imu_frozen_since_usec {
                    Some(s) => s,
                    None => {
                        self.blind_descent("IMU frozen");
                        self.imu_frozen_since_usec = Some(t_usec);
                        t_usec
                    }
                };
                let t_s = t_usec.saturating_sub(since) as f64 * 1e-6;
                match self.blind.as_ref().map(|d| d.commands(t_s)) {
                    Some(Some(c)) => Some(Some(c)),
                    Some(None) => {
                        self.blind_descent_over();
                        Some(None)
                    }
                    None => Some(None),
                }
            }
        }
    }

    /// The answer to a sample flown blind: `commands` (motors off if none), the loops untouched.
    pub(super) fn blind_output(
        &mut self,
        t_usec: u64,
        commands: Option<[f64; MAX_ROTORS]>,
        restarted: bool,
    ) -> bool {
        if self.published.estimate.is_none() {
            return false;
        }
        if !self.commander.armed() {
            self.imu_frozen_since_usec = None;
        }
        let (commands, armed) = match commands {
            Some(c) => (c, true),
            None => ([0.0; MAX_ROTORS], false),
        };
        let answer = AutopilotOutput {
            t_usec,
            commands,
            armed,
            kind: StepKind::Blind,
            setpoint: self
                .published
                .setpoint
                .unwrap_or_else(super::origin_setpoint),
            restarted,
        };
        self.last_answer = Some(answer);
        self.publish();
        true
    }
}
