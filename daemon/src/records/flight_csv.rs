//! The flight-data CSV: one row per sensor frame with what the flight core estimated, what it was
//! asked to do, what it commanded, the simulator's truth where one reports it, and how late the
//! control loop woke. For plots (`tools/plot_flight.py`, any spreadsheet, pandas, gnuplot) and for
//! finding where an error comes from. Every cell is a number at a fixed precision or a fixed word,
//! so rows are written straight into a buffer ([`crate::records::fixed`]) rather than through the
//! `csv` crate (whose job, quoting and escaping, has nothing to do here; the batch CSV, with free
//! text, uses it). Rows are written by a
//! thread of their own ([`crate::records::log_files`]): the control loop copies each row and never
//! formats or waits on the disk.

use crate::records::fixed::{push_fixed, push_int};
use crate::records::log_files::LogFile;
use airframe::MAX_ROTORS;
use flight_core::autopilot::AutopilotOutput;
use flight_core::commander::{CommanderStatus, LandedState};
use flight_core::sample::{SensorSample, StepOutput};
use nalgebra::{UnitQuaternion, Vector3};
use std::path::Path;
use std::time::Duration;

/// Writes flight-data rows.
pub struct FlightCsv {
    file: LogFile<Vec<Row>>,
    /// Rows not yet handed to the writer.
    rows: Vec<Row>,
    /// Flight time of the last row handed over: see [`FLUSH_INTERVAL_S`].
    flushed_t_s: f64,
}

/// Rows are handed to the writer whenever this much flight time has passed since the last time,
/// so a daemon killed outright (SIGKILL, power lost) loses at most the last half second of its
/// log; one that is stopped (Ctrl-C, SIGTERM) writes the rest.
pub const FLUSH_INTERVAL_S: f64 = crate::records::log_files::SHIP_INTERVAL_S;

/// Rows held before a flight-time interval is over (a row per frame at up to 2 kHz).
const ROWS_PER_SHIP: usize = 1024;

/// One row as the control loop copies it: the writer thread formats it.
#[derive(Debug, Clone, Copy)]
struct Row {
    t_s: f64,
    mode: &'static str,
    landed: LandedState,
    armed: bool,
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    sp_pos: Vector3<f64>,
    /// The attitude estimate's roll, pitch and yaw (rad), worked out once by the estimator.
    euler: Option<(f64, f64, f64)>,
    q_d: Option<UnitQuaternion<f64>>,
    thrust_n: Option<f64>,
    /// The wind the outside force on the vehicle means (NED, m/s).
    wind: Option<Vector3<f64>>,
    rate_ref: Vector3<f64>,
    /// True position from the take-off spot and attitude.
    truth: Option<(Vector3<f64>, UnitQuaternion<f64>)>,
    loop_late: Option<Duration>,
    gyro: Vector3<f64>,
    accel: Vector3<f64>,
    mag: Option<Vector3<f64>>,
    commands: [f64; MAX_ROTORS],
}

/// Cells at a precision: each followed by a comma but the last.
fn cells(out: &mut Vec<u8>, values: &[f64], decimals: usize) {
    for (i, &x) in values.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        push_fixed(out, x, decimals);
    }
}

/// Roll, pitch, yaw (deg) of an optional quaternion, or empty cells.
fn euler_deg(out: &mut Vec<u8>, q: Option<UnitQuaternion<f64>>) {
    angles_deg(out, q.map(|q| q.euler_angles()));
}

/// Roll, pitch, yaw (deg) from radians, or empty cells.
fn angles_deg(out: &mut Vec<u8>, rpy: Option<(f64, f64, f64)>) {
    match rpy {
        Some((r, p, y)) => cells(out, &[r.to_degrees(), p.to_degrees(), y.to_degrees()], 3),
        None => out.extend_from_slice(b",,"),
    }
}

/// Formats `r` as a CSV line with `rotors` motor columns (on the writer thread).
fn write_row(out: &mut Vec<u8>, r: &Row, rotors: usize) {
    let (p, v, s) = (r.pos, r.vel, r.sp_pos);
    push_fixed(out, r.t_s, 4);
    out.push(b',');
    out.extend_from_slice(r.mode.as_bytes());
    out.push(b',');
    out.extend_from_slice(r.landed.name().as_bytes());
    out.extend_from_slice(if r.armed { b",1," } else { b",0," });
    cells(out, &[p.x, p.y, p.z, v.x, v.y, v.z, s.x, s.y, s.z], 4);
    out.push(b',');
    angles_deg(out, r.euler);
    out.push(b',');
    euler_deg(out, r.q_d);
    out.push(b',');
    cells(out, &[r.rate_ref.x, r.rate_ref.y, r.rate_ref.z], 5);
    out.push(b',');
    if let Some(t) = r.thrust_n {
        push_fixed(out, t, 3);
    }
    out.push(b',');
    match r.wind {
        Some(w) => cells(out, &[w.x, w.y], 3),
        None => out.push(b','),
    }
    out.push(b',');
    match r.truth {
        Some((p, q)) => {
            cells(out, &[p.x, p.y, p.z], 4);
            out.push(b',');
            euler_deg(out, Some(q));
        }
        None => out.extend_from_slice(b",,,,,"),
    }
    out.push(b',');
    if let Some(d) = r.loop_late {
        push_int(out, d.as_micros().try_into().unwrap_or(u64::MAX));
    }
    out.push(b',');
    let (g, a) = (r.gyro, r.accel);
    cells(out, &[g.x, g.y, g.z], 6);
    out.push(b',');
    cells(out, &[a.x, a.y, a.z], 5);
    out.push(b',');
    match r.mag {
        Some(m) => cells(out, &[m.x, m.y, m.z], 6),
        None => out.extend_from_slice(b",,"),
    }
    for &c in &r.commands[..rotors] {
        out.push(b',');
        push_fixed(out, c, 4);
    }
    out.push(b'\n');
}

