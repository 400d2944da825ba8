//! `sitl`: the multirotor simulator process.
//!
//! Runs the physics and sensors of `sitl-core` behind the MAVLink HIL link of docs/conventions.md:
//! sends `HIL_SENSOR`, `HIL_GPS`, `ESC_STATUS` and `HIL_STATE_QUATERNION` to the autopilot's UDP
//! port (or over a serial line, or to PX4 connected over TCP) and steps physics on its
//! `HIL_ACTUATOR_CONTROLS`, in lockstep (default) or real time. With
//! `--open-loop` it flies the scenario's actuator script with no autopilot at all.

mod device_line;
mod gps_device;
mod jsbsim;
mod json_physics;
mod rc_device;
mod run;
mod tcp;
mod transport;

use anyhow::{Context, Result, bail};
use clap::{Parser, ValueEnum};
use sitl_core::scenario::Scenario;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::{Airframe, Integrator};
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;

/// How simulation time relates to wall time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// Physics advances only when the autopilot has answered the last sensor frame; the
    /// simulation clock is the autopilot's clock. As fast as the autopilot allows.
    Lockstep,
    /// Physics advances with the wall clock (times `--speed`); the latest actuator command is used.
    Realtime,
}

/// Who moves the rigid body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Physics {
    /// The built-in rigid body (the scenario's integrator), flat ground.
    Builtin,
    /// A JSBSim process (rigid body, gravity, Earth and ground contact), stepped in lockstep;
    /// rotors, motors, battery, drag, wind and sensors stay the built-in models.
    Jsbsim,
}

