"""The BROAD data's tools, on data made here: the scorer against the benchmark's definitions, the
conversion of BROAD's MATLAB files to the replay CSV, the fetch refusing a file that is not the
pinned one, the one lookup and its order, and the lint that keeps every other path inside the
repository."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from conftest import ROOT

sys.path.insert(0, str(ROOT / "tools"))
import broad  # noqa: E402
import broad_score  # noqa: E402
import lint  # noqa: E402


def axis_angle(axis, deg):
    half = math.radians(deg) / 2
    return np.array([math.cos(half), *(math.sin(half) * np.asarray(axis, float))])


def rotate(q, v):
    """v rotated by the unit quaternion q (Hamilton, scalar first)."""
    p = broad.quat_mul(broad.quat_mul(q, np.array([0.0, *v])), q * [1, -1, -1, -1])
    return p[1:]


def write_trial(path: Path, q_true: np.ndarray, movement: np.ndarray):
    rows = ["t,qw,qx,qy,qz,movement"]
    for i, (q, m) in enumerate(zip(q_true, movement)):
        cells = ",".join(f"{v:.12f}" for v in q) if np.isfinite(q[0]) else ",,,"
        rows.append(f"{i * 0.01},{cells},{m}")
    path.write_text("\n".join(rows) + "\n")


def write_estimate(path: Path, q_est: np.ndarray):
    np.savetxt(path, np.column_stack([np.arange(len(q_est)) * 0.01, q_est]), delimiter=",",
               header="t,qw,qx,qy,qz", comments="", fmt="%.12f")


@pytest.mark.parametrize("axis, total, heading, inclination", [
    ((0, 0, 1), 10.0, 10.0, 0.0),  # about the vertical: all of it is heading
    ((1, 0, 0), 5.0, 0.0, 5.0),    # about north: all of it is inclination
    ((0, 1, 0), 7.0, 0.0, 7.0),
])
def test_scorer_splits_a_world_frame_error_as_the_benchmark_defines_it(
        tmp_path, axis, total, heading, inclination):
    rng = np.random.default_rng(3)
    n = 400
    q_true = rng.normal(size=(n, 4))
    q_true /= np.linalg.norm(q_true, axis=1)[:, None]
    movement = np.ones(n, int)
    movement[:50] = 0  # the rest phase: not scored
    q_true[60:70] = np.nan  # truth lost: not scored
    # The error in the world frame: q_est = q_err ⊗ q_true, on the scored samples.
    q_est = broad.quat_mul(axis_angle(axis, total), q_true)
    q_est[:50] = axis_angle((1, 0, 0), 90)  # far off where nothing is scored
    q_est[60:70] = axis_angle((1, 0, 0), 90)
    q_est[70:80] *= -1  # q and -q are one attitude
    write_trial(tmp_path / "trial.csv", q_true, movement)
    write_estimate(tmp_path / "est.csv", q_est)
    r = broad_score.score(str(tmp_path / "trial.csv"), str(tmp_path / "est.csv"))
    assert r["samples"] == n - 50 - 10
    assert r["total_rmse_deg"] == pytest.approx(total, abs=1e-6)
    assert r["heading_rmse_deg"] == pytest.approx(heading, abs=1e-6)
    assert r["inclination_rmse_deg"] == pytest.approx(inclination, abs=1e-6)


def test_scorer_refuses_an_estimate_of_another_length(tmp_path):
    q = np.tile([1.0, 0, 0, 0], (10, 1))
    write_trial(tmp_path / "trial.csv", q, np.ones(10, int))
    write_estimate(tmp_path / "est.csv", q[:9])
    with pytest.raises(ValueError, match="9 rows for the trial's 10"):
        broad_score.score(str(tmp_path / "trial.csv"), str(tmp_path / "est.csv"))


def broad_mat(path: Path, n=5):
    """A small trial in BROAD's MATLAB layout: the IMU level with x east, y north, z up (its
    truth, q_enu_from_imu, the identity), then lost by the optical system."""
    q = np.tile([1.0, 0, 0, 0], (n, 1))
    q[-1] = np.nan
    scipy.io.savemat(path, {
        "imu_gyr": np.tile([0.1, 0.2, -0.3], (n, 1)),
        "imu_acc": np.tile([0.0, 0.0, 9.81], (n, 1)),
        "imu_mag": np.tile([0.0, 20.0, -40.0], (n, 1)),  # µT: north and down
        "opt_quat": q, "movement": np.array([0] + [1] * (n - 2) + [0], np.uint8),
        "sampling_rate": 200.0})


def test_conversion_turns_broad_into_frd_ned_and_gauss(tmp_path):
    broad_mat(tmp_path / "t.mat")
    text = broad.convert((tmp_path / "t.mat").read_bytes())
    header, *rows = text.splitlines()
    assert header == broad.HEADER
    cols = header.split(",")
    rows = [dict(zip(cols, r.split(","))) for r in rows]
    assert [r["t"] for r in rows] == ["0", "0.005", "0.01", "0.015", "0.02"]
    assert [r["movement"] for r in rows] == ["0", "1", "1", "1", "0"]
    r = rows[0]
    f = lambda *k: np.array([float(r[c]) for c in k])
    # FRD: the y and z axes turned over; specific force at rest reads -g on z.
    assert f("gx", "gy", "gz") == pytest.approx([0.1, -0.2, 0.3])
    assert f("ax", "ay", "az") == pytest.approx([0.0, 0.0, -9.81])
    assert f("mx", "my", "mz") == pytest.approx([0.0, -0.2, 0.4])  # gauss
    # The truth as q_ned_from_frd: the body's nose points east, its right wing south, its belly
    # down.
    q = f("qw", "qx", "qy", "qz")
    assert rotate(q, [1, 0, 0]) == pytest.approx([0, 1, 0], abs=1e-7)
    assert rotate(q, [0, 1, 0]) == pytest.approx([-1, 0, 0], abs=1e-7)
    assert rotate(q, [0, 0, 1]) == pytest.approx([0, 0, 1], abs=1e-7)
    # The measured field, turned to NED by the truth, points north and down.
    field = rotate(q, f("mx", "my", "mz"))
    assert field == pytest.approx([0.2, 0.0, 0.4], abs=1e-7)
    assert [rows[-1][k] for k in ("qw", "qx", "qy", "qz")] == ["", "", "", ""]


def test_fetch_refuses_a_file_that_is_not_the_pinned_one_and_writes_no_trial(tmp_path):
    source, dest = tmp_path / "mirror", tmp_path / "cache"
    source.mkdir()
    first = next(iter(broad.TRIALS))
    broad_mat(source / f"{first}.mat")  # a file of the right name, but not BROAD's
    with pytest.raises(ValueError, match=f"{first}.mat .*SHA-256 .*expected"):
        broad.fetch(dest, str(source), log=lambda _: None)
    assert not list(dest.glob("*.csv.gz"))
    assert not [p for p in dest.iterdir() if p.name.startswith(".")]  # no temporary left
    assert "CC BY 4.0" in (dest / "README.md").read_text()  # the attribution goes with the data


def test_fetch_says_which_download_failed(tmp_path):
    with pytest.raises(OSError, match="01_undisturbed_slow_rotation_A.mat"):
        broad.fetch(tmp_path / "cache", str(tmp_path / "no-such-mirror"), log=lambda _: None)


def test_lookup_takes_the_variable_alone_and_says_how_to_fetch(tmp_path, monkeypatch):
    folder = tmp_path / "broad"
    folder.mkdir()
    monkeypatch.setenv(broad.ENV_DIR, str(folder))
    for name in list(broad.TRIALS)[:-1]:
        (folder / f"{name}.csv.gz").touch()
    assert broad.trials_dir() is None
    why = broad.why_none()
    assert f"${broad.ENV_DIR} {folder}: 1 of 12 trials missing" in why
    assert broad.FETCH_COMMAND in why
    (folder / f"{list(broad.TRIALS)[-1]}.csv.gz").touch()
    assert broad.trials_dir() == folder
    # Found is not checked: verify says which files are not the pinned data.
    assert len(broad.verify(folder)) == 12


def test_lookup_order_and_the_cache(tmp_path, monkeypatch):
    monkeypatch.delenv(broad.ENV_DIR, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert broad.cache_dir() == tmp_path / "autopilot" / "broad"
    (_, kept_beside), (_, cache) = broad.candidates()
    assert cache == broad.cache_dir()
    # This project's own machines keep a copy beside the repository, looked at before the cache.
    assert not kept_beside.is_relative_to(ROOT)
    assert kept_beside.parts[-3:] == (lint.BESIDE, "benchmarks", "broad")


# The examples are written with {up} for a parent step and {beside} for the folder beside the
# repository, filled in at run time: this file would otherwise name paths outside the repository.
@pytest.mark.parametrize("file, line", [
    ("README.md", "papers in `{up}/{beside}/papers/`"),
    ("docs/references.md", "File: `{up}/{beside}/papers/000.txt`."),
    ("tests/python/test_x.py", 'TRIALS = HERE.parent / "{beside}" / "benchmarks"'),
    ("tests/python/test_y.py", 'SCHEMAS = {root}.parent / "specs"'),
    ("tools/bench_x.py", 'default=os.path.join({root}, "{up}", "{beside}", "benchmarks")'),
    ("tools/x.py", "HERE = Path(__file__).resolve().parents[2]"),
    ("daemon/src/x.rs", 'include_str!("{up}/{up}/{up}/{up}/notes.txt")'),
])
def test_lint_finds_a_path_outside_the_repository(file, line):
    text = "x\n" + line.format(up="..", beside=lint.BESIDE, root="ROOT") + "\n"
    assert lint.outside_paths(Path(file), text)[0].startswith(f"{file}:2: ")


@pytest.mark.parametrize("file, line", [
    ("daemon/core/src/mixer/tests.rs", '.join("../../params/airframes/quad_x.toml")'),
    ("tests/python/conftest.py", "ROOT = Path(__file__).resolve().parents[2]"),
    ("docs/autopilot.md", "![plot](../tools/plot_flight_example.png)"),
    ("daemon/files/src/ftp/paths.rs", 'r.resolve(b"../etc/passwd")'),
    ("docs/x.md", "the shared folder of the workspace"),
])
def test_lint_leaves_paths_inside_the_repository(file, line):
    assert lint.outside_paths(Path(file), line) == []