impl FlightCsv {
    /// Creates `path` and writes the header for `rotors` motor columns. `lockstep`: the flight's
    /// time is simulated, so a writer that falls behind (a simulation as fast as it goes) is
    /// waited for rather than losing rows; otherwise the loop never waits on it.
    pub fn create(path: &Path, rotors: usize, lockstep: bool) -> std::io::Result<Self> {
        let rotors = rotors.min(MAX_ROTORS);
        let mut header = String::from(
            "t_s,mode,landed,armed,n_m,e_m,d_m,vn_m_s,ve_m_s,vd_m_s,sp_n_m,sp_e_m,sp_d_m,\
             roll_deg,pitch_deg,yaw_deg,sp_roll_deg,sp_pitch_deg,sp_yaw_deg,\
             p_ref_rad_s,q_ref_rad_s,r_ref_rad_s,thrust_n,wind_n_m_s,wind_e_m_s,\
             true_n_m,true_e_m,true_d_m,true_roll_deg,true_pitch_deg,true_yaw_deg,loop_late_us,\
             gx,gy,gz,ax,ay,az,mx,my,mz",
        );
        for i in 1..=rotors {
            header += &format!(",motor{i}");
        }
        header.push('\n');
        // Each chunk of rows formatted into one buffer, kept from chunk to chunk, and written
        // with one call.
        let mut text = Vec::new();
        let file = LogFile::create_with(path, header.as_bytes(), move |rows: Vec<Row>, out| {
            text.clear();
            for r in &rows {
                write_row(&mut text, r, rotors);
            }
            out.write_all(&text)
        })?;
        let file = if lockstep { file.lossless() } else { file };
        Ok(Self {
            file,
            rows: Vec::with_capacity(ROWS_PER_SHIP),
            flushed_t_s: f64::NEG_INFINITY,
        })
    }

    /// Records one frame's row. `true_pose` is the true position from the take-off spot and
    /// attitude (none before arming or without truth); `loop_late` is how late the control loop woke for this frame
    /// (empty when paced by the simulator, lockstep); then the sensor sample the flight core
    /// stepped on, raw (gyro rad/s, specific force m/s², magnetometer gauss, FRD; the
    /// magnetometer only when fresh), the columns `autopilot replay` and `calibrate-mag` read.
    /// The row is copied here and formatted by the writer thread.
    pub fn record(
        &mut self,
        status: &CommanderStatus,
        step: &AutopilotOutput,
        out: &StepOutput,
        sample: &SensorSample,
        true_pose: Option<(Vector3<f64>, UnitQuaternion<f64>)>,
        loop_late: Option<Duration>,
    ) -> std::io::Result<()> {
        let t_s = step.t_usec as f64 * 1e-6;
        let sp = out.attitude_setpoint;
        self.rows.push(Row {
            t_s,
            mode: status.mode.name(),
            landed: status.landed,
            armed: step.armed,
            pos: out.translation.pos_ned_m,
            vel: out.translation.vel_ned_m_s,
            // Stick-to-attitude modes fly no position: its set-point columns are NaN.
            sp_pos: step
                .setpoint
                .position()
                .map_or(Vector3::repeat(f64::NAN), |p| p.pos_ned_m),
            euler: out.attitude.map(|a| a.euler_rad),
            q_d: sp.map(|a| a.q_d),
            thrust_n: sp.map(|a| a.thrust_n),
            wind: out.wind.map(|w| w.wind_ned_m_s),
            rate_ref: out.rate_reference,
            truth: true_pose,
            loop_late,
            gyro: sample.gyro,
            accel: sample.accel,
            mag: sample.mag,
            commands: out.commands,
        });
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
        if self.rows.is_empty() {
            return Ok(());
        }
        let rows = std::mem::replace(&mut self.rows, Vec::with_capacity(ROWS_PER_SHIP));
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
