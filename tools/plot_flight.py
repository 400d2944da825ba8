#!/usr/bin/env python3
"""Turns a flight-data CSV (`autopilot` writes one per run: logs/<start time>.csv) into PNG figures:
attitude against its set-point, position and path, motor outputs, estimator error (against the
simulator's truth, where the log has it) and loop timing.

    .venv/bin/python tools/plot_flight.py logs/2026-11-23_10-15-02.csv [--out DIR] [--overview]
        [--spin]

Writes DIR/<stem>_attitude.png, _position.png, _motors.png, _estimator.png and _loop.png
(DIR: beside the CSV), or with --overview the five in one <stem>_overview.png, or with --spin
<stem>_spin.png: height, yaw rate, tilt and motor outputs of a quad flying on three rotors.
"""

import argparse
import csv
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def load(path):
    """The CSV's columns as float arrays (an empty cell is NaN) and its mode column."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None or "t_s" not in header:
            raise SystemExit(f"{path}: not a flight-data CSV (no t_s column)")
        rows = list(reader)
    if not rows:
        raise SystemExit(f"{path}: no rows")
    columns = {}
    for i, name in enumerate(header):
        if name == "mode":
            columns[name] = [r[i] for r in rows]
            continue
        values = []
        for r in rows:
            cell = r[i] if i < len(r) else ""
            try:
                values.append(float(cell) if cell not in ("", "true", "false") else
                              {"": math.nan, "true": 1.0, "false": 0.0}[cell])
            except ValueError:
                values.append(math.nan)
        columns[name] = np.array(values)
    return columns


def wrap_deg(a):
    return (a + 180.0) % 360.0 - 180.0


def has(c, name):
    return name in c and not np.all(np.isnan(c[name]))


def rows_with(c, name):
    """The rows where `name` has a value (truth comes at its own, lower rate)."""
    return ~np.isnan(c[name])


def plot_attitude(c, axes):
    t = c["t_s"]
    for ax, axis in zip(axes, ("roll", "pitch", "yaw")):
        ax.plot(t, c[f"{axis}_deg"], label="estimate", lw=1)
        ax.plot(t, c[f"sp_{axis}_deg"], "--", label="set-point", lw=1)
        if has(c, f"true_{axis}_deg"):
            k = rows_with(c, f"true_{axis}_deg")
            ax.plot(t[k], c[f"true_{axis}_deg"][k], ":", label="truth", lw=1)
        ax.set_ylabel(f"{axis} (deg)")
    axes[0].set_title("Attitude and set-point")
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time (s)")


def plot_position(c, ax_height, ax_path):
    t = c["t_s"]
    ax_height.plot(t, -c["d_m"], label="estimate", lw=1)
    ax_height.plot(t, -c["sp_d_m"], "--", label="set-point", lw=1)
    if has(c, "true_d_m"):
        k = rows_with(c, "true_d_m")
        ax_height.plot(t[k], -c["true_d_m"][k], ":", label="truth", lw=1)
    ax_height.set_ylabel("height (m)")
    ax_height.set_xlabel("time (s)")
    ax_height.set_title("Height")
    ax_height.legend(loc="upper right", fontsize="small")
    if ax_path is None:
        return
    ax_path.plot(c["e_m"], c["n_m"], label="estimate", lw=1)
    ax_path.plot(c["sp_e_m"], c["sp_n_m"], "x", ms=3, label="set-point")
    if has(c, "true_e_m"):
        k = rows_with(c, "true_e_m")
        ax_path.plot(c["true_e_m"][k], c["true_n_m"][k], ":", label="truth", lw=1)
    ax_path.set_xlabel("east (m)")
    ax_path.set_ylabel("north (m)")
    ax_path.set_title("Path")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.legend(loc="upper right", fontsize="small")


def plot_motors(c, ax):
    t = c["t_s"]
    motors = sorted((k for k in c if k.startswith("motor")), key=lambda k: int(k[5:]))
    for k in motors:
        ax.plot(t, c[k], lw=0.8, label=k)
    ax.set_ylabel("command (0-1)")
    ax.set_xlabel("time (s)")
    ax.set_title("Motor outputs")
    ax.legend(loc="upper right", fontsize="x-small", ncol=max(1, len(motors) // 4))


def plot_estimator(c, ax_pos, ax_att):
    t = c["t_s"]
    if not has(c, "true_n_m"):
        for ax in (ax_pos, ax_att):
            ax.text(0.5, 0.5, "no truth in this log (a flight board)", ha="center",
                    transform=ax.transAxes)
        ax_pos.set_title("Estimator error")
        return
    k = rows_with(c, "true_n_m")
    for axis, label in (("n", "north"), ("e", "east"), ("d", "down")):
        ax_pos.plot(t[k], (c[f"{axis}_m"] - c[f"true_{axis}_m"])[k], lw=0.8, label=label)
    ax_pos.set_ylabel("position error (m)")
    ax_pos.set_title("Estimator error (estimate - truth)")
    ax_pos.legend(loc="upper right", fontsize="small")
    for axis in ("roll", "pitch", "yaw"):
        err = wrap_deg(c[f"{axis}_deg"] - c[f"true_{axis}_deg"])
        k = ~np.isnan(err)
        ax_att.plot(t[k], err[k], lw=0.8, label=axis)
    ax_att.set_ylabel("attitude error (deg)")
    ax_att.set_xlabel("time (s)")
    ax_att.legend(loc="upper right", fontsize="small")


def plot_loop(c, ax):
    t = c["t_s"]
    if has(c, "loop_late_us"):
        ax.plot(t, c["loop_late_us"], lw=0.6)
        ax.set_ylabel("wake-up lateness (us)")
        ax.set_title("Control loop: how late each tick woke")
    else:
        # Lockstep: the simulator paces the loop; the step between sensor frames is the timing.
        interval = np.round(np.diff(t) * 1e3, 3)  # the CSV's 0.1 ms resolution
        ax.plot(t[1:], interval, lw=0.6)
        ax.set_ylim(0, 1.2 * max(interval.max(), 1e-3))
        ax.set_ylabel("frame interval (ms)")
        ax.set_title("Control loop: sensor frame interval (lockstep)")
    ax.set_xlabel("time (s)")


def plot_spin(c, axes):
    """Height, yaw rate, the body's tilt and the motor outputs, one above the other."""
    t = c["t_s"]
    plot_position(c, axes[0], None)
    axes[0].set_xlabel("")
    axes[1].plot(t, c["gz"], lw=0.8, label="gyro z")
    axes[1].set_ylabel("yaw rate (rad/s)")
    axes[1].set_title("Yaw rate")
    tilt = np.degrees(np.arccos(np.clip(np.cos(np.radians(c["roll_deg"]))
                                        * np.cos(np.radians(c["pitch_deg"])), -1.0, 1.0)))
    axes[2].plot(t, tilt, lw=0.8, label="estimate")
    if has(c, "true_roll_deg"):
        k = rows_with(c, "true_roll_deg")
        true_tilt = np.degrees(np.arccos(np.clip(
            np.cos(np.radians(c["true_roll_deg"][k])) * np.cos(np.radians(c["true_pitch_deg"][k])),
            -1.0, 1.0)))
        axes[2].plot(t[k], true_tilt, ":", lw=1, label="truth")
    axes[2].set_ylabel("tilt (deg)")
    axes[2].set_title("Tilt of the body's z axis from the vertical")
    axes[2].legend(loc="upper right", fontsize="small")
    plot_motors(c, axes[3])


