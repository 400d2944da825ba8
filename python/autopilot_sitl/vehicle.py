"""Vehicles: one `autopilot` process flying the embedded simulator in lockstep (a swarm: one
process flying N), or, in real time, a `sitl` process and an autopilot beside it. Every port is
bound by the process itself on 127.0.0.1 port 0 and read back from its output, so vehicles
started side by side (pytest -n) never take each other's ports."""

import re
import signal
import socket
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ._binaries import binary
from ._process import Child
from .sim_control import ControlError, SimControl, Truth

__all__ = ["Logs", "Swarm", "Truth", "Vehicle", "VehicleError"]

_ENDPOINT = re.compile(r"autopilot endpoint: system=(\d+) (\w+)://(\S+)")


class VehicleError(RuntimeError):
    """A vehicle did not start, refused what it was asked, or ended badly; says why, with the
    end of its log."""


@dataclass(frozen=True)
class Logs:
    """Where a vehicle's run left its logs: the flight log (ULog: pyulog, Flight Review,
    PlotJuggler), the telemetry log (.tlog: MAVExplorer, QGroundControl), the flight-data CSV and
    what the processes printed."""

    directory: Path
    ulog: Optional[Path]
    tlog: Optional[Path]
    csv: Optional[Path]
    daemon: Path
    simulator: Optional[Path] = None

    def paths(self) -> dict:
        """Every log that exists, by kind."""
        kinds = {"ulog": self.ulog, "tlog": self.tlog, "csv": self.csv, "daemon": self.daemon,
                 "simulator": self.simulator}
        return {k: p for k, p in kinds.items() if p is not None and p.exists()}


def _speed_factor(speed) -> Optional[float]:
    """Simulated seconds per wall-clock second; None for "max" (as fast as it can)."""
    if speed == "max" or speed is None:
        return None
    speed = float(speed)
    if not 0.01 <= speed <= 10000:
        raise ValueError(f"speed must be in [0.01, 10000] or 'max', got {speed}")
    return speed


def _speed_arg(speed) -> str:
    """`--speed`'s argument."""
    factor = _speed_factor(speed)
    return "max" if factor is None else repr(factor)


def _param_store(path: Path, params: dict) -> None:
    """The parameter overrides as the autopilot's parameter store (MAVLink names and values),
    applied over its flight parameters at start."""
    lines = ["# parameter overrides (autopilot_sitl)"]
    for name, value in params.items():
        if not re.fullmatch(r"[A-Z][A-Z0-9_]{0,15}", name):
            raise ValueError(f"{name!r} is not a MAVLink parameter name")
        lines.append(f"{name} = {float(value)!r}")
    path.write_text("\n".join(lines) + "\n")


class _Member:
    """What every vehicle offers: its system id, its ground-station endpoints' addresses."""

    def __init__(self, system_id: int, endpoints: dict):
        self.system_id = system_id
        self._endpoints = endpoints
        self._server_port = None

    @property
    def mavsdk_server_port(self) -> int:
        """A TCP port for MAVSDK-Python's own gRPC server (`mavsdk_grpc.System(port=...)`),
        held for the vehicle's life: bound here with SO_REUSEPORT, which gRPC's server also
        sets, so mavsdk_server binds it beside this socket while no other program is given it.
        Two tests side by side each start a mavsdk_server; on its default port (50051) they
        would clash."""
        if self._server_port is None:
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            s.bind(("127.0.0.1", 0))
            self._server_port = s
        return self._server_port.getsockname()[1]

    def _release(self):
        if self._server_port is not None:
            self._server_port.close()
            self._server_port = None

    @property
    def mavsdk_url(self) -> str:
        """MAVSDK's connection string (`System().connect(system_address=...)`,
        `Mavsdk.add_any_connection`): MAVSDK sends to the vehicle's UDP port, whose streams are
        PX4's onboard set, as PX4's SITL gives MAVSDK."""
        return f"udpout://{self._endpoints['udpin']}"

    @property
    def pymavlink_url(self) -> str:
        """pymavlink's (and MAVProxy's `--master`) connection string: the vehicle's TCP server,
        which streams at once to a client that connects, as ArduPilot's SITL on port 5760."""
        return f"tcp:{self._endpoints['tcpin']}"


