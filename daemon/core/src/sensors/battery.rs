//! Battery state of charge from the pack voltage and current, for the battery failsafe and the
//! ground station (`SYS_STATUS`, `BATTERY_STATUS`).
//!
//! As PX4's battery library, two estimates are fused:
//! - **voltage**: the cell voltage, compensated for the load (`V + I·R`, or a drop proportional
//!   to the throttle when no current is measured: `BAT1_V_LOAD_DROP`), low-passed, read against a
//!   discharge curve. PX4 uses a straight line between `BAT1_V_EMPTY` and `BAT1_V_CHARGED`; a
//!   LiPo's curve is flat in the middle and steep at both ends, so the line reads a 20 % pack as
//!   ~35 % and the low-battery warning comes late. Here a typical LiPo open-circuit curve is
//!   stretched between the same two parameters.
//! - **charge counted** (`BAT1_CAPACITY` known): the estimate starts from the voltage reading of
//!   the pack at rest and integrates the current; once the voltage reads low (below 15 %, where
//!   the curve is steep) it leans toward it at a rate that grows as the pack empties (PX4's
//!   weighting, kept out of the flat middle), so a wrong capacity cannot fly the pack flat while
//!   the curve's own error stays out of the mid-range figure.

use airframe::BatterySpec;

/// A typical LiPo cell's open-circuit voltage against state of charge (published discharge
/// tables of hobby LiPo cells; 3.27 V empty, 4.20 V full).
const LIPO_CURVE: [(f64, f64); 12] = [
    (0.00, 3.27),
    (0.05, 3.61),
    (0.10, 3.69),
    (0.20, 3.73),
    (0.30, 3.77),
    (0.40, 3.80),
    (0.50, 3.84),
    (0.60, 3.87),
    (0.70, 3.95),
    (0.80, 4.02),
    (0.90, 4.11),
    (1.00, 4.20),
];

/// Below this pack voltage there is no battery (or no report): nothing is estimated.
const NO_BATTERY_V: f64 = 2.1;

crate::params::param_group! {
    /// The flight battery, PX4's `BAT1_*`.
    BatteryGroup, "battery", BATTERY_META {
        /// Cells in series (0: the airframe's pack).
        cells: u32 = 0, "BAT1_N_CELLS", "", [0.0, 16.0], "Cells in series; 0: the airframe file's pack";
        /// Cell voltage at empty, at rest (V).
        v_empty: f64 = 3.27, "BAT1_V_EMPTY", "V", [2.5, 4.0], "Cell voltage of an empty pack at rest: the bottom of the discharge curve";
        /// Cell voltage when full, at rest (V).
        v_charged: f64 = 4.2, "BAT1_V_CHARGED", "V", [3.0, 4.5], "Cell voltage of a full pack at rest: the top of the discharge curve";
        /// Internal resistance per cell (Ω; negative: the airframe's pack resistance).
        r_internal_ohm: f64 = -1.0, "BAT1_R_INTERNAL", "Ohm", [-1.0, 0.2], "Internal resistance per cell for the load compensation; -1: from the airframe file's pack";
        /// Capacity (mAh; 0: the airframe's pack; negative: unknown, voltage only).
        capacity_mah: f64 = 0.0, "BAT1_CAPACITY", "mAh", [-1.0, 100000.0], "Pack capacity; 0: the airframe file's pack; -1: unknown, the estimate is voltage-based only";
        /// Cell voltage drop at full throttle, used when the current is not measured (V).
        v_load_drop: f64 = 0.1, "BAT1_V_LOAD_DROP", "V", [0.0, 0.5], "Cell voltage drop at full throttle, for the load compensation when no current is measured";
    }
}

impl BatteryGroup {
    /// `BAT1_V_EMPTY` below `BAT1_V_CHARGED` is required.
    pub fn inconsistencies(&self) -> Vec<String> {
        if self.v_empty + 0.1 > self.v_charged {
            vec![format!(
                "BAT1_V_EMPTY {} must be at least 0.1 V below BAT1_V_CHARGED {}",
                self.v_empty, self.v_charged
            )]
        } else {
            Vec::new()
        }
    }
}

/// The estimator's settings, the parameters resolved against the airframe's pack.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryConfig {
    /// Cells in series.
    pub cells: u32,
    /// Cell voltage at empty (V).
    pub v_empty: f64,
    /// Cell voltage when full (V).
    pub v_charged: f64,
    /// Internal resistance per cell (Ω).
    pub r_cell_ohm: f64,
    /// Capacity (mAh), if known.
    pub capacity_mah: Option<f64>,
    /// Cell voltage drop at full throttle (V).
    pub v_load_drop: f64,
}

impl BatteryConfig {
    /// The parameters, with the airframe file's pack for what they leave open.
    pub fn from_params(p: &BatteryGroup, pack: &BatterySpec) -> Self {
        let cells = if p.cells == 0 { pack.cells } else { p.cells }.max(1);
        Self {
            cells,
            v_empty: p.v_empty,
            v_charged: p.v_charged,
            r_cell_ohm: if p.r_internal_ohm < 0.0 {
                pack.internal_resistance_ohm / pack.cells.max(1) as f64
            } else {
                p.r_internal_ohm
            },
            capacity_mah: if p.capacity_mah == 0.0 {
                Some(pack.capacity_mah)
            } else {
                (p.capacity_mah > 0.0).then_some(p.capacity_mah)
            },
            v_load_drop: p.v_load_drop,
        }
    }

