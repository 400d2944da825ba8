"""JSBSim as the physics back-end (`sitl --physics jsbsim`), with the pinned PyPI jsbsim's console
program: the two back-ends flown open loop on the same commands agree, one seed gives one
trajectory (to a centimetre: JSBSim's runs are not bit-identical), and the autopilot takes off, hovers and lands in JSBSim within the bounds it meets in
the built-in physics."""

import csv
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from conftest import ROOT, Daemon, binary
from test_ground_station import ack, armed, ready_to_arm, wait

ML = mavutil.mavlink
# The venv's Python runs the bridge (the test command installs jsbsim==1.3.3 there).
PYTHON = sys.executable
RATE_HZ = 250  # JSBSim's rate: one frame per HIL exchange

# Airborne at 20 m, rotors at hover, in a light turbulent wind: a climb, a roll-pitch kick from
# rotors 1 and 3, a descent; the quad tilts by tens of degrees and travels metres.
MANOEUVRE = """
airframe = "quad_x"
seed = {seed}
duration_s = 5.0
sensors = "typical"
[initial]
position_ned_m = [0.0, 0.0, -20.0]
attitude_euler_deg = [0.0, 0.0, 30.0]
rotors_at_hover = true
[wind]
mean_ned_m_s = [0.0, 3.0, 0.0]
turbulence_w20_m_s = 3.0
[[open_loop]]
t_s = 0.0
hover_delta = 0.0
[[open_loop]]
t_s = 1.0
hover_delta = 0.03
[[open_loop]]
t_s = 2.0
controls = [0.61, 0.59, 0.61, 0.59]
[[open_loop]]
t_s = 2.2
hover_delta = -0.02
[[open_loop]]
t_s = 3.5
hover_delta = 0.0
"""


