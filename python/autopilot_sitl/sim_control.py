"""A client of the simulator's own MAVLink endpoint (`autopilot --sim-control`, `sitl --control`):
its weather and clock by the parameter protocol, its truth by MAV_CMD_REQUEST_MESSAGE. It speaks
MAVLink 2 through pymavlink's codec on a socket of its own, whatever dialect the rest of the
process chose for pymavlink."""

import math
import socket
import time
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

HIL_STATE_QUATERNION = mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION
LOCAL_POSITION_NED = mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED


class ControlError(RuntimeError):
    """The simulator refused or did not answer."""


@dataclass(frozen=True)
class Truth:
    """The simulator's state at one moment: position from its home (NED, m), velocity (NED,
    m/s), geodetic position, attitude (quaternion w, x, y, z from body FRD to NED; Euler angles
    in degrees) and body rates (rad/s)."""

    time_s: float
    north_m: float
    east_m: float
    down_m: float
    vn_m_s: float
    ve_m_s: float
    vd_m_s: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    q: tuple
    rates_rad_s: tuple

    @property
    def height_m(self) -> float:
        """Height above home (m)."""
        return -self.down_m

    @property
    def euler_deg(self) -> tuple:
        """Roll, pitch, yaw (degrees, ZYX)."""
        w, x, y, z = self.q
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        return tuple(math.degrees(a) for a in (roll, pitch, yaw))


class SimControl:
    """The endpoint at `address` ("127.0.0.1:PORT"), as system 250, component 190."""

    def __init__(self, address: str, timeout_s: float = 5.0):
        host, port = address.rsplit(":", 1)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect((host, int(port)))
        self.mav = mavlink2.MAVLink(None, srcSystem=250, srcComponent=190)
        self.mav.robust_parsing = True
        self.timeout_s = timeout_s
        self.said = []

    def close(self):
        self.sock.close()

    def _send(self, msg):
        self.sock.send(msg.pack(self.mav))

    def _receive(self, wanted, timeout_s):
        """The first message for which `wanted` holds within `timeout_s`, or None."""
        end = time.monotonic() + timeout_s
        while (left := end - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(65536)
            except (socket.timeout, ConnectionRefusedError):
                continue
            for m in self.mav.parse_buffer(data) or []:
                if m.get_type() == "STATUSTEXT":
                    self.said.append(m.text)
                if wanted(m):
                    return m
        return None

    def get(self, name: str) -> float:
        """The value of parameter `name`."""
        self._send(mavlink2.MAVLink_param_request_read_message(1, 25, name.encode(), -1))
        m = self._receive(lambda m: _is_value(m, name), self.timeout_s)
        if m is None:
            raise ControlError(f"no value of {name} from the simulator")
        return m.param_value

    def set(self, name: str, value: float) -> float:
        """Sets parameter `name`; the value the simulator answers with. A refused value (out of
        range) raises ControlError with the simulator's reason."""
        self.said.clear()
        self._send(mavlink2.MAVLink_param_set_message(
            1, 25, name.encode(), float(value), mavlink2.MAV_PARAM_TYPE_REAL32))
        m = self._receive(lambda m: _is_value(m, name), self.timeout_s)
        if m is None:
            raise ControlError(f"the simulator did not answer setting {name}")
        if not math.isclose(m.param_value, value, rel_tol=1e-6, abs_tol=1e-6):
            # The refusal's STATUSTEXT comes just before its PARAM_VALUE.
            why = "; ".join(self.said) or f"it kept {m.param_value}"
            raise ControlError(f"{name} = {value} refused: {why}")
        return m.param_value

    def wait_value(self, name: str, value: float, timeout_s: float) -> None:
        """Waits for the simulator to say parameter `name` is `value` (as SIM_RUN_S says 0 when a
        stretch ends)."""
        m = self._receive(lambda m: _is_value(m, name) and m.param_value == value, timeout_s)
        if m is None:
            raise ControlError(f"{name} did not become {value} within {timeout_s} s")

    def _request(self, msg_id: int):
        self._send(mavlink2.MAVLink_command_long_message(
            1, 25, mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, msg_id, 0, 0, 0, 0, 0, 0))

    def truth(self) -> Truth:
        """The truth: both messages asked for at once, so the simulator answers them at the same
        moment (asked again if not)."""
        for _ in range(5):
            self._request(HIL_STATE_QUATERNION)
            self._request(LOCAL_POSITION_NED)
            got = {}
            end = time.monotonic() + self.timeout_s
            while len(got) < 2 and time.monotonic() < end:
                m = self._receive(
                    lambda m: m.get_type() in ("HIL_STATE_QUATERNION", "LOCAL_POSITION_NED"),
                    end - time.monotonic())
                if m is not None:
                    got[m.get_type()] = m
            if len(got) < 2:
                raise ControlError("the simulator did not send its truth")
            s, p = got["HIL_STATE_QUATERNION"], got["LOCAL_POSITION_NED"]
            if s.time_usec // 1000 == p.time_boot_ms:
                return Truth(
                    time_s=s.time_usec * 1e-6,
                    north_m=p.x, east_m=p.y, down_m=p.z,
                    vn_m_s=p.vx, ve_m_s=p.vy, vd_m_s=p.vz,
                    lat_deg=s.lat * 1e-7, lon_deg=s.lon * 1e-7, alt_m=s.alt * 1e-3,
                    q=tuple(s.attitude_quaternion),
                    rates_rad_s=(s.rollspeed, s.pitchspeed, s.yawspeed),
                )
        raise ControlError("the simulator's truth moved between its two messages five times")


def _is_value(m, name):
    return m.get_type() == "PARAM_VALUE" and m.param_id == name
