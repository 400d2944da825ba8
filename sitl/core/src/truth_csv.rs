//! Ground-truth CSV: one row per sample, for plots and for scoring a flight.

use crate::sim::TruthState;
use std::io::{BufWriter, Write};

/// Writes truth rows at a fixed simulation-time interval.
pub struct TruthCsv {
    out: BufWriter<std::fs::File>,
    interval_usec: u64,
    next_usec: u64,
}

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
        writeln!(self.out)
    }

    /// Flushes buffered rows to disk.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}
