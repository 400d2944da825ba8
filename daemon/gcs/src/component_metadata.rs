//! Component metadata (the MAVLink component-information microservice, as QGroundControl reads
//! a PX4 vehicle's): the general metadata file, which lists the others by `mftp://` URI and
//! CRC, and the parameter metadata file (name, type, default, range, units, descriptions,
//! group, decimal places), made from the same parameter declarations as `params/README.md`, and
//! the events metadata ([`crate::events`]).
//! The files are served by MAVLink FTP; `COMPONENT_METADATA` names the general one.

use flight_core::params::{FlightParams, ParamKind};
use serde_json::{Value, json};

/// Where the metadata files are in the vehicle's FTP tree (a virtual, read-only directory).
pub const METADATA_DIR: &str = "@META";

/// `COMP_METADATA_TYPE_PARAMETER`.
const COMP_METADATA_TYPE_PARAMETER: u32 = 1;

/// `COMP_METADATA_TYPE_EVENTS`.
const COMP_METADATA_TYPE_EVENTS: u32 = 4;

/// The metadata files of one vehicle, and what `COMPONENT_METADATA` says of them.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentMetadata {
    /// Each file's name in [`METADATA_DIR`] and its bytes (JSON).
    pub files: Vec<(String, Vec<u8>)>,
    /// The general metadata file's URI (`mftp://[;comp=1]@META/general.json`).
    pub uri: String,
    /// Its CRC-32 (as MAVLink FTP's `CalcFileCRC32` computes it).
    pub crc: u32,
}

/// CRC-32 as MAVLink FTP computes it, so a client can check a file with FTP's own opcode.
pub use vehicle_files::ftp::crc32_of as ftp_crc32;

impl ComponentMetadata {
    /// The metadata of this build's parameters, for the vehicle `model` (its airframe),
    /// served by component `component_id`.
    pub fn new(model: &str, component_id: u8) -> Self {
        let uri = |name: &str| format!("mftp://[;comp={component_id}]{METADATA_DIR}/{name}");
        let parameters = to_bytes(&parameters_json());
        let events = to_bytes(&crate::events::metadata_json());
        let general = to_bytes(&json!({
            "version": 1,
            "vendorName": "autopilot",
            "modelName": model,
            "firmwareVersion": env!("CARGO_PKG_VERSION"),
            "metadataTypes": [{
                "type": COMP_METADATA_TYPE_PARAMETER,
                "uri": uri("parameters.json"),
                "fileCrc": ftp_crc32(&parameters),
            }, {
                "type": COMP_METADATA_TYPE_EVENTS,
                "uri": uri("events.json"),
                "fileCrc": ftp_crc32(&events),
            }],
        }));
        Self {
            crc: ftp_crc32(&general),
            uri: uri("general.json"),
            files: vec![
                ("general.json".to_owned(), general),
                ("parameters.json".to_owned(), parameters),
                ("events.json".to_owned(), events),
            ],
        }
    }
}

fn to_bytes(v: &Value) -> Vec<u8> {
    serde_json::to_vec_pretty(v).unwrap_or_default()
}

/// The first sentence of a description (the short one a ground station shows as a name).
fn first_sentence(text: &str) -> &str {
    let end = text.find(". ").map_or(text.len(), |i| i + 1);
    text[..end].trim_end_matches('.').trim()
}

/// Decimal places to show: none for an integer, else enough for the default and the range.
fn decimal_places(kind: ParamKind, values: [f64; 3]) -> u32 {
    if kind == ParamKind::Int32 {
        return 0;
    }
    let places = |v: f64| {
        (0..=6)
            .find(|&p| {
                let scaled = v * 10f64.powi(p);
                (scaled - scaled.round()).abs() < 1e-6 * scaled.abs().max(1.0)
            })
            .unwrap_or(6)
    };
    values
        .iter()
        .map(|&v| places(v) as u32)
        .max()
        .unwrap_or(0)
        .max(1)
}

/// The parameter metadata (version 3 of the format) of every flight-core parameter.
pub fn parameters_json() -> Value {
    let parameters: Vec<Value> = FlightParams::metadata()
        .map(|(group, m)| {
            json!({
                "name": m.name,
                "type": match m.kind {
                    ParamKind::Real32 => "Float",
                    ParamKind::Int32 => "Int32",
                },
                "shortDesc": first_sentence(m.description),
                "longDesc": m.description,
                "units": m.unit,
                "default": m.default,
                "min": m.min,
                "max": m.max,
                "decimalPlaces": decimal_places(m.kind, [m.default, m.min, m.max]),
                "rebootRequired": false,
                "group": FlightParams::group_title(group),
                "category": "Standard",
            })
        })
        .collect();
    json!({ "version": 3, "parameters": parameters })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn general_metadata_points_at_the_parameters_with_their_crc() {
        let m = ComponentMetadata::new("quad_x", 1);
        assert_eq!(m.uri, "mftp://[;comp=1]@META/general.json");
        let general: Value = serde_json::from_slice(&m.files[0].1).expect("json");
        let entry = &general["metadataTypes"][0];
        assert_eq!(entry["uri"], "mftp://[;comp=1]@META/parameters.json");
        assert_eq!(entry["fileCrc"], ftp_crc32(&m.files[1].1));
        assert_eq!(ftp_crc32(b"123456789"), 0x2DFD_2D88);
        let params: Value = serde_json::from_slice(&m.files[1].1).expect("json");
        let list = params["parameters"].as_array().expect("array");
        assert_eq!(list.len(), FlightParams::count());
        let takeoff = list
            .iter()
            .find(|p| p["name"] == "MIS_TAKEOFF_ALT")
            .expect("param");
        assert_eq!(
            (takeoff["type"].as_str(), takeoff["default"].as_f64()),
            (Some("Float"), Some(2.5))
        );
        assert_eq!(decimal_places(ParamKind::Real32, [2.5, 0.0, 100.0]), 1);
        assert_eq!(decimal_places(ParamKind::Real32, [0.015, 0.0, 1.0]), 3);
    }
}
