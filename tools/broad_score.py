#!/usr/bin/env python3
"""Scores an attitude estimate against a BROAD trial, as the BROAD benchmark defines its errors.

    tools/broad_score.py TRIAL.csv.gz ESTIMATE.csv   # ESTIMATE: t,qw,qx,qy,qz (q_ned_from_frd)

Laidig et al., "BROAD — A Benchmark for Robust Inertial Orientation Estimation" (Data 6(7), 2021),
as its example code (`broad_utils.py`, `calculateRMSE`) computes them: the error quaternion is q_est ⊗ q_true⁻¹, the error seen in the world frame; its whole
rotation angle is the total error, its part about the vertical the heading error, the rest the
inclination error. Each is an RMS over the samples of the motion phase (`movement` 1; the rest
phases at both ends are not scored), samples without truth skipped. The estimate has one row per
trial row, in order (as `autopilot replay` writes it). Prints one JSON line, degrees.
"""
import gzip
import json
import sys

import numpy as np

QUAT = ("qw", "qx", "qy", "qz")


def read_csv(path: str) -> dict[str, np.ndarray]:
    """A CSV with a header row (gzip-compressed where the name ends in .gz) as named columns;
    empty cells are NaN."""
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        d = np.genfromtxt(f, delimiter=",", names=True)
    return {k: d[k] for k in d.dtype.names}


def error_angles(q_est: np.ndarray, q_true: np.ndarray) -> dict[str, np.ndarray]:
    """Total, heading and inclination error (rad) of each row's q_est ⊗ q_true⁻¹ (NED world:
    the vertical is z)."""
    a = q_est / np.linalg.norm(q_est, axis=1)[:, None]
    b = q_true / np.linalg.norm(q_true, axis=1)[:, None]
    # The scalar and z parts of a ⊗ b⁻¹, all the three errors need.
    w = np.sum(a * b, 1)
    z = -a[:, 0] * b[:, 3] + a[:, 3] * b[:, 0] - a[:, 1] * b[:, 2] + a[:, 2] * b[:, 1]
    with np.errstate(divide="ignore"):
        heading = 2 * np.arctan(np.abs(z / w))
    return {"total": 2 * np.arccos(np.clip(np.abs(w), 0, 1)),
            "heading": heading,
            "inclination": 2 * np.arccos(np.clip(np.sqrt(w * w + z * z), 0, 1))}


def score(trial: str, estimate: str) -> dict:
    """The RMS errors (deg) of `estimate` over `trial`'s scored samples, and their count."""
    t, e = read_csv(trial), read_csv(estimate)
    if len(t["t"]) != len(e["t"]):
        raise ValueError(f"{estimate}: {len(e['t'])} rows for the trial's {len(t['t'])}")
    q_true = np.stack([t[k] for k in QUAT], 1)
    q_est = np.stack([e[k] for k in QUAT], 1)
    scored = (t["movement"] == 1) & np.isfinite(q_true[:, 0])
    if not scored.any():
        raise ValueError(f"{trial}: no scored samples")
    errors = error_angles(q_est[scored], q_true[scored])
    rms = {f"{k}_rmse_deg": float(np.degrees(np.sqrt(np.mean(v * v))))
           for k, v in errors.items()}
    return {"samples": int(scored.sum()), **rms}


def main() -> int:
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("\n\n")[1])
    try:
        print(json.dumps(score(sys.argv[1], sys.argv[2])))
    except (OSError, ValueError) as e:
        sys.exit(f"broad_score.py: {e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