def open_loop(tmp_path, physics, scenario=MANOEUVRE, seed=3, name=None):
    """Flies `scenario` (with `seed`) open loop in `physics`; the truth CSV's rows and the run's
    summary."""
    name = name or physics
    path = tmp_path / f"{name}.toml"
    path.write_text(scenario.format(seed=seed))
    truth = tmp_path / f"{name}.csv"
    run = subprocess.run(
        [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--open-loop",
         "--scenario", str(path), "--rate", str(RATE_HZ), "--status-interval", "0",
         "--physics", physics, "--jsbsim-python", PYTHON, "--truth-csv", str(truth)],
        capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    line = next(l for l in run.stdout.splitlines() if l.startswith("sitl summary:"))
    with open(truth) as f:
        rows = list(csv.DictReader(f))
    return rows, dict(kv.split("=", 1) for kv in line.split()[2:])


def ned(row):
    return [float(row[k]) for k in ("n_m", "e_m", "d_m")]


def tilt_deg(row):
    """The angle between the body's down axis and the vertical."""
    w, x, y, z = (float(row[k]) for k in ("qw", "qx", "qy", "qz"))
    return math.degrees(math.acos(max(-1.0, min(1.0, 1 - 2 * (x * x + y * y)))))


def apart_deg(a, b):
    qa = [float(a[k]) for k in ("qw", "qx", "qy", "qz")]
    qb = [float(b[k]) for k in ("qw", "qx", "qy", "qz")]
    return math.degrees(2 * math.acos(min(1.0, abs(sum(x * y for x, y in zip(qa, qb))))))


def test_open_loop_runs_of_both_back_ends_agree(tmp_path):
    """Same airframe, same commands, same wind: the rigid bodies of JSBSim and of the built-in
    physics (RK4) stay within centimetres and a tenth of a degree through a manoeuvre that
    tilts the quad by over a hundred degrees. What differs: JSBSim's gravity model (WGS84 with
    the Earth's rotation), its integrators, and its forces acting one JSBSim frame (1 ms) late."""
    builtin, _ = open_loop(tmp_path, "builtin")
    jsbsim, summary = open_loop(tmp_path, "jsbsim")
    assert summary["steps"] == str(5 * RATE_HZ) and summary["landed"] == "false"
    assert len(builtin) == len(jsbsim) > 400
    position = max(math.dist(ned(b), ned(j)) for b, j in zip(builtin, jsbsim))
    attitude = max(apart_deg(b, j) for b, j in zip(builtin, jsbsim))
    velocity = max(math.dist([float(b[k]) for k in ("vn_m_s", "ve_m_s", "vd_m_s")],
                             [float(j[k]) for k in ("vn_m_s", "ve_m_s", "vd_m_s")])
                   for b, j in zip(builtin, jsbsim))
    travelled = math.dist(ned(builtin[-1]), ned(builtin[0]))
    tilted = max(tilt_deg(b) for b in builtin)
    print(f"\nopen loop, 5 s at {RATE_HZ} Hz: travelled {travelled:.2f} m, tilted up to "
          f"{tilted:.0f} deg; JSBSim vs built-in at worst {position * 100:.1f} cm, "
          f"{velocity * 100:.1f} cm/s, {attitude:.2f} deg")
    assert travelled > 2.0 and tilted > 20.0, "a manoeuvre worth comparing"
    assert position < 0.03 and velocity < 0.05 and attitude < 0.3


HOVER = """
airframe = "quad_x"
seed = {seed}
duration_s = 5.0
sensors = "typical"
[initial]
position_ned_m = [0.0, 0.0, -20.0]
rotors_at_hover = true
[wind]
mean_ned_m_s = [2.0, 0.0, 0.0]
turbulence_w20_m_s = 4.0
[[open_loop]]
t_s = 0.0
hover_delta = 0.0
"""


def test_one_seed_gives_one_jsbsim_trajectory(tmp_path):
    """An open-loop hover in turbulence, seeded: the same seed twice flies the same path, every
    row of the truth CSV alike to the last digit (the bridge runs exactly one JSBSim frame per
    request); another seed (another turbulence) a path decimetres away."""
    runs = {name: open_loop(tmp_path, "jsbsim", HOVER, seed, name)[0]
            for name, seed in (("first", 5), ("again", 5), ("other", 6))}
    assert len(runs["first"]) == len(runs["again"]) > 400
    differing = [i for i, (a, b) in enumerate(zip(runs["first"], runs["again"])) if a != b]
    assert not differing, f"rows {differing[:5]}... differ: {runs['first'][differing[0]]} vs " \
                          f"{runs['again'][differing[0]]}"
    other = max(math.dist(ned(a), ned(b)) for a, b in zip(runs["first"], runs["other"]))
    print(f"\nsame seed: {len(runs['first'])} identical rows; another seed {other:.2f} m away")
    assert other > 0.1


def bridges_of(pid):
    """The pids of JSBSim bridges that the sitl of `pid` started (its root is named after it)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            cmdline = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except (OSError, ValueError):
            continue
        if "bridge.py" in cmdline and f"sitl-jsbsim-{pid}-" in cmdline:
            found.append(int(proc.name))
    return found


def test_the_bridge_does_not_outlive_a_killed_simulator(tmp_path):
    """SIGKILL to sitl (no handler runs): the JSBSim bridge sees its standard input close and
    ends within seconds, removing the temporary root; it never runs on, orphaned."""
    path = tmp_path / "hover.toml"
    path.write_text(HOVER.format(seed=1).replace("duration_s = 5.0", "duration_s = 600.0"))
    sim = subprocess.Popen(
        [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--open-loop",
         "--scenario", str(path), "--speed", "1", "--status-interval", "1",
         "--physics", "jsbsim", "--jsbsim-python", PYTHON],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        # The first status line comes after a simulated second: JSBSim is up and stepping.
        assert sim.stdout.readline(), "sitl printed nothing"
        bridges = bridges_of(sim.pid)
        assert len(bridges) == 1, bridges
    finally:
        sim.kill()
        sim.wait()
    end = time.monotonic() + 10
    while bridges_of(sim.pid) and time.monotonic() < end:
        time.sleep(0.05)
    assert not bridges_of(sim.pid), "the bridge outlived sitl"
    assert not list(Path(tempfile.gettempdir()).glob(f"sitl-jsbsim-{sim.pid}-*")), \
        "the bridge left its root behind"


@pytest.mark.parametrize("physics", ["builtin", "jsbsim"])
def test_the_autopilot_takes_off_hovers_and_lands(tmp_path, physics):
    """The same flight and the same bounds in both back-ends: TAKEOFF to MIS_TAKEOFF_ALT (2.5 m),
    Hold for 5 s, LAND. From the simulator's truth: the climb stops within 0.3 m of 2.5 m, the
    vehicle never tilts past 15 deg, comes down the last 10 cm at under 1 m/s and rests within
    1 m of where it started; from the autopilot: Hold keeps it within 0.5 m (250 Hz physics,
    lockstep capped at x3, so that a busy machine slows the run but cannot change the flight;
    the figures printed are for both back-ends)."""
    truth = tmp_path / "truth.csv"
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
               sim_args=["--physics", physics, "--jsbsim-python", PYTHON, "--rate", str(RATE_HZ),
                         "--truth-csv", str(truth)],
               lockstep=True)
    try:
        gcs = d.gcs
        assert gcs.wait_heartbeat(timeout=60), "no heartbeat"
        ready_to_arm(gcs)
        gcs.set_mode("TAKEOFF")
        assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
        gcs.arducopter_arm()
        assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m), timeout=30)
        held = []
        end = time.monotonic() + 5
        while time.monotonic() < end:
            held.append(wait(gcs, "LOCAL_POSITION_NED", lambda m: True, 2))
        gcs.set_mode("LAND")
        assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
        try:
            wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=60)
        finally:
            summary = d.stop_sim()
            if not truth.exists() or summary.get("landed") != "true":
                rows = truth.read_text().splitlines() if truth.exists() else []
                print("not down; the simulator's summary:", summary, "truth:", *rows[-20:],
                      sep="\n")
    finally:
        d.close()
    spread = max(math.dist((a.x, a.y, a.z), (b.x, b.y, b.z)) for a in held for b in held)
    with open(truth) as f:
        rows = list(csv.DictReader(f))
    top = max(-float(r["d_m"]) for r in rows)
    tilt = max(tilt_deg(r) for r in rows)
    off = math.dist(ned(rows[-1])[:2], ned(rows[0])[:2])
    # The descent speed as the feet near the ground (JSBSim's springy feet make contact flicker
    # at rest, so the simulator's last-touchdown figure is not the landing's).
    final = next(i for i in range(len(rows) - 1, -1, -1) if float(rows[i]["d_m"]) < -0.10)
    touchdown = max(float(r["vd_m_s"]) for r in rows[final:final + 50])
    print(f"\n{physics}: climbed to {top:.2f} m, Hold within {spread:.2f} m, tilt <= {tilt:.1f} "
          f"deg, touchdown {touchdown:.2f} m/s, {off:.2f} m from the start")
    assert abs(top - 2.5) < 0.3
    assert spread < 0.5
    assert tilt < 15.0
    assert summary["landed"] == "true" and int(summary["touchdowns"]) >= 1
    assert 0.05 < touchdown < 1.0
    assert off < 1.0
