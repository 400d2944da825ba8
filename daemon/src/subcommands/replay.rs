//! `autopilot replay`: CSV in, attitude estimate CSV out.

use anyhow::{Context, Result, bail};
use flight_core::estimator::replay::{Replay, ReplaySample};
use flight_core::params::FlightParams;
use nalgebra::Vector3;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

const REQUIRED: [&str; 10] = ["t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz"];

/// Runs the replay from `input` to `output`.
pub fn run(input: &Path, output: &Path, params: Option<&Path>) -> Result<()> {
    let params = match params {
        Some(p) => FlightParams::load(p)?,
        None => FlightParams::default(),
    };
    let file =
        std::fs::File::open(input).with_context(|| format!("{}: cannot open", input.display()))?;
    let mut lines = BufReader::new(file).lines();
    let header = lines
        .next()
        .with_context(|| format!("{}: empty file, expected a header", input.display()))??;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut index = [0usize; 10];
    for (k, want) in REQUIRED.iter().enumerate() {
        // The flight-data CSV calls its time `t_s`.
        let alias = if *want == "t" { "t_s" } else { want };
        index[k] = names
            .iter()
            .position(|n| n == want)
            .or_else(|| names.iter().position(|n| *n == alias))
            .with_context(|| {
                format!(
                    "{}: header lacks the column `{want}` (needs {})",
                    input.display(),
                    REQUIRED.join(",")
                )
            })?;
    }
    let out_file = std::fs::File::create(output)
        .with_context(|| format!("{}: cannot create", output.display()))?;
    let mut out = BufWriter::new(out_file);
    writeln!(out, "t,qw,qx,qy,qz,bx,by,bz")?;
    let mut replay = Replay::new(&params.attitude);
    let mut last_t = f64::NEG_INFINITY;
    for (n, line) in lines.enumerate() {
        let line = line?;
        let row = n + 2;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let value = |k: usize| -> Result<f64> {
            let text = fields.get(index[k]).copied().unwrap_or("");
            if text.is_empty() {
                return Ok(f64::NAN);
            }
            text.parse::<f64>().with_context(|| {
                format!(
                    "{}:{row}: column `{}`: not a number: {text:?}",
                    input.display(),
                    REQUIRED[k]
                )
            })
        };
        let v: Vec<f64> = (0..10).map(value).collect::<Result<_>>()?;
        if !(v[0].is_finite() && v[0] > last_t) {
            bail!(
                "{}:{row}: time `t` must increase, got {} after {last_t}",
                input.display(),
                v[0]
            );
        }
        last_t = v[0];
        let mag = Vector3::new(v[7], v[8], v[9]);
        let sample = ReplaySample {
            t_s: v[0],
            gyro: Vector3::new(v[1], v[2], v[3]),
            accel: Vector3::new(v[4], v[5], v[6]),
            mag: mag.iter().all(|x| x.is_finite()).then_some(mag),
        };
        for r in replay.push(&sample) {
            write_row(&mut out, &r)?;
        }
    }
    for r in replay.finish() {
        write_row(&mut out, &r)?;
    }
    out.flush()?;
    Ok(())
}

fn write_row(out: &mut impl Write, r: &flight_core::estimator::replay::ReplayRow) -> Result<()> {
    let b = r.gyro_bias;
    match r.q {
        Some(q) => writeln!(
            out,
            "{},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}",
            r.t_s, q.w, q.i, q.j, q.k, b.x, b.y, b.z
        )?,
        None => writeln!(out, "{},nan,nan,nan,nan,nan,nan,nan", r.t_s)?,
    }
    Ok(())
}
