//! `autopilot calibrate-mag`: the magnetometer's ellipsoid (Castillo (75)–(79)) fitted to the raw
//! samples of a log, written into a flight-parameter file.
//!
//! Any CSV with `mx,my,mz` columns (raw FRD magnetometer; an empty cell is a sample that was not
//! fresh) will do: the flight-data CSV every run leaves in `logs/`, or a log in the `replay`
//! format. The vehicle must have been turned through every orientation while it was recorded.

use anyhow::{Context, Result, bail};
use flight_core::params::FlightParams;
use flight_core::sensors::mag_fit::{Ellipsoid, fit_ellipsoid};
use nalgebra::Vector3;
use std::io::{BufRead, BufReader};
use std::path::Path;

/// The raw magnetometer samples of a CSV log (rows whose `mx,my,mz` are all numbers).
pub fn read_samples(path: &Path) -> Result<Vec<Vector3<f64>>> {
    let file =
        std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let mut lines = BufReader::new(file).lines();
    let header = lines
        .next()
        .with_context(|| format!("{}: empty file, expected a header", path.display()))??;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut index = [0usize; 3];
    for (k, want) in ["mx", "my", "mz"].iter().enumerate() {
        index[k] = names.iter().position(|n| n == want).with_context(|| {
            format!(
                "{}: no `{want}` column (a log with raw magnetometer columns mx,my,mz)",
                path.display()
            )
        })?;
    }
    let mut samples = Vec::new();
    for (n, line) in lines.enumerate() {
        let line = line?;
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let cell = |k: usize| fields.get(index[k]).copied().unwrap_or("");
        if (0..3).any(|k| cell(k).is_empty()) {
            continue; // not fresh in this row
        }
        let mut v = Vector3::zeros();
        for k in 0..3 {
            v[k] = cell(k).parse().with_context(|| {
                format!(
                    "{}:{}: `{}` is not a number",
                    path.display(),
                    n + 2,
                    cell(k)
                )
            })?;
        }
        samples.push(v);
    }
    Ok(samples)
}

/// The `[attitude]` keys a calibration sets, as TOML values.
fn calibration_values(
    fit: &Ellipsoid,
    strength: f64,
    device_id: u32,
) -> [(&'static str, String); 4] {
    let v = |x: [f64; 3]| format!("[{:.6}, {:.6}, {:.6}]", x[0], x[1], x[2]);
    let mut p = flight_core::estimator::attitude::AttitudeParams::default();
    p.set_mag_correction(&fit.correction(strength));
    [
        ("mag_offset", v(fit.offset.into())),
        ("mag_scale", v(p.mag_scale)),
        ("mag_offdiag", v(p.mag_offdiag)),
        ("mag_calibration_id", device_id.to_string()),
    ]
}

/// `text` (a flight-parameter file) with the calibration's keys set in its `[attitude]` table:
/// a key's line is replaced keeping its comment, a missing key is added under the table's
/// header, a missing table is appended.
pub fn with_calibration(text: &str, values: &[(&str, String)]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let table = |l: &str| l.trim_start().starts_with('[');
    let start = lines.iter().position(|l| l.trim() == "[attitude]");
    let Some(start) = start else {
        let mut out = text.trim_end().to_owned();
        out += "\n\n[attitude]\n";
        for (k, v) in values {
            out += &format!("{k} = {v}\n");
        }
        return out;
    };
    let end = lines[start + 1..]
        .iter()
        .position(|l| table(l))
        .map_or(lines.len(), |i| start + 1 + i);
    let mut missing = Vec::new();
    for (k, v) in values {
        let found = (start + 1..end).find(|&i| {
            lines[i]
                .split_once('=')
                .is_some_and(|(key, _)| key.trim() == *k)
        });
        match found {
            Some(i) => {
                // The comment with the spaces before it (these keys' values hold no `#`).
                let comment = lines[i]
                    .find('#')
                    .map(|h| lines[i][lines[i][..h].trim_end().len()..].to_owned())
                    .unwrap_or_default();
                lines[i] = format!("{k} = {v}{comment}");
            }
            None => missing.push(format!("{k} = {v}")),
        }
    }
    for (n, line) in missing.into_iter().enumerate() {
        lines.insert(start + 1 + n, line);
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// Fits `input`'s samples and writes the calibration into `params` (atomically, comments kept),
/// or prints it when `params` is `None`. The field strength the calibrated field is scaled to is
/// `ATT_MAG_STR` of that file (or the default's).
pub fn run(input: &Path, params: Option<&Path>, device_id: Option<u32>) -> Result<()> {
    let samples = read_samples(input)?;
    let current = match params {
        Some(p) => FlightParams::load(p)?,
        None => FlightParams::default(),
    };
    let fit = fit_ellipsoid(&samples)
        .map_err(|e| anyhow::anyhow!("{}: no calibration: {e}", input.display()))?;
    let strength = current.attitude.mag_intensity_gauss;
    let id = device_id.unwrap_or(match current.attitude.mag_calibration_id {
        0 => 1,
        id => id,
    });
    let values = calibration_values(&fit, strength, id);
    println!(
        "calibrate-mag: {} samples, {} of {} directions covered, fit residual {:.2} % of the field",
        samples.len(),
        fit.coverage,
        flight_core::sensors::mag_fit::COVERAGE_DIRECTIONS,
        100.0 * fit.residual_rms
    );
    println!(
        "offset {:.4} {:.4} {:.4}, radii {:.4} {:.4} {:.4} (field {strength} gauss)",
        fit.offset.x, fit.offset.y, fit.offset.z, fit.radii.x, fit.radii.y, fit.radii.z
    );
    let Some(path) = params else {
        println!("[attitude]");
        for (k, v) in &values {
            println!("{k} = {v}");
        }
        return Ok(());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let updated = with_calibration(&text, &values);
    // Never write a file the autopilot would refuse.
    if let Err(e) = FlightParams::from_toml_str(&updated, &path.display().to_string()) {
        bail!("the calibrated parameters do not load: {e}");
    }
    crate::records::param_file::write_atomically(path, &updated)?;
    println!("written to {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_replaced_keeping_comments_or_added() {
        let text = "[attitude]\nmag_weight = 0.1  # ATT_W_MAG\nmag_offset = [0.0, 0.0, 0.0]  # CAL_MAG offset\n\n[position]\nx = 1\n";
        let out = with_calibration(
            text,
            &[
                ("mag_offset", "[1.0, 2.0, 3.0]".into()),
                ("mag_scale", "[1.0, 1.0, 1.0]".into()),
            ],
        );
        assert_eq!(
            out,
            "[attitude]\nmag_scale = [1.0, 1.0, 1.0]\nmag_weight = 0.1  # ATT_W_MAG\nmag_offset = [1.0, 2.0, 3.0]  # CAL_MAG offset\n\n[position]\nx = 1\n"
        );
        let out = with_calibration("[position]\nx = 1\n", &[("mag_calibration_id", "1".into())]);
        assert_eq!(
            out,
            "[position]\nx = 1\n\n[attitude]\nmag_calibration_id = 1\n"
        );
    }
}
