//! The settings file (good, shipped, bad) and the precedence of flag over file over default.
#![allow(clippy::unwrap_used)]

use super::*;
use crate::cli::Cli;
use clap::Parser;

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("autopilot-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_good_file_loads_with_paths_beside_it() {
    let p = write(
        "good.toml",
        "source = \"udp://127.0.0.1:4560\"\ntakeoff_m = 8\nspeed = 20\nflight_csv = \"f.csv\"\nairframe = \"hexa_x\"\n",
    );
    let c = Settings::load(&p).unwrap();
    assert_eq!(c.source.as_deref(), Some("udp://127.0.0.1:4560"));
    assert_eq!(c.takeoff_m, Some(8.0));
    assert_eq!(c.speed.factor(), Ok(Some(20.0)));
    assert_eq!(c.flight_csv, Some(p.parent().unwrap().join("f.csv")));
    assert_eq!(c.airframe, "hexa_x", "a name stays a name");
    let c = Settings::load(&write("max.toml", "speed = \"max\"\n")).unwrap();
    assert_eq!(c.speed.factor(), Ok(None));
}

#[test]
fn the_shipped_example_loads() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../params/autopilot.toml");
    let c = Settings::load(&p).unwrap();
    assert_eq!(c.source.as_deref(), Some("sim"));
    assert!(
        c.params_dir
            .unwrap()
            .join("airframes/quad_x.toml")
            .is_file()
    );
}

#[test]
fn bad_files_name_the_file_the_key_and_the_range() {
    let missing = std::env::temp_dir().join("autopilot-no-such-config.toml");
    let e = Settings::load(&missing).unwrap_err().to_string();
    assert!(
        e.contains("autopilot-no-such-config.toml") && e.contains("cannot read"),
        "{e}"
    );
    for (name, text, says) in [
        ("unknown.toml", "takeof_m = 5\n", "unknown field `takeof_m`"),
        ("type.toml", "takeoff_m = \"high\"\n", "takeoff_m"),
        (
            "range.toml",
            "takeoff_m = 500\n",
            "`takeoff_m`: 500 is out of range [1, 100] m",
        ),
        (
            "hover.toml",
            "hover_s = -1\n",
            "`hover_s`: -1 is out of range [0, 604800] s",
        ),
        (
            "inst.toml",
            "instance = 300\n",
            "`instance`: 300 is out of range [0, 250]",
        ),
        (
            "speed.toml",
            "speed = \"fast\"\n",
            "`speed`: \"fast\" is neither",
        ),
        ("zero.toml", "speed = 0\n", "`speed`: 0 is out of range"),
        (
            "loop.toml",
            "loop_hz = 5000\n",
            "`loop_hz`: 5000 is out of range [50, 2000] Hz",
        ),
        (
            "spin.toml",
            "loop_spin_us = -3\n",
            "`loop_spin_us`: -3 is out of range [0, 1000] µs",
        ),
        (
            "sensors.toml",
            "sensors = \"perfect\"\n",
            "`sensors`: \"perfect\" is not",
        ),
        ("syntax.toml", "takeoff_m = = 5\n", "syntax.toml"),
    ] {
        let e = Settings::load(&write(name, text)).unwrap_err().to_string();
        assert!(e.contains(name), "{name}: names the file: {e}");
        assert!(e.contains(says), "{name}: {e}");
    }
}

#[test]
fn flags_win_over_the_file_which_wins_over_the_defaults() {
    let dir = std::env::temp_dir().join(format!("autopilot-settings-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("autopilot.toml");
    std::fs::write(
        &file,
        "source = \"udp://127.0.0.1:4560\"\ntakeoff_m = 8\nhover_s = 3\nspeed = \"max\"\n",
    )
    .unwrap();
    let cli = Cli::parse_from([
        "autopilot",
        "--config",
        file.to_str().unwrap(),
        "--takeoff",
        "3",
    ]);
    let s = Settings::resolve(&cli.flight).unwrap();
    assert_eq!(s.source(), "udp://127.0.0.1:4560");
    assert_eq!(
        (s.takeoff_m, s.hover_s, s.realtime_factor().unwrap()),
        (Some(3.0), 3.0, None)
    );
    assert_eq!((s.seed, s.instance, s.airframe.as_str()), (1, 0, "quad_x"));
    let cli = Cli::parse_from(["autopilot", "--config", file.to_str().unwrap(), "--sim"]);
    assert_eq!(Settings::resolve(&cli.flight).unwrap().source(), "sim");
}

#[test]
fn a_flag_given_overwrites_its_key_and_none_turns_logs_and_the_store_off() {
    let file = write(
        "paths.toml",
        "source = \"sim\"\nmavlink = [\"udpin://0.0.0.0:14560\"]\nlog_dir = \"l\"\nparam_store = \"p.toml\"\nseed = 4\nsensors = \"noisy\"\n",
    );
    let dir = file.parent().unwrap();
    let from_file = Settings::load(&file).unwrap();
    assert_eq!(from_file.log_dir(), Some(dir.join("l").as_path()));
    assert_eq!(from_file.param_store(3), Some(dir.join("p.toml")));
    assert_eq!(
        from_file.named_param_store(),
        Some(dir.join("p.toml").as_path())
    );
    assert_eq!(from_file.mavlink, ["udpin://0.0.0.0:14560"]);
    let cli = Cli::parse_from([
        "autopilot",
        "--config",
        file.to_str().unwrap(),
        "--log-dir",
        "none",
        "--param-store",
        "none",
        "--mavlink",
        "none",
        "--seed",
        "9",
    ]);
    let s = Settings::resolve(&cli.flight).unwrap();
    assert_eq!((s.log_dir(), s.param_store(3)), (None, None));
    assert_eq!(s.named_param_store(), None);
    assert_eq!(s.mavlink, ["none"]);
    assert_eq!((s.seed, s.sensors.as_str()), (9, "noisy"));
    let s = Settings::resolve(&Cli::parse_from(["autopilot", "--sim"]).flight).unwrap();
    assert_eq!(s.log_dir(), Some(Path::new("logs")));
    assert_eq!(
        s.param_store(2),
        Some(PathBuf::from("autopilot-params-2.toml"))
    );
    assert_eq!(s.mavlink, crate::gcs_links::DEFAULT_ENDPOINTS);
}

#[test]
fn an_airframe_is_a_name_in_the_params_dir_or_a_file() {
    let dir = Path::new("p");
    assert_eq!(
        airframe_path("hexa_x", dir),
        Path::new("p/airframes/hexa_x.toml")
    );
    assert_eq!(airframe_path("my/a.toml", dir), Path::new("my/a.toml"));
    assert_eq!(params_path(None, dir), Path::new("p/flight.toml"));
    assert_eq!(
        params_path(Some(Path::new("f.toml")), dir),
        Path::new("f.toml")
    );
}
