#!/usr/bin/env python3
"""A synthetic multirotor flight's IMU and magnetometer, with its true attitude: the start in
motion the estimator benchmark replays beside the BROAD recordings.

    tools/synthetic_flight.py OUT.csv [--seed N] [--bias-deg-s 1.2,-1.2,1.2]

120 s at 200 Hz, no rest anywhere: 20 s of hover with oscillations (up to ±6° of tilt), 60° banks
held for a second or two, yaw spins at 450°/s, a coordinated turn at 45° of bank, then all of it
mixed. The motion is a multirotor's: the body's z axis is along the thrust, so the accelerometer
reads the thrust (plus noise and vibration), never gravity's direction, and the tilt shows only
through the average of the accelerations. The gyro carries a MEMS turn-on bias (default 1.2°/s
per axis) and the `typical` preset's noise (sitl/core/src/sensors/config.rs); the magnetometer
(100 Hz, nan between) the same preset's noise in a clean field, the BROAD site's (69.2° of
inclination, 0.437 G). The columns are the BROAD trials' (t, gx..gz, ax..az, mx..mz, qw..qz,
movement), so `autopilot replay`, VQF and the scorer read it as they read a trial.
"""
import argparse
import math

import numpy as np

RATE_HZ = 200.0
DURATION_S = 120.0
GRAVITY = 9.80665
# The `typical` preset (sitl/core/src/sensors/config.rs).
GYRO_NOISE_DENSITY = 1.7e-4  # rad/s/√Hz
ACCEL_NOISE_DENSITY = 2.0e-3  # m/s²/√Hz
ACCEL_VIBRATION = 0.3  # m/s², white
MAG_NOISE = 0.003  # gauss
MAG_RATE_HZ = 100.0
# The BROAD site's field (tools/bench_estimator.py SITE).
INCLINATION_DEG = 69.2
INTENSITY_GAUSS = 0.437


def window(t, start, end, ramp=1.0):
    """1 inside [start, end], 0 outside, raised-cosine ramps of `ramp` s: smooth motions."""
    up = np.clip((t - start) / ramp, 0.0, 1.0)
    down = np.clip((end - t) / ramp, 0.0, 1.0)
    return 0.25 * (1 - np.cos(np.pi * up)) * (1 - np.cos(np.pi * down))


def profile(t, rng):
    """Roll, pitch and the heading rate (rad, rad/s) and the linear acceleration (NED, m/s²) at
    the times t."""
    roll = np.zeros(len(t))
    pitch = np.zeros(len(t))
    yaw_rate = 0.3 * np.sin(2 * np.pi * 0.05 * t + rng.uniform(0, 2 * np.pi))
    acc = np.zeros((len(t), 3))
    # Hover with oscillations: a few incommensurate sines, up to ±6° of tilt at rates of a
    # gusty hover (10–30°/s), and the small accelerations of holding a place.
    for angle in (roll, pitch):
        for _ in range(3):
            f = rng.uniform(0.1, 1.0)
            angle += math.radians(2) * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    for axis in range(3):
        f = rng.uniform(0.2, 1.0)
        acc[:, axis] += 1.0 * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    # 60° banks, held for 1.5 s, each way about a random axis.
    for start in np.arange(22.0, 34.0, 3.0):
        d = rng.uniform(0, 2 * np.pi)
        w = math.radians(60) * window(t, start, start + 1.5, 0.5) * rng.choice((-1, 1))
        roll += math.cos(d) * w
        pitch += math.sin(d) * w
    # Yaw spins at 450°/s.
    for start, sign in ((36.0, 1.0), (41.0, -1.0), (95.0, 1.0)):
        yaw_rate += sign * math.radians(450) * window(t, start, start + 1.0, 0.4)
    # A turn: 30° of roll while the heading turns at 0.6 rad/s, slowly (its centripetal
    # acceleration left out: held for 20 s, it would look like gravity to any estimator that has
    # only the accelerometer for the tilt).
    turn = window(t, 48.0, 68.0, 3.0)
    roll += math.radians(30) * turn
    yaw_rate += 0.6 * turn
    # Then all of it mixed: oscillations twice as large.
    late = window(t, 82.0, DURATION_S + 10.0, 2.0)
    for angle in (roll, pitch):
        f = rng.uniform(0.2, 0.8)
        angle += math.radians(20) * late * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    return roll, pitch, yaw_rate, acc


