//! A batch's summary, counted from its CSV rows alone, so that a campaign flown on one machine
//! and one merged from shards say the same.

use super::FaultKind;
use serde::{Deserialize, Serialize};

/// Runs counted by outcome, with their failsafes and the hardest impact.
#[derive(Debug, Default, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tally {
    /// Runs counted.
    pub runs: u32,
    /// On the ground, disarmed and upright.
    pub landed: u32,
    /// Hit the ground too fast, or on its side or back.
    pub crashed: u32,
    /// Still flying or armed when its time was up.
    pub not_landed: u32,
    /// Could not be flown.
    pub errors: u32,
    /// Runs in which a failsafe acted.
    pub failsafes: u32,
    /// The hardest impact (m/s), as the CSV has it.
    pub max_impact_m_s: f64,
}

/// The columns a tally reads.
struct Columns {
    fault: usize,
    outcome: usize,
    failsafe: usize,
    impact: usize,
}

fn columns() -> Columns {
    let at = super::column;
    Columns {
        fault: at("fault"),
        outcome: at("outcome"),
        failsafe: at("failsafe"),
        impact: at("impact_m_s"),
    }
}

impl Tally {
    /// Counts one CSV row.
    fn add(&mut self, row: &csv::StringRecord, c: &Columns) {
        self.runs += 1;
        match row.get(c.outcome).unwrap_or("") {
            "landed" => self.landed += 1,
            "crashed" => self.crashed += 1,
            "not_landed" => self.not_landed += 1,
            _ => self.errors += 1,
        }
        self.failsafes += u32::from(row.get(c.failsafe) == Some("true"));
        if let Some(v) = row.get(c.impact).and_then(|s| s.parse::<f64>().ok()) {
            self.max_impact_m_s = self.max_impact_m_s.max(v);
        }
    }
}

impl std::fmt::Display for Tally {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "runs={} landed={} crashed={} not_landed={} errors={} failsafes={} max_impact_m_s={:.2}",
            self.runs,
            self.landed,
            self.crashed,
            self.not_landed,
            self.errors,
            self.failsafes,
            self.max_impact_m_s
        )
    }
}

/// One fault's tally.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FaultTally {
    /// The fault's name, as in the CSV.
    pub fault: String,
    /// Its runs.
    #[serde(flatten)]
    pub tally: Tally,
}

/// A batch's tallies: all runs, and each fault's in [`FaultKind::ALL`]'s order.
#[derive(Debug, Default, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchSummary {
    /// Every run.
    pub total: Tally,
    /// By fault.
    pub faults: Vec<FaultTally>,
}

impl BatchSummary {
    /// The summary of `rows`.
    pub fn of<'a>(rows: impl IntoIterator<Item = &'a csv::StringRecord>) -> Self {
        let c = columns();
        let mut s = BatchSummary::default();
        for row in rows {
            s.add(row, &c);
        }
        s.faults.sort_by_key(|f| {
            FaultKind::ALL
                .iter()
                .position(|(n, _)| *n == f.fault)
                .unwrap_or(usize::MAX)
        });
        s
    }

    fn add(&mut self, row: &csv::StringRecord, c: &Columns) {
        self.total.add(row, c);
        let fault = row.get(c.fault).unwrap_or("");
        match self.faults.iter_mut().find(|f| f.fault == fault) {
            Some(f) => f.tally.add(row, c),
            None => {
                let mut tally = Tally::default();
                tally.add(row, c);
                self.faults.push(FaultTally {
                    fault: fault.to_owned(),
                    tally,
                });
            }
        }
    }

    /// Prints one `batch fault=NAME …` line per fault.
    pub fn print_faults(&self) {
        for f in &self.faults {
            println!("batch fault={} {}", f.fault, f.tally);
        }
    }
}