def save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("csv", type=Path, help="flight-data CSV")
    ap.add_argument("--out", type=Path, help="directory of the PNGs [default: beside the CSV]")
    ap.add_argument("--overview", action="store_true", help="one PNG with every figure")
    ap.add_argument("--spin", action="store_true",
                    help="one PNG of a flight on three rotors: height, yaw rate, tilt, motors")
    args = ap.parse_args()
    try:
        c = load(args.csv)
    except OSError as e:
        raise SystemExit(f"{args.csv}: {e}")
    out = args.out or args.csv.parent
    out.mkdir(parents=True, exist_ok=True)
    stem = args.csv.stem
    if args.spin:
        fig, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
        plot_spin(c, axes)
        save(fig, out / f"{stem}_spin.png")
        return
    if args.overview:
        fig = plt.figure(figsize=(16, 12))
        grid = fig.add_gridspec(4, 3)
        att = [fig.add_subplot(grid[i, 0]) for i in range(3)]
        plot_attitude(c, att)
        plot_position(c, fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[0:2, 2]))
        plot_motors(c, fig.add_subplot(grid[1, 1]))
        plot_estimator(c, fig.add_subplot(grid[2, 1]), fig.add_subplot(grid[2, 2]))
        plot_loop(c, fig.add_subplot(grid[3, 1:]))
        ax = fig.add_subplot(grid[3, 0])
        ax.axis("off")
        ax.text(0, 0.5, f"{args.csv.name}\n{len(c['t_s'])} rows, {c['t_s'][-1]:.1f} s",
                va="center")
        save(fig, out / f"{stem}_overview.png")
        return
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    plot_attitude(c, axes)
    save(fig, out / f"{stem}_attitude.png")
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 5))
    plot_position(c, a, b)
    save(fig, out / f"{stem}_position.png")
    fig, ax = plt.subplots(figsize=(10, 4))
    plot_motors(c, ax)
    save(fig, out / f"{stem}_motors.png")
    fig, (a, b) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    plot_estimator(c, a, b)
    save(fig, out / f"{stem}_estimator.png")
    fig, ax = plt.subplots(figsize=(10, 3.5))
    plot_loop(c, ax)
    save(fig, out / f"{stem}_loop.png")


if __name__ == "__main__":
    sys.exit(main())
