//! The pure crates stay pure: the flight core, the simulator's physics, the airframe schema and
//! the shared mathematics depend on no MAVLink, no async runtime and no clock. Time comes with
//! their inputs, bytes are the links' business; a dependency or a clock read creeping in fails
//! here. The ground-station protocol speaks MAVLink but is sans-I/O the same way: no runtime,
//! clock, socket or file (and the `hil` it uses without its `transport` feature).

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

/// A crate kept free of some dependencies and some words in its sources.
struct Rule {
    /// The crate's directory, from this crate's.
    dir: &'static str,
    /// Dependencies it must not have.
    dependencies: &'static [&'static str],
    /// What its sources must not name.
    in_sources: &'static [&'static str],
}

/// The workspace's pure crates, and the sans-I/O ground-station protocol.
const RULES: [Rule; 5] = [
    PURE.at("."),
    PURE.at("../../sitl/core"),
    PURE.at("../../airframe"),
    PURE.at("../../navmath"),
    Rule {
        dir: "../gcs",
        dependencies: &["tokio", "serialport"],
        in_sources: &[
            "tokio::",
            "Instant",
            "SystemTime",
            "std::net",
            "std::fs",
            "hil::transport",
        ],
    },
];

/// What a pure crate must neither depend on nor name.
const PURE: Rule = Rule {
    dir: "",
    dependencies: &["mavlink", "tokio", "serialport"],
    in_sources: &["mavlink::", "tokio::", "Instant", "SystemTime", "std::net"],
};

impl Rule {
    const fn at(self, dir: &'static str) -> Rule {
        Rule { dir, ..self }
    }
}

fn crate_dir(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, into: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, into);
        } else if path.extension().is_some_and(|e| e == "rs") {
            into.push(path);
        }
    }
}

#[test]
fn pure_crates_depend_on_no_mavlink_runtime_or_serial_port() {
    for rule in &RULES {
        let krate = rule.dir;
        let manifest = std::fs::read_to_string(crate_dir(krate).join("Cargo.toml")).unwrap();
        let table: toml::Table = manifest.parse().unwrap();
        for section in ["dependencies", "dev-dependencies", "build-dependencies"] {
            let Some(deps) = table.get(section).and_then(|d| d.as_table()) else {
                continue;
            };
            for &name in rule.dependencies {
                assert!(
                    !deps.contains_key(name),
                    "{krate}/Cargo.toml [{section}] names {name}: this crate takes typed inputs, no I/O"
                );
            }
        }
    }
}

#[test]
fn pure_crates_read_no_clock_and_name_no_mavlink() {
    let mut checked = 0;
    for rule in &RULES {
        let krate = rule.dir;
        let mut files = Vec::new();
        // Benchmarks read the clock: measuring is their job.
        for dir in ["src", "tests"] {
            let d = crate_dir(krate).join(dir);
            if d.is_dir() {
                sources(&d, &mut files);
            }
        }
        for file in files {
            if file.ends_with("purity.rs") {
                continue; // this file names what it forbids
            }
            let text = std::fs::read_to_string(&file).unwrap();
            for &word in rule.in_sources {
                assert!(
                    !text.contains(word),
                    "{} names {word}: the pure crates read no clock and speak no MAVLink, the \
                     protocol does no I/O",
                    file.display()
                );
            }
            checked += 1;
        }
    }
    assert!(
        checked > 100,
        "only {checked} files found: wrong directories?"
    );
}