def attitude(roll, pitch, yaw):
    """R_ned_from_frd (n, 3, 3) of Tait-Bryan angles (z-y-x)."""
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    return np.stack([np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], 1),
                     np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], 1),
                     np.stack([-sp, cp * sr, cp * cr], 1)], 1)


def log_so3(r):
    """The rotation vectors of rotation matrices (n, 3, 3)."""
    cos = np.clip((np.trace(r, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)
    angle = np.arccos(cos)
    v = np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], 1)
    scale = np.where(angle > 1e-9, angle / (2 * np.sin(np.maximum(angle, 1e-9))), 0.5)
    return v * scale[:, None]


def quaternion(r):
    """Unit quaternions (w, x, y, z) of rotation matrices (n, 3, 3), w ≥ 0."""
    w = np.sqrt(np.maximum(0.0, 1 + np.trace(r, axis1=1, axis2=2))) / 2
    x = np.sqrt(np.maximum(0.0, 1 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2])) / 2
    y = np.sqrt(np.maximum(0.0, 1 - r[:, 0, 0] + r[:, 1, 1] - r[:, 2, 2])) / 2
    z = np.sqrt(np.maximum(0.0, 1 - r[:, 0, 0] - r[:, 1, 1] + r[:, 2, 2])) / 2
    x = np.copysign(x, r[:, 2, 1] - r[:, 1, 2])
    y = np.copysign(y, r[:, 0, 2] - r[:, 2, 0])
    z = np.copysign(z, r[:, 1, 0] - r[:, 0, 1])
    return np.stack([w, x, y, z], 1)


def flight(seed, bias_deg_s=(1.2, -1.2, 1.2)):
    """The samples: a dict of columns."""
    rng = np.random.default_rng(seed)
    n = int(DURATION_S * RATE_HZ) + 1
    t = np.arange(n) / RATE_HZ
    roll, pitch, yaw_rate, acc = profile(t, rng)
    yaw = rng.uniform(-np.pi, np.pi) + np.concatenate([[0.0], np.cumsum(yaw_rate[1:])]) / RATE_HZ
    r = attitude(roll, pitch, yaw)
    # The gyro at sample k: the rate that turns the body from sample k−1 to k (what the
    # estimator integrates over that interval).
    rel = np.einsum("nji,njk->nik", r[:-1], r[1:])
    gyro = np.vstack([log_so3(rel[:1]), log_so3(rel)]) * RATE_HZ
    gyro += np.radians(bias_deg_s) + rng.normal(0, GYRO_NOISE_DENSITY * math.sqrt(RATE_HZ),
                                                (n, 3))
    f_ned = acc - np.array([0.0, 0.0, GRAVITY])
    accel = np.einsum("nji,nj->ni", r, f_ned)
    accel += rng.normal(0, math.hypot(ACCEL_NOISE_DENSITY * math.sqrt(RATE_HZ), ACCEL_VIBRATION),
                        (n, 3))
    inc = math.radians(INCLINATION_DEG)
    field = INTENSITY_GAUSS * np.array([math.cos(inc), 0.0, math.sin(inc)])
    mag = np.einsum("nji,j->ni", r, field) + rng.normal(0, MAG_NOISE, (n, 3))
    q = quaternion(r)
    cols = {"t": t}
    for k, name in enumerate("xyz"):
        cols["g" + name] = gyro[:, k]
        cols["a" + name] = accel[:, k]
        cols["m" + name] = mag[:, k]
    for k, name in enumerate(("qw", "qx", "qy", "qz")):
        cols[name] = q[:, k]
    cols["movement"] = np.ones(n)
    return cols


def write(path, cols):
    """The columns as a BROAD-style CSV."""
    names = ["t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz", "qw", "qx", "qy", "qz",
             "movement"]
    np.savetxt(path, np.column_stack([cols[c] for c in names]), delimiter=",",
               header=",".join(names), comments="", fmt="%.9g")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bias-deg-s", default="1.2,-1.2,1.2")
    a = ap.parse_args()
    write(a.out, flight(a.seed, tuple(float(x) for x in a.bias_deg_s.split(","))))


if __name__ == "__main__":
    main()
