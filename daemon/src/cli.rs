//! The command line (clap): a flight's flags ([`FlightArgs`], applied over the `--config` file by
//! [`crate::settings::Settings::resolve`]) and the subcommands ([`Command`]).

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// A MAVLink multirotor autopilot.
#[derive(Debug, Parser)]
#[command(
    name = "autopilot",
    version,
    about,
    arg_required_else_help = true,
    args_override_self = true
)]
pub struct Cli {
    /// The flight's flags.
    #[command(flatten)]
    pub flight: FlightArgs,
    /// A subcommand instead of a flight.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// A flight's flags; each one given wins over the `--config` file.
#[derive(Debug, Default, Args)]
pub struct FlightArgs {
    /// Settings file (TOML): every key mirrors a flag below (source, gps, rc, instance, count,
    /// airframe, params, params_dir, takeoff_m, hover_s, speed, seed, sensors, truth_csv,
    /// scenario, sim_control, paused, flight_csv, log_dir, tlog, ulog, ftp_root, ftp_read_only,
    /// loop_hz, loop_spin_us, loop_cpu, loop_stats_s, mavlink, param_store); flags given here
    /// win. Paths in it are relative to its directory.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Fly in the embedded simulator (the physics of `sitl`, in-process, behind the same HIL
    /// messages as an external simulator). Short for `--source sim`.
    #[arg(long, conflicts_with = "source")]
    pub sim: bool,
    /// Sensor source: `sim` (embedded simulator), `udp://127.0.0.1:4560` (a simulator process such
    /// as `sitl`; the port is offset by --instance), `json://127.0.0.1:9002` (a physics speaking
    /// ArduPilot's JSON interface, such as `sitl --json`; the port is offset by 10 × --instance;
    /// `?channels=3,1,4,2` puts rotor k on that servo channel; --sensors and --seed make the
    /// magnetometer, barometer and GPS it lacks) or `serial:///dev/ttyUSB0?baud=921600` (a
    /// flight board streaming HIL messages).
    #[arg(long, value_name = "URL")]
    pub source: Option<String>,
    /// A GPS receiver on a serial port, instead of the sensor source's GPS:
    /// `serial:///dev/ttyUSB1?baud=115200&protocol=ublox&rate=5` (a u-blox M8, M9, M10 or F9P,
    /// found at any baud, moved to `baud` and configured for `rate` solutions a second) or
    /// `…?protocol=nmea&baud=9600` (any NMEA 0183 receiver, read as it is).
    #[arg(long, value_name = "URL")]
    pub gps: Option<String>,
    /// An RC receiver on a serial port: `serial:///dev/ttyS2?protocol=crsf` (ExpressLRS or
    /// TBS Crossfire, 420 000 baud) or `…?protocol=sbus` (100 000 baud 8E2, inverted on the
    /// wire); its sticks and switches fly as PX4's RC_MAP_*, COM_FLTMODE* and COM_RC_* say.
    #[arg(long, value_name = "URL")]
    pub rc: Option<String>,
    /// Instance number N: the UDP sensor port is offset by N (several vehicles on one machine)
    /// and the vehicle speaks as MAVLink system N + 1 [default: 0].
    #[arg(short = 'i', long, value_parser = clap::value_parser!(u16).range(0..=250))]
    pub instance: Option<u16>,
    /// Fly this many vehicles together in the embedded simulator, in one process on one
    /// clock: instances --instance … --instance + N − 1, each its own MAVLink system,
    /// ground-station ports, seed (--seed + k), parameter store and logs, and its home 3 m east
    /// of the one before (as `sitl -i`) [default: 1].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=251))]
    pub count: Option<u16>,
    /// Airframe: a name in PARAMS_DIR/airframes/ (quad_x, quad_plus, hexa_x, octa_x, dodeca) or a
    /// path to a .toml file. With an external simulator it must be the airframe it simulates
    /// [default: quad_x].
    #[arg(long, value_name = "NAME|FILE")]
    pub airframe: Option<String>,
    /// Flight parameters file [default: PARAMS_DIR/flight.toml].
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Directory holding airframes/ and flight.toml [default: ./params, else the installed
    /// PREFIX/share/autopilot/params beside PREFIX/bin, else the source tree's].
    #[arg(long, value_name = "DIR")]
    pub params_dir: Option<PathBuf>,
    /// Fly on its own, without a ground station: arm as soon as the estimator is ready, take
    /// off to this altitude (m above the start, 1 to 100), hover --hover seconds, land, and end
    /// the run once disarmed [default: wait for ground-station commands].
    #[arg(long, value_name = "M")]
    pub takeoff: Option<f64>,
    /// With --takeoff: hover time before landing (s, 0 to 604800: a week, for a tethered vehicle or a soak) [default: 10].
    #[arg(long, value_name = "S")]
    pub hover: Option<f64>,
    /// Embedded simulator: real-time factor, 1 (real time), 20, or "max" (as fast as lockstep
    /// allows) [default: 1].
    #[arg(long, value_name = "FACTOR|max")]
    pub speed: Option<String>,
    /// Embedded simulator: seed of the simulated sensors [default: 1].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Embedded simulator: sensor quality, ideal, typical, noisy, realistic or uncalibrated (as `sitl --sensors`)
    /// [default: typical].
    #[arg(long, value_name = "PRESET")]
    pub sensors: Option<String>,
    /// Embedded simulator: write ground truth to this CSV file (100 rows per simulated second,
    /// the same columns as `sitl --truth-csv`).
    #[arg(long, value_name = "FILE")]
    pub truth_csv: Option<PathBuf>,
    /// Embedded simulator: fly in the world of this scenario file (as `sitl --scenario`: its
    /// wind, turbulence, start, battery and timed events); it must name the airframe flown, and
    /// the seed and sensors stay --seed's and --sensors'.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Embedded simulator: its own MAVLink endpoint on this UDP address (the port offset by
    /// --instance), as `sitl --control`: the weather (SIM_WIND_*, SIM_GUST_*), the clock
    /// (SIM_SPEEDUP, SIM_PAUSE, SIM_RUN_S) by the parameter protocol, and the truth
    /// (HIL_STATE_QUATERNION, LOCAL_POSITION_NED) by MAV_CMD_REQUEST_MESSAGE.
    #[arg(long, value_name = "ADDR")]
    pub sim_control: Option<String>,
    /// Embedded simulator: start paused after the first sensor frame, until SIM_PAUSE is set
    /// to 0 (or SIM_RUN_S runs a stretch) on --sim-control.
    #[arg(long)]
    pub paused: bool,
    /// Write the flight data (estimate, set-points, motor commands, loop timing and, from a
    /// simulator, the truth) to this CSV file, one row per sensor frame, or `none` for no CSV
    /// (the ULog holds the same flight) [default: LOG_DIR/<start time>.csv].
    #[arg(long, value_name = "FILE|none")]
    pub flight_csv: Option<PathBuf>,
    /// Where every run leaves its logs, named by its start time (UTC): a MAVLink telemetry log
    /// (`.tlog`: mavlogdump.py, MAVExplorer, QGroundControl), the flight log (`.ulg`, PX4's
    /// ULog: Flight Review, PlotJuggler, pyulog) and the flight-data CSV; `none` for no logs
    /// but those asked for by --tlog, --ulog or --flight-csv [default: ./logs].
    #[arg(long, value_name = "DIR|none")]
    pub log_dir: Option<PathBuf>,
    /// Write the MAVLink telemetry log (every frame sent and every message heard, each after
    /// its 8-byte big-endian Unix time in µs) to this file [default: LOG_DIR/<start time>.tlog].
    #[arg(long, value_name = "FILE")]
    pub tlog: Option<PathBuf>,
    /// Write the flight log in PX4's ULog format to this file [default: LOG_DIR/<start
    /// time>.ulg].
    #[arg(long, value_name = "FILE")]
    pub ulog: Option<PathBuf>,
    /// The directory MAVLink FTP serves (its `/`; the flight logs are also at `@MAV_LOG`), or
    /// `none` to refuse every FTP request [default: LOG_DIR].
    #[arg(long, value_name = "DIR|none")]
    pub ftp_root: Option<PathBuf>,
    /// MAVLink FTP reads only: it creates, writes, renames and removes nothing.
    #[arg(long)]
    pub ftp_read_only: bool,
    /// With a source that does not wait for answers (a flight board, or `?lockstep=false`):
    /// the control loop's rate, 50 to 2000 Hz. It wakes at absolute deadlines, steps on every
    /// sensor frame that arrived, and logs its jitter and overruns [default: 1000].
    #[arg(long, value_name = "HZ")]
    pub loop_hz: Option<f64>,
    /// The part of each loop period before the deadline spent spinning on the clock rather
    /// than sleeping (µs, 0 to 1000): a sleep alone wakes ~60 µs late on Linux [default: 150].
    #[arg(long, value_name = "US")]
    pub loop_spin_us: Option<f64>,
    /// Pin the control loop's thread to this CPU (Linux), away from CPUs that serve periodic
    /// interrupts [default: not pinned].
    #[arg(long, value_name = "N")]
    pub loop_cpu: Option<usize>,
    /// With deadline pacing: how often the control loop logs its rate, jitter (p50, p99, max)
    /// and overruns (s, 0.5 to 3600) [default: 10].
    #[arg(long, value_name = "S")]
    pub loop_stats_s: Option<f64>,
    /// A ground-station endpoint; repeat for several, `none` for none. `udpout://HOST:PORT?bind=LOCAL`
    /// pushes to HOST:PORT from the LOCAL port and answers every peer writing to it;
    /// `udpin://ADDR:PORT` answers every peer writing to it; `tcpin://ADDR:PORT` is a TCP
    /// server. Every port is offset by --instance, but a udpout target marked `shared` (one
    /// ground station hearing every vehicle, as PX4 does it) and a port 0 (any free one; each
    /// endpoint's port is printed as `autopilot endpoint: system=N KIND://ADDR:PORT`).
    /// `mode=onboard` streams at the rates of PX4's onboard set (its MAVSDK link) [default:
    /// udpout://127.0.0.1:14550?bind=18570&shared (QGroundControl, pymavlink, MAVProxy),
    /// udpout://127.0.0.1:14540?bind=14580&mode=onboard (MAVSDK), tcpin://127.0.0.1:5760].
    #[arg(long, value_name = "URL")]
    pub mavlink: Vec<String>,
    /// Where the parameters a ground station changes are kept (applied over the flight
    /// parameters at start; written atomically on every change), or `none` to keep them in
    /// memory only [default: autopilot-params-N.toml in the working directory, N the instance].
    #[arg(long, value_name = "FILE|none")]
    pub param_store: Option<PathBuf>,
    /// MAVLink 2 signing: the 32-byte secret key as 64 hexadecimal digits in FILE. With a key,
    /// unsigned, wrongly signed and replayed frames are refused (but on endpoints marked
    /// `?trusted`) and the vehicle signs what it sends. A missing FILE is no key (signing off)
    /// until a `SETUP_SIGNING` on a trusted endpoint writes it [default: no key, not kept].
    #[arg(long, value_name = "FILE")]
    pub signing_key_file: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the attitude estimator over logged sensor samples (estimator tuning, like PX4's
    /// replay). The input CSV needs a header with at least t,gx,gy,gz,ax,ay,az,mx,my,mz (seconds;
    /// gyro rad/s FRD; specific force m/s² FRD, level at rest z ≈ −9.81; magnetometer FRD in any
    /// consistent unit, empty or nan when not fresh); other columns are ignored. Writes
    /// t,qw,qx,qy,qz,bx,by,bz (q_ned_from_frd and the gyro-bias estimate, rad/s) for every sample.
    Replay {
        /// Input CSV.
        #[arg(long, short)]
        input: PathBuf,
        /// Output CSV.
        #[arg(long, short)]
        output: PathBuf,
        /// Parameter file whose attitude table sets the gains and magnetometer calibration
        /// [default: the built-in defaults, as in params/flight.toml].
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// Calibrate the magnetometer from a log (Castillo (75)–(79): the ellipsoid's offset,
    /// rotation and scale fitted to the raw samples): any CSV with raw FRD columns mx,my,mz,
    /// such as the flight-data CSV of a run in which the vehicle was turned through every
    /// orientation. Writes mag_offset, mag_scale, mag_offdiag and mag_calibration_id into
    /// the [attitude] table of --params (atomically, comments kept), or prints them.
    CalibrateMag {
        /// Input CSV.
        #[arg(long, short)]
        input: PathBuf,
        /// Flight-parameter file to write the calibration into; its ATT_MAG_STR
        /// (mag_intensity_gauss) is the field strength the calibration scales to [default:
        /// print the calibration for the default parameters].
        #[arg(long)]
        params: Option<PathBuf>,
        /// CAL_MAG0_ID to record [default: the file's if set, else 1].
        #[arg(long)]
        device_id: Option<u32>,
    },
    /// Monte-Carlo batch: fly the take-off, hover and landing many times in the embedded
    /// simulator, each run with its own sensor seed, wind, turbulence and fault drawn from the
    /// batch's seed, on every core, with a progress bar; one CSV row of flight-quality figures
    /// per run (landed, failsafe, height, hover errors, attitude-estimate error, tilt, distance,
    /// touchdown and impact speeds) and a summary per fault.
    Batch(Box<BatchArgs>),
}

/// `autopilot batch`'s flags.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BatchArgs {
    /// What else than flying a batch.
    #[command(subcommand)]
    pub action: Option<BatchAction>,
    /// Runs to fly.
    #[arg(long, default_value_t = 100)]
    pub runs: u32,
    /// The first run's number: run i draws from (seed, i), so a run of a batch is flown
    /// again with the batch's seed, `--first i --runs 1`.
    #[arg(long, default_value_t = 0)]
    pub first: u32,
    /// The batch's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads [default: every CPU].
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Airframe: a name in PARAMS_DIR/airframes/ or a .toml file.
    #[arg(long, default_value = "quad_x")]
    pub airframe: String,
    /// Directory holding airframes/ and flight.toml [default: ./params, else the installed
    /// PREFIX/share/autopilot/params beside PREFIX/bin, else the source tree's].
    #[arg(long)]
    pub params_dir: Option<PathBuf>,
    /// Flight parameters file [default: PARAMS_DIR/flight.toml].
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Take-off height (m, 1 to 100).
    #[arg(long, default_value_t = 5.0)]
    pub takeoff: f64,
    /// Hover time (s, 0 to 604800).
    #[arg(long, default_value_t = 20.0)]
    pub hover: f64,
    /// Largest mean wind (m/s): each run's is drawn from 0 to this, from any direction.
    #[arg(long, default_value_t = 5.0)]
    pub wind_max: f64,
    /// Largest turbulence intensity W20 (m/s), drawn likewise.
    #[arg(long, default_value_t = 3.0)]
    pub turbulence_max: f64,
    /// The faults each run's one is drawn from (comma-separated): none, motor (a propeller
    /// at 50–90 %), motor_off, gps (fix lost 5–15 s), mag (0.1–0.3 G for 3–10 s), baro
    /// (silent 2–10 s), gust (3–8 m/s), imu (stuck); each strikes during the hover.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "none,motor,gps,mag,baro,gust"
    )]
    pub faults: Vec<String>,
    /// Sensor quality: ideal, typical, noisy, realistic or uncalibrated.
    #[arg(long, default_value = "typical")]
    pub sensors: String,
    /// Fly only shard K of N of the campaign (K from 0): the runs whose number, counted from
    /// --first, is K modulo N. Its CSV and manifest are merged with the others' by `batch
    /// merge`.
    #[arg(long, value_name = "K/N", conflicts_with = "shard_count")]
    pub shard: Option<String>,
    /// Fly one shard of N, its index K given by the cluster: JOB_COMPLETION_INDEX (a
    /// Kubernetes Indexed Job) or AWS_BATCH_JOB_ARRAY_INDEX (an AWS Batch array job).
    #[arg(long, value_name = "N")]
    pub shard_count: Option<u32>,
    /// The CSV written, its manifest beside it as .json [default: batch-SEED.csv, a shard's
    /// batch-SEED-shard-K-of-N.csv]; an existing directory (or a path ending in /) holds the
    /// default name.
    #[arg(long, short)]
    pub output: Option<PathBuf>,
}

/// `autopilot batch`'s subcommands.
#[derive(Debug, Subcommand)]
pub enum BatchAction {
    /// Join the shards of a campaign into the CSV and manifest the campaign flown whole
    /// writes (the same rows, byte for byte, in run order); refuses shards of two campaigns
    /// or builds, a CSV that is not what its manifest says, and runs found twice or not at
    /// all.
    Merge {
        /// Shard manifests (.json), their CSVs, or directories holding them.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// The merged CSV, its manifest beside it as .json [default: batch-SEED.csv].
        #[arg(long, short)]
        output: Option<PathBuf>,
    },
}