/// Multirotor simulator: physics, sensors and a MAVLink HIL link over UDP.
#[derive(Debug, Parser)]
#[command(name = "sitl", version, about, long_about = None, args_override_self = true)]
pub struct SitlCli {
    /// Scenario file (TOML): airframe, initial state, sensors, wind, seed, duration, events,
    /// open-loop script. Without one: the airframe rests at home, typical sensors, no wind.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Airframe: a name in PARAMS_DIR/airframes/ (quad_x, quad_plus, hexa_x, octa_x, dodeca) or a
    /// path to a .toml file. Overrides the scenario's.
    #[arg(long, value_name = "NAME|FILE")]
    pub airframe: Option<String>,
    /// Directory that holds airframes/ [default: ./params, else the installed
    /// PREFIX/share/autopilot/params beside PREFIX/bin, else the source tree's params/].
    #[arg(long, value_name = "DIR")]
    pub params_dir: Option<PathBuf>,
    /// Fly the scenario's open-loop actuator script with no autopilot (a physics demo).
    #[arg(long)]
    pub open_loop: bool,
    /// The autopilot's HIL address; its port is offset by --instance.
    #[arg(long, default_value = "127.0.0.1:4560", value_name = "ADDR")]
    pub autopilot: SocketAddr,
    /// Instance number N: talks to autopilot port 4560 + N, and its home is 3 N m east of the
    /// scenario's (several vehicles on one machine, side by side).
    #[arg(short = 'i', long, default_value_t = 0)]
    pub instance: u16,
    /// Speak ArduPilot's JSON physics interface instead of the HIL link, as a physics for
    /// ArduPilot's SITL (`--model JSON`) or `autopilot --source json://…`: listen on ADDR (its
    /// port offset by 10 × --instance) for servo packets, step one exchange (--hil-rate) per new
    /// packet with its PWM as the rotor commands (channel k, rotor k), and reply with the state
    /// as JSON (the IMU, position, velocity, quaternion, battery). Lockstep: the world waits for
    /// the next packet [default address: 127.0.0.1:9002].
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:9002",
          conflicts_with_all = ["serial", "tcp", "open_loop", "control"])]
    pub json: Option<SocketAddr>,
    /// Listen for the autopilot on TCP, as PX4's SITL start-up connects to its simulator
    /// (`simulator_mavlink start -c 4560+i`): ADDR's port offset by --instance, one autopilot
    /// at a time, the HIL messages framed in the stream. From the autopilot's first word to its
    /// first actuator command the clock runs in real time (times --speed), as PX4 boots on the
    /// simulator's time; then lockstep (--mode). It may set the ground truth's rate
    /// (SET_MESSAGE_INTERVAL) [default address: 127.0.0.1:4560].
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:4560",
          conflicts_with_all = ["serial", "open_loop"])]
    pub tcp: Option<SocketAddr>,
    /// Talk over a serial line instead of UDP, playing the flight board: a device such as
    /// /dev/ttyUSB0, or `pty` to open a new pseudo-terminal pair and print the autopilot's end
    /// (`sitl serial: /dev/pts/N`) for `autopilot --source serial:///dev/pts/N`.
    #[arg(long, value_name = "DEVICE|pty")]
    pub serial: Option<String>,
    /// Play a GPS receiver on a serial port instead of sending HIL_GPS: `m8`, `m9`, `m10`,
    /// `f9p` (a u-blox of that generation, at its power-on defaults, answering its
    /// configuration) or `nmea` (NMEA 0183 only, 5 Hz at 38 400 baud), on a new pseudo-terminal
    /// (printed as `sitl gps: /dev/pts/N`, for `autopilot --gps serial:///dev/pts/N`) or
    /// `MODEL:/dev/ttyUSB1`.
    #[arg(long, value_name = "MODEL[:DEVICE]", conflicts_with_all = ["open_loop", "json"])]
    pub gps_device: Option<String>,
    /// Play an RC receiver on a serial port, its transmitter flown by the scenario's pilot
    /// script ([[pilot]]): `crsf` (ExpressLRS) or `sbus`, on a new pseudo-terminal (printed as
    /// `sitl rc: /dev/pts/N`, for `autopilot --rc serial:///dev/pts/N?protocol=crsf`) or
    /// `PROTOCOL:/dev/ttyUSB2`.
    #[arg(long, value_name = "PROTOCOL[:DEVICE]", conflicts_with_all = ["open_loop", "json"])]
    pub rc_device: Option<String>,
    /// Baud rate of --serial (a pseudo-terminal ignores it).
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// Also listen for a ground station or script on this UDP address (its port offset by
    /// --instance) to change the weather while flying: SIM_WIND_SPD, SIM_WIND_DIR, SIM_WIND_TURB,
    /// SIM_GUST_* through the MAVLink parameter protocol.
    #[arg(long, value_name = "ADDR")]
    pub control: Option<SocketAddr>,
    /// Local UDP address to bind.
    #[arg(long, default_value = "127.0.0.1:0", value_name = "ADDR")]
    pub bind: SocketAddr,
    /// Pacing: lockstep with the autopilot, or real time.
    #[arg(long, value_enum, default_value_t = Mode::Lockstep)]
    pub mode: Mode,
    /// Real-time factor, e.g. 1, 20, or "max": the pace of --mode realtime (default 1); in
    /// lockstep and --open-loop a cap (default: as fast as the autopilot answers, or as the
    /// physics goes), so that a lockstep run can be watched, or flown by a script that waits on
    /// the wall clock, without the pace of either side changing the flight.
    #[arg(long, value_name = "FACTOR|max")]
    pub speed: Option<String>,
    /// HIL exchange rate (Hz): one sensor frame out and one actuator command in per exchange.
    /// Physics runs at the scenario's rate; the IMU is averaged over each exchange interval.
    #[arg(long, default_value_t = 250.0, value_name = "HZ")]
    pub hil_rate: f64,
    /// Lockstep: wall-clock time (ms) to wait for an answer before stepping with the last
    /// command; every such timeout is counted and reported.
    #[arg(long, default_value_t = 1000, value_name = "MS")]
    pub timeout_ms: u64,
    /// Give up if no autopilot has answered within this many wall-clock seconds (0 = wait forever).
    #[arg(long, default_value_t = 0.0, value_name = "S")]
    pub connect_timeout: f64,
    /// Simulated seconds to run (overrides the scenario).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Seed of every random process (overrides the scenario).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Sensor preset: ideal, typical, noisy, realistic or uncalibrated (overrides the scenario).
    #[arg(long, value_name = "PRESET")]
    pub sensors: Option<String>,
    /// Who moves the rigid body: the built-in physics or JSBSim (its rate is the physics rate).
    #[arg(long, value_enum, default_value_t = Physics::Builtin)]
    pub physics: Physics,
    /// For --physics jsbsim: a Python with the `jsbsim` module (the pinned PyPI jsbsim==1.3.3),
    /// which runs the bridge that steps JSBSim in-process.
    #[arg(long, default_value = "python3", value_name = "PYTHON")]
    pub jsbsim_python: PathBuf,
    /// Integrator: rk4, exp_map, hypersphere, euler_cromer, second_derivative (overrides the scenario).
    #[arg(long, value_name = "NAME")]
    pub integrator: Option<String>,
    /// Physics rate in Hz (overrides the scenario).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// Write ground truth (position, velocity, attitude, rates, rotor speeds) to this CSV file.
    #[arg(long, value_name = "FILE")]
    pub truth_csv: Option<PathBuf>,
    /// Rows per simulated second in the truth CSV.
    #[arg(long, default_value_t = 100.0, value_name = "HZ")]
    pub truth_rate: f64,
    /// Print a status line every this many simulated seconds (0: only the summary).
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub status_interval: f64,
}

