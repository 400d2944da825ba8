"""Fly the autopilot in its embedded simulator from Python.

    from autopilot_sitl import Vehicle

    with Vehicle(airframe="quad_x", speed=10, wind=(5.0, 90.0)) as v:
        ...  # MAVSDK on v.mavsdk_url, pymavlink on v.pymavlink_url
        v.pause(); v.advance(2.0); v.resume()
        print(v.truth().down_m)
    print(v.summary["touchdown_m_s"], v.logs.ulog)

Each vehicle is one `autopilot` process (a swarm of N is one process too) whose every port is
chosen by the system and read back from its output, so vehicles started side by side never
clash. The pytest plugin (`autopilot_sitl.pytest_plugin`, registered as a pytest11 entry point)
gives each test a fresh one. See docs/python.md.
"""

from ._binaries import binary
from .vehicle import Logs, Swarm, Truth, Vehicle, VehicleError

__all__ = ["Logs", "Swarm", "Truth", "Vehicle", "VehicleError", "binary"]
