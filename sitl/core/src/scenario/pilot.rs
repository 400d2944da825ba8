//! A pilot's script for a simulated RC transmitter (`sitl --rc-device`): from each step's
//! time on, the sticks, the mode switch and the transmitter as it gives them; what a step
//! leaves out stays as it was.
//!
//! ```toml
//! [[pilot]]
//! t_s = 8.0
//! throttle = 0.0        # 0 to 1
//! yaw = 1.0             # roll, pitch, yaw: -1 to 1 (right, forward, clockwise)
//! switch = 0            # the mode switch's slot, 0 to 5 (COM_FLTMODE1 to 6)
//! transmitter = true    # false: switched off (the link lost)
//! ```

use ::airframe::config::Checker;
use serde::Deserialize;

/// One step of the script as the file gives it.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(super) struct PilotFile {
    t_s: f64,
    roll: Option<f64>,
    pitch: Option<f64>,
    throttle: Option<f64>,
    yaw: Option<f64>,
    switch: Option<u8>,
    transmitter: Option<bool>,
}

/// What the pilot gives at a moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PilotInput {
    /// Roll stick, −1 (left) to 1 (right).
    pub roll: f64,
    /// Pitch stick, −1 (back) to 1 (forward).
    pub pitch: f64,
    /// Throttle, 0 to 1.
    pub throttle: f64,
    /// Yaw stick, −1 to 1 (clockwise).
    pub yaw: f64,
    /// The mode switch's slot, 0 to 5.
    pub switch: u8,
    /// The transmitter is on.
    pub transmitter: bool,
}

impl Default for PilotInput {
    /// Sticks centred, throttle down, the switch in its first slot, the transmitter on.
    fn default() -> Self {
        Self {
            roll: 0.0,
            pitch: 0.0,
            throttle: 0.0,
            yaw: 0.0,
            switch: 0,
            transmitter: true,
        }
    }
}

/// The script, checked and in time order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PilotScript {
    steps: Vec<PilotFile>,
}

impl PilotScript {
    /// The file's steps, each value checked into `c`.
    pub(super) fn resolve(c: &mut Checker, steps: &[PilotFile]) -> Self {
        for (i, s) in steps.iter().enumerate() {
            let key = format!("pilot[{i}]");
            c.non_negative(format!("{key}.t_s"), s.t_s);
            for (name, v) in [("roll", s.roll), ("pitch", s.pitch), ("yaw", s.yaw)] {
                if let Some(v) = v {
                    c.within(format!("{key}.{name}"), v, -1.0, 1.0);
                }
            }
            if let Some(t) = s.throttle {
                c.within(format!("{key}.throttle"), t, 0.0, 1.0);
            }
            if let Some(k) = s.switch {
                c.within(format!("{key}.switch"), f64::from(k), 0.0, 5.0);
            }
        }
        let mut steps = steps.to_vec();
        steps.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        Self { steps }
    }

    /// No steps: the transmitter is not scripted.
    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// What the pilot gives at `t_s`.
    pub fn at(&self, t_s: f64) -> PilotInput {
        let mut p = PilotInput::default();
        for s in self.steps.iter().take_while(|s| s.t_s <= t_s + 1e-9) {
            p.roll = s.roll.unwrap_or(p.roll);
            p.pitch = s.pitch.unwrap_or(p.pitch);
            p.throttle = s.throttle.unwrap_or(p.throttle);
            p.yaw = s.yaw.unwrap_or(p.yaw);
            p.switch = s.switch.unwrap_or(p.switch);
            p.transmitter = s.transmitter.unwrap_or(p.transmitter);
        }
        p
    }
}
