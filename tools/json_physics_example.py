#!/usr/bin/env python3
"""A quadrotor physics written the way physics for ArduPilot's SITL JSON interface are written
(https://ardupilot.org/dev/docs/sitl-with-JSON.html): it binds UDP 9002, unpacks each servo
packet with struct ('<HHI16H'), steps, and answers the sender with json.dumps of its state.
Standard library only, and none of this project's code: a second, independent implementation
of the protocol's physics side, to fly `autopilot --source json://127.0.0.1:9002` against.

The model is the project's quad_x in a few lines: four rotors on a 0.225 m X in PX4's order
(1 front-right ccw, 2 rear-left ccw, 3 front-left cw, 4 rear-right cw), speed 950 rad/s x PWM
fraction through a 30 ms lag, thrust and torque ~ speed², rigid body, linear drag, a flat
ground. The IMU is the true rate and specific force (no noise).

    tools/json_physics_example.py [--port 9002] [--duration 120]
"""

import argparse
import json
import math
import socket
import struct

MASS = 1.5                      # kg
INERTIA = (0.029, 0.029, 0.055)  # kg m², principal
ARM = 0.159                     # m, along each body axis
ROTORS = [  # (x, y, reaction torque sign: +1 ccw)
    (ARM, ARM, 1.0), (-ARM, -ARM, 1.0), (ARM, -ARM, -1.0), (-ARM, ARM, -1.0)]
MAX_SPEED = 950.0               # rad/s at full PWM
TAU = 0.03                      # s, motor lag
K_THRUST = 1.357e-5             # N / (rad/s)²: hover at ~520 rad/s
K_TORQUE = 2.26e-7              # N m / (rad/s)²
DRAG = 0.25                     # N s / m
G = 9.80665
DT = 0.001                      # s, physics step


def quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def rotate(q, v):
    """v from body (FRD) to earth (NED) by q."""
    w, x, y, z = quat_mul(quat_mul(q, (0.0, *v)), (q[0], -q[1], -q[2], -q[3]))
    return (x, y, z)


def unrotate(q, v):
    return rotate((q[0], -q[1], -q[2], -q[3]), v)


class Quad:
    def __init__(self):
        self.t = 0.0
        self.pos = [0.0, 0.0, 0.0]
        self.vel = [0.0, 0.0, 0.0]
        self.q = (1.0, 0.0, 0.0, 0.0)
        self.rate = [0.0, 0.0, 0.0]
        self.speed = [0.0] * 4
        self.accel = (0.0, 0.0, 0.0)  # NED, of the last step

    def step(self, commands):
        for i, u in enumerate(commands):
            self.speed[i] += (MAX_SPEED * u - self.speed[i]) * DT / TAU
        thrust = [K_THRUST * w * w for w in self.speed]
        torque = [0.0, 0.0, 0.0]
        for (x, y, sign), t, w in zip(ROTORS, thrust, self.speed):
            torque[0] += -y * t
            torque[1] += x * t
            torque[2] += sign * K_TORQUE * w * w
        # Euler's equations, principal axes.
        p, q_, r = self.rate
        ix, iy, iz = INERTIA
        dp = (torque[0] - (iz - iy) * q_ * r) / ix
        dq = (torque[1] - (ix - iz) * r * p) / iy
        dr = (torque[2] - (iy - ix) * p * q_) / iz
        force = rotate(self.q, (0.0, 0.0, -sum(thrust)))
        acc = [force[k] / MASS - DRAG * self.vel[k] / MASS for k in range(3)]
        acc[2] += G
        on_ground = self.pos[2] >= 0.0 and acc[2] >= 0.0
        if on_ground:
            # Resting on the ground: no motion, level as it stands.
            acc = [0.0, 0.0, 0.0]
            self.vel = [0.0, 0.0, 0.0]
            self.rate = [0.0, 0.0, 0.0]
            self.pos[2] = 0.0
            yaw = math.atan2(2 * (self.q[0] * self.q[3] + self.q[1] * self.q[2]),
                             1 - 2 * (self.q[2] ** 2 + self.q[3] ** 2))
            self.q = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
        else:
            self.rate = [p + dp * DT, q_ + dq * DT, r + dr * DT]
            for k in range(3):
                self.vel[k] += acc[k] * DT
                self.pos[k] += self.vel[k] * DT
            half = [0.5 * w * DT for w in self.rate]
            dq_ = quat_mul(self.q, (1.0, *half))
            n = math.sqrt(sum(c * c for c in dq_))
            self.q = tuple(c / n for c in dq_)
        self.accel = acc
        self.t += DT

    def state(self):
        specific = unrotate(self.q, (self.accel[0], self.accel[1], self.accel[2] - G))
        return {
            "timestamp": self.t,
            "imu": {"gyro": list(self.rate), "accel_body": list(specific)},
            "position": list(self.pos),
            "velocity": list(self.vel),
            "quaternion": list(self.q),
        }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--port", type=int, default=9002)
    parser.add_argument("--step", type=float, default=0.004,
                        help="simulated seconds per servo packet (a multiple of 1 ms; "
                        "0.001: ArduPilot's usual 1 kHz physics)")
    parser.add_argument("--duration", type=float, default=120.0,
                        help="simulated seconds before it exits")
    args = parser.parse_args()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", args.port))
    quad = Quad()
    last_frame, reply, packets = None, b"", 0
    print(f"json physics: listening on 127.0.0.1:{args.port}", flush=True)
    while quad.t < args.duration:
        data, addr = sock.recvfrom(100)
        if len(data) != 40:
            continue
        magic, frame_rate, frame_count = struct.unpack("<HHI", data[:8])
        pwm = struct.unpack("<16H", data[8:40])
        if magic != 18458:
            continue
        if frame_count == last_frame:
            sock.sendto(reply, addr)  # a resend: the same answer
            continue
        last_frame = frame_count
        packets += 1
        commands = [min(max((p - 1000) / 1000.0, 0.0), 1.0) for p in pwm[:4]]
        for _ in range(max(1, round(args.step / DT))):
            quad.step(commands)
        reply = ("\n" + json.dumps(quad.state()) + "\n").encode()
        sock.sendto(reply, addr)
    print(f"json physics: {packets} packets, t={quad.t:.3f} s, "
          f"position {[round(x, 3) for x in quad.pos]}", flush=True)


if __name__ == "__main__":
    main()
