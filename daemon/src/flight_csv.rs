//! The flight-data CSV: one row per sensor frame with what the flight core estimated, what it was
//! asked to do, what it commanded, the simulator's truth where one reports it, and how late the
//! control loop woke. For plots (`tools/plot_flight.py`, any spreadsheet, pandas, gnuplot) and
//! for finding where an error comes from. Rows are written by a thread of their own
//! ([`crate::log_files`]): the control loop formats them and never waits on the disk.

use crate::log_files::LogFile;
use crate::score::FlightScore;
use flight_core::commander::CommanderStatus;
use flight_core::control::Setpoint;
use flight_core::core::{SensorSample, StepOutput};
use hil::TruthReport;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

/// Writes flight-data rows.
pub struct FlightCsv {
    file: LogFile,
    /// Rows not yet handed to the writer.
    out: Vec<u8>,
    rotors: usize,
    /// Flight time of the last row on disk: see [`FLUSH_INTERVAL_S`].
    flushed_t_s: f64,
}

/// Rows are handed to the writer whenever this much flight time has passed since the last time,
/// so a daemon killed outright (SIGKILL, power lost) loses at most the last half second of its
/// log; one that is stopped (Ctrl-C, SIGTERM) writes the rest.
pub const FLUSH_INTERVAL_S: f64 = crate::log_files::SHIP_INTERVAL_S;

/// Roll, pitch, yaw (deg) of an optional quaternion, or empty cells.
fn euler_deg(q: Option<nalgebra::UnitQuaternion<f64>>) -> String {
    q.map_or(",,".to_owned(), |q| {
        let (r, p, y) = q.euler_angles();
        format!(
            "{:.3},{:.3},{:.3}",
            r.to_degrees(),
            p.to_degrees(),
            y.to_degrees()
        )
    })
}

impl FlightCsv {
    /// Creates `path` and writes the header for `rotors` motor columns.
    pub fn create(path: &Path, rotors: usize) -> std::io::Result<Self> {
        let file = LogFile::create(path)?;
        let mut out = Vec::with_capacity(256 * 1024);
        write!(
            out,
            "t_s,mode,landed,armed,n_m,e_m,d_m,vn_m_s,ve_m_s,vd_m_s,sp_n_m,sp_e_m,sp_d_m,\
             roll_deg,pitch_deg,yaw_deg,sp_roll_deg,sp_pitch_deg,sp_yaw_deg,\
             p_ref_rad_s,q_ref_rad_s,r_ref_rad_s,thrust_n,\
             true_n_m,true_e_m,true_d_m,true_roll_deg,true_pitch_deg,true_yaw_deg,loop_late_us,\
             gx,gy,gz,ax,ay,az,mx,my,mz"
        )?;
        for i in 1..=rotors {
            write!(out, ",motor{i}")?;
        }
        writeln!(out)?;
        Ok(Self {
            file,
            out,
            rotors,
            flushed_t_s: f64::NEG_INFINITY,
        })
    }

    /// Writes one frame's row. True positions are relative to the take-off spot (empty before
    /// arming or without truth); `loop_late` is how late the control loop woke for this frame
    /// (empty when paced by the simulator, lockstep); then the sensor sample the flight core
    /// stepped on, raw (gyro rad/s, specific force m/s², magnetometer gauss, FRD; the
    /// magnetometer only when fresh), the columns `autopilot replay` and `calibrate-mag` read.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &mut self,
        t_s: f64,
        status: &CommanderStatus,
        armed: bool,
        setpoint: &Setpoint,
        out: &StepOutput,
        truth: Option<&TruthReport>,
        score: &FlightScore,
        loop_late: Option<Duration>,
        sample: &SensorSample,
    ) -> std::io::Result<()> {
        let tr = &out.translation;
        // Stick-to-attitude modes fly no position: its set-point columns are NaN.
        let s = setpoint
            .position()
            .map_or(nalgebra::Vector3::repeat(f64::NAN), |p| p.pos_ned_m);
        let (p, v) = (tr.pos_ned_m, tr.vel_ned_m_s);
        write!(
            self.out,
            "{t_s:.4},{},{:?},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},",
            status.mode.name(),
            status.landed,
            armed as u8,
            p.x,
            p.y,
            p.z,
            v.x,
            v.y,
            v.z,
            s.x,
            s.y,
            s.z,
            euler_deg(out.attitude.map(|a| a.q)),
        )?;
        let sp = out.attitude_setpoint;
        write!(
            self.out,
            "{},{:.5},{:.5},{:.5},{},",
            euler_deg(sp.map(|a| a.q_d)),
            out.rate_reference.x,
            out.rate_reference.y,
            out.rate_reference.z,
            sp.map_or(String::new(), |a| format!("{:.3}", a.thrust_n)),
        )?;
        match truth.and_then(|t| score.local(t).map(|p| (p, t.q))) {
            Some((p, q)) => write!(
                self.out,
                "{:.4},{:.4},{:.4},{}",
                p.x,
                p.y,
                p.z,
                euler_deg(Some(q))
            )?,
            None => write!(self.out, ",,,,,")?,
        }
        match loop_late {
            Some(d) => write!(self.out, ",{}", d.as_micros())?,
            None => write!(self.out, ",")?,
        }
        let (g, a) = (sample.gyro, sample.accel);
        write!(
            self.out,
            ",{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},",
            g.x, g.y, g.z, a.x, a.y, a.z
        )?;
        match sample.mag {
            Some(m) => write!(self.out, "{:.6},{:.6},{:.6}", m.x, m.y, m.z)?,
            None => write!(self.out, ",,")?,
        }
        for c in &out.commands[..self.rotors] {
            write!(self.out, ",{c:.4}")?;
        }
        writeln!(self.out)?;
        // Not `>=` on the difference alone: a clock that steps back (a board restarted)
        // flushes at once and starts counting again.
        if !(t_s < self.flushed_t_s + FLUSH_INTERVAL_S && t_s >= self.flushed_t_s) {
            self.flushed_t_s = t_s;
            self.ship()?;
        }
        Ok(())
    }

    /// Hands the rows held to the writer; if it has stopped, the error that stopped it.
    fn ship(&mut self) -> std::io::Result<()> {
        let rows = std::mem::replace(&mut self.out, Vec::with_capacity(256 * 1024));
        if let Err(e) = self.file.write(rows) {
            return Err(self.file.finish().err().unwrap_or(e));
        }
        Ok(())
    }

    /// Writes what is held and waits for the writer to finish.
    pub fn finish(&mut self) -> std::io::Result<()> {
        self.ship()?;
        self.file.finish()
    }
}
