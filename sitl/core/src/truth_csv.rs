//! Ground-truth CSV: one row per sample, for plots and for scoring a flight. Every cell is a
//! number at a fixed precision, so nothing ever needs quoting: rows are written with `write!` rather
//! than through the `csv` crate (whose job, quoting and escaping, has nothing to do here).

use crate::sim::TruthState;
use std::io::{BufWriter, Write};

/// Writes truth rows at a fixed simulation-time interval.
pub struct TruthCsv {
    out: BufWriter<std::fs::File>,
    interval_usec: u64,
    next_usec: u64,
    /// Simulation time of the last row on disk: see [`FLUSH_INTERVAL_USEC`].
    flushed_usec: u64,
}

/// Rows are flushed to disk whenever this much simulation time has passed since the last flush,
/// so a process killed outright loses at most the last half second of its log (and a stopped
/// one nothing: it flushes the rest).
pub const FLUSH_INTERVAL_USEC: u64 = 500_000;

impl TruthCsv {
    /// Creates `path` and writes the header for `rotors` rotors.
    pub fn create(path: &std::path::Path, rate_hz: f64, rotors: usize) -> std::io::Result<Self> {
        let mut out = BufWriter::new(std::fs::File::create(path)?);
        write!(
            out,
            "t_s,n_m,e_m,d_m,vn_m_s,ve_m_s,vd_m_s,qw,qx,qy,qz,p_rad_s,q_rad_s,r_rad_s,landed,battery_v"
        )?;
        for i in 1..=rotors {
            write!(out, ",rotor{i}_rad_s")?;
        }
        writeln!(out)?;
        Ok(Self {
            out,
            interval_usec: (1e6 / rate_hz.max(0.1)) as u64,
            next_usec: 0,
            flushed_usec: 0,
        })
    }

    /// Writes a row if one is due at `t`'s time.
    pub fn record(&mut self, t: &TruthState, rotor_speeds: &[f64]) -> std::io::Result<()> {
        if t.time_usec < self.next_usec {
            return Ok(());
        }
        self.next_usec = t.time_usec + self.interval_usec;
        let b = &t.body;
        let q = b.q_ned_from_frd.quaternion();
        write!(
            self.out,
            "{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.9},{:.9},{:.9},{:.9},{:.6},{:.6},{:.6},{},{:.3}",
            t.time_usec as f64 * 1e-6,
            b.pos_ned_m.x,
            b.pos_ned_m.y,
            b.pos_ned_m.z,
            b.vel_ned_m_s.x,
            b.vel_ned_m_s.y,
            b.vel_ned_m_s.z,
            q.w,
            q.i,
            q.j,
            q.k,
            b.rate_frd_rad_s.x,
            b.rate_frd_rad_s.y,
            b.rate_frd_rad_s.z,
            t.landed as u8,
            t.battery_voltage_v
        )?;
        for w in rotor_speeds {
            write!(self.out, ",{w:.3}")?;
        }
        writeln!(self.out)?;
        if t.time_usec >= self.flushed_usec + FLUSH_INTERVAL_USEC {
            self.flushed_usec = t.time_usec;
            self.out.flush()?;
        }
        Ok(())
    }

    /// Flushes buffered rows to disk.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::sim::{SimConfig, Simulator};
    use crate::{Airframe, BodyState};

    /// What a process killed outright leaves on disk: every row but those of the last half
    /// second of simulation time (read through another handle, nothing flushed by hand). Rows
    /// at 10 Hz: the write buffer alone would hold seconds of them.
    #[test]
    fn a_killed_writer_leaves_all_but_the_last_half_second_on_disk() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let airframe = Airframe::load(&dir.join("../../params/airframes/quad_x.toml")).unwrap();
        let mut sim =
            Simulator::new(&airframe, SimConfig::default(), BodyState::default()).unwrap();
        let path = std::env::temp_dir().join(format!("truth-flush-{}.csv", std::process::id()));
        let mut csv = TruthCsv::create(&path, 10.0, 4).unwrap();
        while sim.truth().time_usec < 7_300_000 {
            sim.step(&[0.0; 4]);
            let t = sim.truth();
            csv.record(&t, sim.rotor_speeds()).unwrap();
            let latest_s = t.time_usec as f64 * 1e-6;
            let on_disk = std::fs::read_to_string(&path).unwrap();
            let last_on_disk = on_disk
                .lines()
                .filter(|l| l.ends_with(char::is_numeric) && !l.starts_with('t'))
                .filter_map(|l| l.split(',').next()?.parse::<f64>().ok())
                .next_back()
                .unwrap_or(0.0);
            assert!(
                latest_s - last_on_disk <= FLUSH_INTERVAL_USEC as f64 * 1e-6 + 0.101,
                "at {latest_s:.3} s only rows up to {last_on_disk:.3} s are on disk"
            );
        }
        drop(csv);
        let rows = std::fs::read_to_string(&path).unwrap().lines().count() - 1;
        assert!((73..=74).contains(&rows), "{rows} rows at 10 Hz over 7.3 s");
        std::fs::remove_file(&path).unwrap();
    }
}