fn params_dir(cli: &SitlCli) -> PathBuf {
    sitl_core::airframe::config::params_dir(cli.params_dir.as_deref())
}

/// The scenario after command-line overrides.
fn load_scenario(cli: &SitlCli) -> Result<Scenario> {
    let dir = params_dir(cli).join("airframes");
    let mut scenario = match &cli.scenario {
        Some(path) => Scenario::load(path, &dir)?,
        None => {
            let name = cli.airframe.as_deref().unwrap_or("quad_x");
            let path = sitl_core::scenario::resolve_airframe(name, std::path::Path::new("."), &dir);
            Scenario::basic(Airframe::load(&path)?, 10.0)
        }
    };
    if let (Some(name), Some(_)) = (&cli.airframe, &cli.scenario) {
        let path = sitl_core::scenario::resolve_airframe(name, std::path::Path::new("."), &dir);
        scenario.airframe = Airframe::load(&path)?;
    }
    if let Some(d) = cli.duration {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration must be > 0 s, got {d}");
        }
        scenario.duration_s = d;
    }
    if let Some(s) = cli.seed {
        scenario.sim.seed = s;
    }
    scenario.sim.home = sitl_core::geo::home_for_instance(&scenario.sim.home, cli.instance);
    if let Some(p) = &cli.sensors {
        let preset = SensorPreset::from_name(p).with_context(|| {
            format!("--sensors must be ideal, typical, noisy, realistic or uncalibrated, got {p:?}")
        })?;
        scenario.sim.sensors = SensorConfig::preset(preset);
    }
    if let Some(i) = &cli.integrator {
        scenario.sim.integrator = Integrator::from_name(i).with_context(|| {
            let names: Vec<&str> = Integrator::ALL.iter().map(|i| i.name()).collect();
            format!(
                "--integrator must be one of {}, got {i:?}",
                names.join(", ")
            )
        })?;
    }
    if let Some(r) = cli.rate {
        if !(20.0..=10_000.0).contains(&r) {
            bail!("--rate must be within [20, 10000] Hz, got {r}");
        }
        scenario.sim.dt_s = 1.0 / r;
    }
    Ok(scenario)
}

/// Parsed `--speed`: `None` for as fast as possible (lockstep and open loop unless told).
fn speed(cli: &SitlCli) -> Result<Option<f64>> {
    let given = match cli.speed.as_deref() {
        None if cli.mode == Mode::Realtime => return Ok(Some(1.0)),
        None | Some("max") => return Ok(None),
        Some(given) => given,
    };
    match given.parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 && f <= 10_000.0 => Ok(Some(f)),
        _ => bail!("--speed must be a factor in (0, 10000] or \"max\", got {given:?}"),
    }
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr)
        .init();
    let cli = SitlCli::parse();
    match try_main(&cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("sitl: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn try_main(cli: &SitlCli) -> Result<()> {
    let scenario = load_scenario(cli)?;
    if !(cli.hil_rate.is_finite() && cli.hil_rate >= 10.0) {
        bail!("--hil-rate must be at least 10 Hz, got {}", cli.hil_rate);
    }
    let speed = speed(cli)?;
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, std::sync::atomic::Ordering::SeqCst))
            .context("installing the Ctrl-C (and SIGTERM, SIGHUP) handler")?;
    }
    let summary = if cli.open_loop {
        if scenario.open_loop.is_empty() {
            bail!("--open-loop needs a scenario with an [[open_loop]] script");
        }
        run::open_loop(&scenario, cli, speed, &stop)?
    } else if cli.json.is_some() {
        json_physics::run(&scenario, cli, speed, &stop)?
    } else {
        run::hil(&scenario, cli, speed, &stop)?
    };
    // A closed stdout (a reader that went away) is no reason to fail a finished run.
    let _ = writeln!(std::io::stdout(), "{summary}");
    Ok(())
}
