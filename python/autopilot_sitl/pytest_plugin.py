"""pytest plugin (the `pytest11` entry point `autopilot_sitl`): a fresh vehicle for every test.

Fixtures:
- `vehicle`: a Vehicle, ready (heartbeat, health ok), stopped after the test; its options from
  `@pytest.mark.vehicle(**kwargs)` (Vehicle's keyword arguments) over the command line's.
- `swarm`: a Swarm of `@pytest.mark.swarm(count=N, ...)` vehicles (3 by default).
- `make_vehicle`: a factory, `make_vehicle(**kwargs)`, for tests that want several or none.

Options: `--autopilot-speed` (simulated seconds per wall-clock second, or "max"; 10 by default),
`--autopilot-airframe` (quad_x), `--autopilot-sensors` (typical), `--autopilot-keep-logs`
(keep the logs of tests that passed too; a failed test's are always kept).

After the test each vehicle is stopped at once (SIGTERM: its logs flushed), in the air or not.
When a test fails, its report gets a section naming each vehicle's logs (ULog, .tlog, CSV, the
processes' output) with the end of the autopilot's output, and the paths as user properties
(`--junitxml` writes them). No vehicle outlives its test: each is stopped in teardown, killed if
it will not stop, and every process the plugin started is killed at the end of the session.
"""

import shutil

import pytest

from . import _process
from .vehicle import Swarm, Vehicle

_KEY = pytest.StashKey[list]()


def pytest_addoption(parser):
    group = parser.getgroup("autopilot", "autopilot_sitl vehicles")
    group.addoption("--autopilot-speed", default="10",
                    help="simulated seconds per wall-clock second of each test's vehicle, or "
                         "'max' (default: 10)")
    group.addoption("--autopilot-airframe", default="quad_x",
                    help="airframe of each test's vehicle (default: quad_x)")
    group.addoption("--autopilot-sensors", default="typical",
                    help="sensor preset: ideal, typical, noisy, realistic, uncalibrated")
    group.addoption("--autopilot-keep-logs", action="store_true",
                    help="keep the logs of the tests that passed too (a failed test's are kept)")


def pytest_configure(config):
    config.addinivalue_line("markers", "vehicle(**kwargs): the `vehicle` fixture's options "
                                       "(autopilot_sitl.Vehicle's keyword arguments)")
    config.addinivalue_line("markers", "swarm(count=3, **kwargs): the `swarm` fixture's size "
                                       "and options")


def _defaults(config) -> dict:
    speed = config.getoption("--autopilot-speed")
    return {
        "airframe": config.getoption("--autopilot-airframe"),
        "sensors": config.getoption("--autopilot-sensors"),
        "speed": speed if speed == "max" else float(speed),
    }


def _vehicles(item) -> list:
    return item.stash.setdefault(_KEY, [])


@pytest.fixture
def make_vehicle(request, tmp_path):
    """`make_vehicle(**kwargs)`: a started Vehicle (the command line's options, then the
    arguments); every one is stopped after the test."""
    started = _vehicles(request.node)

    def make(**kwargs):
        options = {**_defaults(request.config), **kwargs}
        options.setdefault("log_dir", tmp_path / f"vehicle-{len(started)}")
        v = Vehicle(**options)
        started.append(v)
        return v

    yield make
    _teardown(request, started)


@pytest.fixture
def vehicle(request, make_vehicle):
    """A fresh vehicle, ready for MAVSDK and pymavlink (`mavsdk_url`, `pymavlink_url`)."""
    marker = request.node.get_closest_marker("vehicle")
    return make_vehicle(**(marker.kwargs if marker else {}))


@pytest.fixture
def swarm(request, tmp_path):
    """A fresh swarm flown in one process (`@pytest.mark.swarm(count=N, ...)`)."""
    marker = request.node.get_closest_marker("swarm")
    kwargs = dict(marker.kwargs) if marker else {}
    count = kwargs.pop("count", 3)
    options = {**_defaults(request.config), **kwargs}
    s = Swarm(count, log_dir=tmp_path / "swarm", **options)
    _vehicles(request.node).append(s)
    yield s
    _teardown(request, [s])


def _teardown(request, started):
    """Stops every vehicle (killed if it will not stop); removes the logs of a passed test
    unless they are to be kept."""
    failed = False
    for v in started:
        try:
            # At once, wherever it is (SIGTERM: logs flushed, summary printed): a test that
            # ended with its vehicle in the air does not wait for it to land.
            v.stop(land=False)
        except Exception:  # noqa: BLE001 - reported below with the logs
            failed = True
        finally:
            v.kill()
    report = getattr(request.node, "_autopilot_call_report", None)
    passed = report is not None and report.passed and not failed
    if passed and not request.config.getoption("--autopilot-keep-logs"):
        for v in started:
            shutil.rmtree(v.log_dir, ignore_errors=True)
    if failed:
        pytest.fail("a vehicle did not stop cleanly; its logs: "
                    + ", ".join(str(v.log_dir) for v in started))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.when == "call":
        item._autopilot_call_report = report
    vehicles = item.stash.get(_KEY, [])
    if not report.failed or not vehicles:
        return
    lines = []
    for k, v in enumerate(vehicles):
        if isinstance(v, Vehicle):
            logs = v.logs.paths()
        else:
            logs = {"daemon": v.ap.log, "directory": v.log_dir}
        lines.append(f"vehicle {k}: " + ", ".join(f"{kind} {path}" for kind, path in logs.items()))
        for kind, path in logs.items():
            item.user_properties.append((f"autopilot_{k}_{kind}", str(path)))
        lines.append(f"--- the end of vehicle {k}'s autopilot output ---")
        lines.append(v.ap.tail(2000))
    report.sections.append(("autopilot logs", "\n".join(lines)))


def pytest_sessionfinish(session, exitstatus):
    """Whatever a test left running (a vehicle made outside the fixtures) ends with the run."""
    for child in _process.live():
        child.kill()