class _Run:
    """A run of processes: stopped (and killed if it will not stop) when done, as a context
    manager too; its logs stay in its `log_dir`."""

    def stop(self, timeout_s: float = 60.0, land: bool = True):
        raise NotImplementedError

    def kill(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Stops the run, killing it if it will not stop."""
        try:
            self.stop()
        except VehicleError:
            pass
        finally:
            self.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            self.stop()
        finally:
            self.kill()


class Vehicle(_Member, _Run):
    """One vehicle in the embedded simulator (`lockstep=True`, the default: simulated time runs
    at `speed` × the wall clock, or as fast as it can with "max", and can be paused) or in a
    `sitl` process in real time (`lockstep=False`: its clock is the wall clock's times `speed`).

    `airframe`: quad_x, quad_plus, hexa_x, octa_x, dodeca or a .toml file; `sensors`: ideal,
    typical, noisy, realistic, uncalibrated; `seed`: the sensors' noise; `wind`: (speed m/s, from
    degrees) or None; `turbulence`: Dryden W20 (m/s); `scenario`: a scenario file (its wind,
    start, battery, timed events); `params`: {MAVLink name: value} over the flight parameters;
    `log_dir`: where the logs go and stay (by default a new directory in the system's temporary
    one, `autopilot-sitl-*`); `args`: more command-line
    flags of `autopilot`. Started at once; ready (heartbeat, health ok) when the constructor
    returns."""

    def __init__(self, airframe="quad_x", *, sensors="typical", seed=1, speed=10, wind=None,
                 turbulence=0.0, scenario=None, params=None, lockstep=True, log_dir=None,
                 args=(), ready_timeout_s=30.0):
        self.airframe, self.speed, self.lockstep = airframe, speed, lockstep
        self._server_port = None
        if log_dir is None:
            log_dir = tempfile.mkdtemp(prefix="autopilot-sitl-")
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.summary = None
        self.sim = None
        self.control = None
        store = self.log_dir / "params.toml"
        _param_store(store, params or {})
        world = ["--airframe", str(airframe), "--seed", str(int(seed)), "--sensors", sensors]
        if scenario is not None:
            world += ["--scenario", str(Path(scenario).resolve())]
        common = [
            *world, "--mavlink", "udpin://127.0.0.1:0?mode=onboard",
            "--mavlink", "tcpin://127.0.0.1:0", "--log-dir", str(self.log_dir),
            "--param-store", str(store), "--ftp-root", str(self.log_dir), *map(str, args)]
        if lockstep:
            # Unpaced and paused until the weather is set, unpaced until ready, then `speed`.
            self.ap = Child([binary("autopilot"), "--sim", "--speed", "max", "--sim-control",
                             "127.0.0.1:0", "--paused", *common], self.log_dir / "autopilot.log")
            control = self._line("autopilot sim-control:", ready_timeout_s)
            self.control = SimControl(control.rsplit("//", 1)[1])
        else:
            self.ap = Child([binary("autopilot"), "--source", "udp://127.0.0.1:0?lockstep=false",
                             *common], self.log_dir / "autopilot.log")
            link = self._line("autopilot sensor-link:", ready_timeout_s).rsplit("//", 1)[1]
            sim_args = ["--mode", "realtime", "--speed", _speed_arg(speed), "--autopilot", link,
                        "--control", "127.0.0.1:0", "--status-interval", "0",
                        "--duration", "1e9", *world[:2], "--seed", str(int(seed)),
                        "--sensors", sensors]
            if scenario is not None:
                sim_args += ["--scenario", str(Path(scenario).resolve())]
            self.sim = Child([binary("sitl"), *sim_args], self.log_dir / "sitl.log")
            control = self._line("sitl control:", ready_timeout_s, self.sim)
            self.control = SimControl(control.rsplit("//", 1)[1])
        try:
            if wind is not None or turbulence:
                self.set_wind(*(wind or (0.0, 0.0)), turbulence=turbulence)
            if lockstep:
                self.control.set("SIM_PAUSE", 0)
            endpoints = {}
            for line in self.ap.wait_line("autopilot endpoint:", ready_timeout_s, 2) or []:
                m = _ENDPOINT.match(line)
                endpoints[m.group(2)] = m.group(3)
            self._line("autopilot ready:", ready_timeout_s)
            if lockstep and speed != "max":
                self.set_speed(speed)
        except BaseException:
            self.kill()
            raise
        super().__init__(1, endpoints)

    def _line(self, prefix, timeout_s, child=None):
        child = child or self.ap
        found = child.wait_line(prefix, timeout_s)
        if found is None:
            self.kill()
            what = "ended" if not child.running() else f"said nothing in {timeout_s} s"
            raise VehicleError(
                f"{child.args[0]} {what} before '{prefix}'; its log ({child.log}):\n"
                f"{child.tail()}")
        return found[0]

    # The clock (lockstep only).

    def _clock(self):
        if not self.lockstep:
            raise VehicleError("a real-time simulator's clock is the wall clock's: only a "
                               "lockstep vehicle pauses, advances or changes speed")
        return self.control

    def pause(self) -> None:
        """Holds simulated time (the autopilot waits for its next sensor frame)."""
        self._clock().set("SIM_PAUSE", 1)

    def resume(self) -> None:
        """Lets simulated time run again at the vehicle's speed."""
        self._clock().set("SIM_PAUSE", 0)

    def advance(self, seconds: float, timeout_s: float = 60.0) -> None:
        """While paused: runs `seconds` of simulated time as fast as it can, and holds again."""
        c = self._clock()
        if c.get("SIM_PAUSE") != 1:
            raise VehicleError("advance() steps a paused clock: pause() first")
        c.set("SIM_RUN_S", seconds)
        c.wait_value("SIM_RUN_S", 0.0, timeout_s)

    def set_speed(self, speed) -> None:
        """Simulated seconds per wall-clock second ("max": as fast as it can)."""
        self._clock().set("SIM_SPEEDUP", _speed_factor(speed) or 0.0)
        self.speed = speed

    # The world.

    def set_wind(self, speed_m_s: float, from_deg: float, turbulence: Optional[float] = None):
        """The mean wind (m/s, from `from_deg`: 0 north, 90 east) and, if given, Dryden
        turbulence (W20, m/s)."""
        self.control.set("SIM_WIND_SPD", speed_m_s)
        self.control.set("SIM_WIND_DIR", from_deg % 360.0)
        if turbulence is not None:
            self.control.set("SIM_WIND_TURB", turbulence)

    def gust(self, peak_m_s: float, from_deg: float, length_s: float = 2.0) -> None:
        """A `1 − cos` gust starting now."""
        self.control.set("SIM_GUST_DIR", from_deg % 360.0)
        self.control.set("SIM_GUST_T", length_s)
        self.control.set("SIM_GUST_SPD", peak_m_s)

    def truth(self) -> Truth:
        """The simulator's state now."""
        try:
            return self.control.truth()
        except ControlError as e:
            raise VehicleError(f"{e}; the autopilot's log:\n{self.ap.tail()}") from e

    # The end.

    @property
    def logs(self) -> Logs:
        """The run's logs (named by its start time in the log directory)."""
        def newest(pattern):
            found = sorted(self.log_dir.glob(pattern))
            return found[-1] if found else None
        return Logs(self.log_dir, newest("*.ulg"), newest("*.tlog"), newest("*.csv"),
                    self.ap.log, self.sim.log if self.sim else None)

    def stop(self, timeout_s: float = 60.0, land: bool = True) -> dict:
        """Ends the run as Ctrl-C does (in the air it lands first; logs flushed), or with
        `land=False` as SIGTERM does (at once, wherever it is), and returns the flight summary
        (`autopilot summary:` as a dict of strings); killed if not ended within `timeout_s`, and
        VehicleError if it ended in an error."""
        if self.summary is not None:
            return self.summary
        code = self.ap.interrupt(timeout_s, signal.SIGINT if land else signal.SIGTERM)
        if self.sim is not None:
            self.sim.interrupt(10)
        if self.control is not None:
            self.control.close()
        found = [line for line in self.ap.lines if line.startswith("autopilot summary:")]
        if code != 0 or not found:
            raise VehicleError(f"the autopilot ended with status {code}; its log "
                               f"({self.ap.log}):\n{self.ap.tail()}")
        self.summary = _fields(found[-1])
        return self.summary

    def kill(self) -> None:
        """Ends every process of the vehicle at once (SIGKILL)."""
        for child in (getattr(self, "ap", None), self.sim):
            if child is not None:
                child.kill()
        if self.control is not None:
            self.control.close()
        self._release()



class Swarm(_Run):
    """N vehicles flown together in one autopilot process on one clock (`--count N`): systems 1
    … N, each 3 m east of the one before, with its own seed (`seed` + k), ground-station ports
    and logs. Its clock runs at `speed`; pausing it, the weather and the truth are a single
    vehicle's (Vehicle)."""

    def __init__(self, count: int, airframe="quad_x", *, sensors="typical", seed=1, speed=10,
                 scenario=None, log_dir=None, args=(), ready_timeout_s=30.0):
        if not 1 <= count <= 251:
            raise ValueError(f"a swarm has 1 to 251 vehicles, not {count}")
        if log_dir is None:
            log_dir = tempfile.mkdtemp(prefix="autopilot-swarm-")
        self.log_dir = Path(log_dir)
        self.summaries = None
        extra = ["--scenario", str(Path(scenario).resolve())] if scenario is not None else []
        self.ap = Child([
            binary("autopilot"), "--sim", "--count", str(count), "--airframe", str(airframe),
            "--seed", str(int(seed)), "--sensors", sensors, "--speed", _speed_arg(speed),
            "--mavlink", "udpin://127.0.0.1:0?mode=onboard", "--mavlink", "tcpin://127.0.0.1:0",
            "--log-dir", str(self.log_dir), "--param-store", "none", *extra, *map(str, args)],
            self.log_dir / "autopilot.log")
        lines = self.ap.wait_line("autopilot ready:", ready_timeout_s, count)
        if lines is None:
            tail = self.ap.tail()
            self.ap.kill()
            raise VehicleError(f"the swarm was not ready in {ready_timeout_s} s:\n{tail}")
        endpoints = {}
        for line in self.ap.wait_line("autopilot endpoint:", 1.0, 2 * count) or []:
            m = _ENDPOINT.match(line)
            endpoints.setdefault(int(m.group(1)), {})[m.group(2)] = m.group(3)
        self.vehicles = [_Member(s, endpoints[s]) for s in sorted(endpoints)]

    def __len__(self):
        return len(self.vehicles)

    def __getitem__(self, k):
        return self.vehicles[k]

    def stop(self, timeout_s: float = 60.0, land: bool = True) -> list:
        """Ends the run (airborne vehicles land first; with `land=False` at once); each
        vehicle's summary, in order."""
        if self.summaries is None:
            code = self.ap.interrupt(timeout_s, signal.SIGINT if land else signal.SIGTERM)
            found = [_fields(line) for line in self.ap.lines
                     if line.startswith("autopilot summary:") and "system_id=" in line]
            if code != 0 or not found:
                raise VehicleError(f"the swarm ended with status {code}:\n{self.ap.tail()}")
            self.summaries = found
        return self.summaries

    def kill(self) -> None:
        """Ends the process at once (SIGKILL)."""
        self.ap.kill()
        for v in self.vehicles:
            v._release()



def _fields(line: str) -> dict:
    """`autopilot summary: k=v k=v …` as {k: v}."""
    return dict(kv.split("=", 1) for kv in line.split()[2:] if "=" in kv)
