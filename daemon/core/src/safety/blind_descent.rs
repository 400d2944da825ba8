//! What the vehicle does when it can no longer see: the blind descent after the sensor stream
//! stops in the air.
//!
//! Without the IMU no loop can close, so the only safe command is an open-loop one. The motors'
//! recent hover commands already balance weight and torques (centre-of-gravity offsets, motor
//! spread), so the descent keeps their ratios and scales them: thrust goes as the rotor speed
//! squared and the commands as the speed, so a thrust fraction `f` is the commands times `√f`.
//! A short push below hover starts the descent, hover thrust then holds that speed, and after the
//! time the estimated height needs (with margin) the motors stop. Open loop, attitude drifts with
//! any torque left unbalanced (the hover commands are averaged over 2 s, whose noise alone leaves
//! ≈ 1°/s² of roll or pitch acceleration in the simulator), so the descent is brisk: 1.5 m/s, a
//! firm landing rather than a long blind fall.
//! From much higher up no open-loop descent stays upright; on a real board its own firmware's
//! failsafe must act (this is the daemon's best without a gyro).

use airframe::MAX_ROTORS;

/// Deepest thrust cut below hover during the push.
const PUSH_DEPTH: f64 = 0.225;
/// Duration of the push (s): a cut of 0.225 g·sin²(πt/T) over T gives 0.225 g T / 2 ≈ 1.5 m/s
/// down (rotor drag makes it ≈ 1.3 m/s in the simulator).
/// Smooth at both ends: a step in thrust, through motors of slightly different lag, kicks the
/// attitude into a rate nothing damps.
const START_S: f64 = 1.36;
/// The descent speed that push reaches from a hover (m/s).
pub const DESCENT_SPEED_M_S: f64 = 1.5;
/// Time added to the estimated fall time before the motors stop (s).
const MARGIN_S: f64 = 1.5;

/// Low-pass of the commands while flying: the hover commands without the rate loop's moment-to-
/// moment corrections.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoverCommands {
    commands: [f64; MAX_ROTORS],
    tau_s: f64,
    primed: bool,
}

impl HoverCommands {
    /// A filter with time constant `tau_s` (s).
    pub fn new(tau_s: f64) -> Self {
        Self {
            commands: [0.0; MAX_ROTORS],
            tau_s,
            primed: false,
        }
    }

    /// Folds in one step's commands, `dt` seconds after the last.
    pub fn update(&mut self, commands: &[f64; MAX_ROTORS], dt: f64) {
        if !self.primed {
            self.commands = *commands;
            self.primed = true;
            return;
        }
        let k = (dt / self.tau_s).clamp(0.0, 1.0);
        for (c, new) in self.commands.iter_mut().zip(commands) {
            *c += k * (new - *c);
        }
    }

    /// Forgets (on the ground, disarmed).
    pub fn reset(&mut self) {
        self.primed = false;
        self.commands = [0.0; MAX_ROTORS];
    }

    /// The filtered commands.
    pub fn get(&self) -> [f64; MAX_ROTORS] {
        self.commands
    }
}

/// The open-loop descent after the sensors stop in the air.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlindDescent {
    hover: [f64; MAX_ROTORS],
    stop_after_s: f64,
}

impl BlindDescent {
    /// A descent from `height_m` above the ground, from hover commands `hover` while moving
    /// down at `down_m_s` (negative: climbing).
    pub fn new(hover: [f64; MAX_ROTORS], height_m: f64, down_m_s: f64) -> Self {
        // Push time (with the climb to stop first), then the rest at the descent speed.
        let climb_s = (-down_m_s).max(0.0) / (DESCENT_SPEED_M_S / START_S);
        // Half the push's time is spent at half the speed.
        let fall_s = height_m.max(0.0) / DESCENT_SPEED_M_S - START_S / 2.0;
        Self {
            hover,
            stop_after_s: climb_s + START_S + fall_s + MARGIN_S,
        }
    }

    /// Seconds after the start at which the motors stop.
    pub fn stop_after_s(&self) -> f64 {
        self.stop_after_s
    }

    /// The motor commands `t_s` seconds after the sensors stopped; `None` once the motors
    /// should stop (disarm).
    pub fn commands(&self, t_s: f64) -> Option<[f64; MAX_ROTORS]> {
        if t_s >= self.stop_after_s {
            return None;
        }
        let fraction = if t_s < START_S {
            1.0 - PUSH_DEPTH * (std::f64::consts::PI * t_s / START_S).sin().powi(2)
        } else {
            1.0
        };
        Some(self.hover.map(|c| (c * fraction.sqrt()).clamp(0.0, 1.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GRAVITY_M_S2;

    #[test]
    fn the_hover_filter_drops_the_rate_loop_jitter() {
        let mut f = HoverCommands::new(0.5);
        let mut c = [0.0; MAX_ROTORS];
        for k in 0..2000 {
            c[0] = 0.5 + if k % 2 == 0 { 0.05 } else { -0.05 };
            c[1] = 0.4;
            f.update(&c, 0.004);
        }
        assert!((f.get()[0] - 0.5).abs() < 0.005 && (f.get()[1] - 0.4).abs() < 1e-9);
    }

    /// A point mass under thrust ∝ command² with drag-free dynamics follows the profile down
    /// at the design speed and the motors stop only after it is down.
    #[test]
    fn the_descent_reaches_the_ground_gently_before_the_motors_stop() {
        let hover = {
            let mut h = [0.0; MAX_ROTORS];
            h[..4].copy_from_slice(&[0.5, 0.52, 0.49, 0.51]);
            h
        };
        let d = BlindDescent::new(hover, 5.0, 0.0);
        let (dt, mut t, mut v, mut height) = (0.001, 0.0, 0.0f64, 5.0f64);
        let mut touchdown = None;
        let mut last_f = 1.0;
        while let Some(c) = d.commands(t) {
            // Thrust fraction of the hover: mean of (c/hover)² over the rotors.
            let f: f64 = (0..4).map(|i| (c[i] / hover[i]).powi(2)).sum::<f64>() / 4.0;
            let ratios: Vec<f64> = (0..4).map(|i| c[i] / hover[i]).collect();
            assert!(
                ratios.iter().all(|r| (r - ratios[0]).abs() < 1e-12),
                "ratios kept"
            );
            assert!(
                (f - last_f).abs() < 0.01,
                "smooth thrust: {last_f} → {f} at {t}"
            );
            last_f = f;
            if height > 0.0 {
                v += (1.0 - f) * GRAVITY_M_S2 * dt;
                height -= v * dt;
            } else if touchdown.is_none() {
                touchdown = Some((t, v));
            }
            t += dt;
        }
        let (t_down, v_down) = touchdown.expect("on the ground before the motors stop");
        assert!((v_down - DESCENT_SPEED_M_S).abs() < 0.01, "at {v_down} m/s");
        assert!(
            d.stop_after_s() - t_down > 1.0,
            "margin {}",
            d.stop_after_s() - t_down
        );
    }
}