    /// State of charge (0–1) of a cell at rest at voltage `v`: the LiPo curve stretched between
    /// `v_empty` and `v_charged`.
    pub fn charge_at_rest(&self, v: f64) -> f64 {
        let (lo, hi) = (LIPO_CURVE[0].1, LIPO_CURVE[LIPO_CURVE.len() - 1].1);
        // The cell voltage on the table's own scale.
        let x = lo + (v - self.v_empty) * (hi - lo) / (self.v_charged - self.v_empty);
        if x <= lo {
            return 0.0;
        }
        for w in LIPO_CURVE.windows(2) {
            let ((s0, v0), (s1, v1)) = (w[0], w[1]);
            if x <= v1 {
                return s0 + (s1 - s0) * (x - v0) / (v1 - v0);
            }
        }
        1.0
    }
}

/// What the estimator says about the pack.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BatteryState {
    /// Pack voltage under load (V); 0 when none is reported.
    pub voltage_v: f64,
    /// Pack current (A), when measured.
    pub current_a: Option<f64>,
    /// Charge drawn since start (mAh), when the current is measured.
    pub consumed_mah: Option<f64>,
    /// Cell voltage compensated for the load, filtered (V).
    pub cell_v_at_rest: f64,
    /// State of charge (0–1), once a voltage has been seen.
    pub remaining: Option<f64>,
    /// Flight time left at the present current (s), when the charge is counted.
    pub time_remaining_s: Option<f64>,
}

/// The battery estimator (pure: voltage, current, throttle and the sample time in).
#[derive(Debug, Clone, PartialEq)]
pub struct BatteryEstimator {
    config: BatteryConfig,
    cell_v: Option<f64>,
    charge: Option<f64>,
    consumed_mah: f64,
    current_filtered_a: Option<f64>,
    state: BatteryState,
}

/// Time constant of the cell-voltage low-pass (s).
const VOLTAGE_TAU_S: f64 = 1.0;
/// Time constant of the current low-pass for the time left (s).
const CURRENT_TAU_S: f64 = 10.0;
/// How fast a counted estimate leans toward the voltage reading (1/s) when the voltage reads
/// empty; the lean starts at a reading of [`VOLTAGE_TRUSTED_BELOW`] and grows linearly to this.
/// Above it the curve is too flat to correct a count (a typical curve is off by up to 10 % of
/// charge there for a given pack); below, it is steep and a wrong capacity shows.
const VOLTAGE_WEIGHT_PER_S: f64 = 0.05;
/// The voltage reading below which it corrects the count.
const VOLTAGE_TRUSTED_BELOW: f64 = 0.15;

impl BatteryEstimator {
    /// An estimator that has seen nothing yet.
    pub fn new(config: BatteryConfig) -> Self {
        Self {
            config,
            cell_v: None,
            charge: None,
            consumed_mah: 0.0,
            current_filtered_a: None,
            state: BatteryState::default(),
        }
    }

    /// New settings; the estimate is kept.
    pub fn set_config(&mut self, config: BatteryConfig) {
        self.config = config;
    }

    /// The last state.
    pub fn state(&self) -> BatteryState {
        self.state
    }

    /// One sample: pack `voltage_v`, `current_a` if measured, the mean motor command `throttle`
    /// (0–1), `dt` since the last sample (s).
    pub fn step(
        &mut self,
        voltage_v: f64,
        current_a: Option<f64>,
        throttle: f64,
        dt: f64,
    ) -> BatteryState {
        let c = self.config;
        let dt = if dt.is_finite() {
            dt.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let current_a = current_a.filter(|i| i.is_finite()).map(|i| i.max(0.0));
        if !voltage_v.is_finite() || voltage_v < NO_BATTERY_V {
            self.state = BatteryState {
                current_a,
                ..BatteryState::default()
            };
            return self.state;
        }
        // Load compensation: the voltage the cell would show at rest.
        let cell = voltage_v / c.cells as f64
            + match current_a {
                Some(i) => i * c.r_cell_ohm,
                None => c.v_load_drop * throttle.clamp(0.0, 1.0),
            };
        let alpha = 1.0 - (-dt / VOLTAGE_TAU_S).exp();
        let cell_v = self.cell_v.map_or(cell, |v| v + alpha * (cell - v));
        self.cell_v = Some(cell_v);
        let by_voltage = c.charge_at_rest(cell_v);
        if let Some(i) = current_a {
            self.consumed_mah += i * dt / 3.6;
            let beta = 1.0 - (-dt / CURRENT_TAU_S).exp();
            let f = self.current_filtered_a.get_or_insert(i);
            *f += beta * (i - *f);
        }
        let remaining = match (c.capacity_mah, current_a) {
            (Some(cap), Some(i)) => {
                let q = self.charge.get_or_insert(by_voltage);
                let lean = ((VOLTAGE_TRUSTED_BELOW - by_voltage) / VOLTAGE_TRUSTED_BELOW).max(0.0);
                let w = (VOLTAGE_WEIGHT_PER_S * lean * dt).min(1.0);
                *q = ((1.0 - w) * *q + w * by_voltage - i * dt / 3.6 / cap).clamp(0.0, 1.0);
                *q
            }
            _ => by_voltage,
        };
        let time_remaining_s = match (c.capacity_mah, self.current_filtered_a, current_a) {
            (Some(cap), Some(i), Some(_)) if i > 0.1 => Some(remaining * cap * 3.6 / i),
            _ => None,
        };
        self.state = BatteryState {
            voltage_v,
            current_a,
            consumed_mah: current_a.map(|_| self.consumed_mah),
            cell_v_at_rest: cell_v,
            remaining: Some(remaining),
            time_remaining_s,
        };
        self.state
    }
}

#[cfg(test)]
mod tests;
