#!/usr/bin/env python3
"""The BROAD trials the attitude estimator is measured on: where they are, and how to get them.

    tools/broad.py where                 # the folder the tests and benchmarks will read, or why none
    tools/broad.py fetch [--source URL]  # download, check and convert the twelve trials into the cache
    tools/broad.py verify [DIR]          # check a folder's trials against the pinned checksums

BROAD (D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD — A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072; github.com/dlaidig/broad) is
real 9-axis IMU recordings with optical truth, under Creative Commons Attribution 4.0. The data is
not kept in this repository. This file is the one place that knows where it lives; the tests and
`tools/bench_estimator.py` ask `trials_dir()`, which looks, in order:

1. `$AUTOPILOT_BROAD_DIR` (when set, only there);
2. `benchmarks/broad` in the `shared` folder beside the repository, where this project's own
   machines keep it;
3. the cache, `$XDG_CACHE_HOME/autopilot/broad` (default `~/.cache/autopilot/broad`), which
   `fetch` fills.

`fetch` downloads the twelve trials' MATLAB files from BROAD's repository at a pinned commit,
checks each file's SHA-256, converts it to the CSV `autopilot replay` reads (below), checks the
CSV's SHA-256 too and only then moves it into the cache (one atomic rename a trial). Needs numpy and
scipy (tests/requirements.txt: run it with `.venv/bin/python`).

The CSV, one row per sample: `t` (s); `gx,gy,gz` gyro (rad/s, body FRD); `ax,ay,az` specific force
(m/s², FRD: level at rest reads z ≈ −9.81); `mx,my,mz` magnetometer (gauss, FRD); `qw,qx,qy,qz` the
truth as q_ned_from_frd (Hamilton, scalar first; empty where the optical system lost the markers;
heading referenced to magnetic north); `movement` 1 in the scored motion phase. BROAD's IMU frame
turned 180° about its x axis is FRD, its truth is q_enu_from_imu and its field is in µT.
"""
import argparse
import gzip
import hashlib
import io
import math
import os
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ENV_DIR = "AUTOPILOT_BROAD_DIR"
# Set by CI (.ci/run): a missing data set fails the BROAD test instead of skipping it.
ENV_REQUIRED = "AUTOPILOT_REQUIRE_BROAD"
FETCH_COMMAND = ".venv/bin/python tools/broad.py fetch"

# BROAD's repository at the commit the checksums were taken from.
SOURCE = ("https://raw.githubusercontent.com/dlaidig/broad/"
          "7e2f8189bb4a3ac91eae32c69b6bc87f08a6e2ad/data_mat")
# Trial: (SHA-256 of BROAD's .mat file, SHA-256 of the converted CSV, uncompressed).
TRIALS = {
    "01_undisturbed_slow_rotation_A": (
        "ad2cec0390a279953084e1de12dfd8d542af55e4ea187e68e8ebb7c316ecb96b",
        "39e5264125272f4bef78869da0acd83d36f19cd4063295f7a36c6aec1ce1430e"),
    "03_undisturbed_slow_rotation_C": (
        "8edaa587044d5d6d06a73785f482c66d44ad1eb7b0d50aa2949f238999a14c79",
        "baee83f9a4cd3ab00d469145fa27dbcd013364b2c127717320eb261ebb6b9d80"),
    "06_undisturbed_fast_rotation_A": (
        "61cb32774b40c33d16a172dbe06503b4a3cb0b2d3e9b8eae0df66c313506a8e2",
        "cb364973b61332562167c9d8263f8d8ef13056dfc31921486ead4044a8e46b24"),
    "09_undisturbed_fast_rotation_with_breaks_B": (
        "355a8bca7c89ba3012a2bad96656bf904d04337dfc2d8e3d50be980eb4e6df28",
        "2c33ff84452e8bc314c0bebc9555cf6c75542fc0394c6e549da90068ab02b0eb"),
    "10_undisturbed_slow_translation_A": (
        "eee6293f1d0aaf8d0ac025b873667f6f7697acad318057f4fd6a801fb31c93c1",
        "31cf6bd9ae6a53bf1966c648a97dec3596bc752d6999514ba83fd23080b72687"),
    "15_undisturbed_fast_translation_A": (
        "4290740d09dc3e055dd3cc939d083fa55321a9c90c0cb0aa3a6ffc26c4350951",
        "2a912345faa4758524c3a947ccc02522e76002989e61985ff59885be56e281dd"),
    "24_disturbed_tapping_A": (
        "1246fed1680a882a5f4d0dc2ae16e2db9dc90281fbaf1d486c84db1f27db51fa",
        "91fffe42b4c224109520c6b6df04bf24077959c0854a16c6e194277c3e4e5592"),
    "26_disturbed_phone_vibration_A": (
        "545dda7c8b00548cfa476d53fa7e520bfae98f40ad2dac1b5686f5fda5117735",
        "60e0644e476d144395f406e966ac05107247dde14c6e6bad6b806b91003136c0"),
    "28_disturbed_stationary_magnet_A": (
        "a909fb0b89ff454328cdb1151e6b796082b748a4cb5d6b00986a221649ccff42",
        "d55dd5b0a4f3b6ca06b7f0d335e9e9bafd5e7ce82dcbaaac471d4da31524c2c0"),
    "30_disturbed_stationary_magnet_C": (
        "a2749e93855ca115384c0d998dcdb088a2a6f1d46f743c5f37e5feb9b6ebb753",
        "1803eb134e829605a3402841b4c7fe74234787a2a8e4ab1c53333824d2e457a9"),
    "32_disturbed_attached_magnet_1cm": (
        "1919d236f89947247ccae26e7ad04a543da47686ea3fab6ad6855b7e0402c4f3",
        "b10c5243ceb2888f4730b743477972a9a40231ee36e1032ae701a7996856b091"),
    "34_disturbed_attached_magnet_3cm": (
        "b6fc1bc7c858b241cf0cfe5db57c364f8e5e92f44d22f0501a8b95e0d03f0264",
        "0337527149bd7f7622e281954734e14823526b1e076eed1c04495e3897170fe4"),
}
HEADER = "t,gx,gy,gz,ax,ay,az,mx,my,mz,qw,qx,qy,qz,movement"
ATTRIBUTION = """\
# BROAD: twelve trials, converted

From the Berlin Robust Orientation Estimation Assessment Dataset (BROAD): D. Laidig, M. Caruso,
A. Cereatti, T. Seel, "BROAD — A Benchmark for Robust Inertial Orientation Estimation", Data 6(7),
2021, doi:10.3390/data6070072; github.com/dlaidig/broad (commit {commit}). Licence: Creative
Commons Attribution 4.0 (CC BY 4.0). These files are a conversion of that data (IMU frame turned
180° about x to FRD, the field in gauss, the truth as q_ned_from_frd), made by the autopilot
project's tools/broad.py; keep this attribution with any copy.
"""


def cache_dir() -> Path:
    """Where `fetch` puts the trials: $XDG_CACHE_HOME/autopilot/broad, ~/.cache by default."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "autopilot" / "broad"


def candidates() -> list[tuple[str, Path]]:
    """The folders looked in, in order, each with what it is."""
    if os.environ.get(ENV_DIR):
        return [(f"${ENV_DIR}", Path(os.environ[ENV_DIR]))]
    return [("the shared folder beside the repository",
             ROOT.parent / "shared" / "benchmarks" / "broad"),
            ("the cache", cache_dir())]


def missing(folder: Path) -> list[str]:
    """The trials (names without .csv.gz) that `folder` lacks."""
    return [n for n in TRIALS if not (folder / f"{n}.csv.gz").is_file()]


def trials_dir() -> Path | None:
    """The first folder that holds all twelve trials, or None (`why_none()` says why)."""
    for _, folder in candidates():
        if not missing(folder):
            return folder
    return None


def why_none() -> str:
    """Why `trials_dir()` found nothing, and the command that fixes it."""
    looked = "; ".join(f"{what} {folder}: {len(missing(folder))} of {len(TRIALS)} trials missing"
                       for what, folder in candidates())
    return (f"the BROAD trials are not here ({looked}); fetch them with `{FETCH_COMMAND}` "
            f"(about 45 MB from github.com/dlaidig/broad, CC BY 4.0)")


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def csv_sha256(path: Path) -> str:
    """The SHA-256 of a trial's CSV, uncompressed; raises OSError on a missing or broken file."""
    try:
        return sha256(gzip.decompress(path.read_bytes()))
    except (EOFError, gzip.BadGzipFile) as e:
        raise OSError(f"{path}: not a whole gzip file ({e})") from e


def holds(path: Path, csv_sum: str) -> bool:
    """Whether `path` is a trial whose CSV has the checksum `csv_sum`."""
    try:
        return csv_sha256(path) == csv_sum
    except OSError:
        return False


def verify(folder: Path) -> list[str]:
    """Each trial in `folder` whose CSV is missing or differs from the pinned checksum, said."""
    problems = []
    for name, (_, csv_sum) in TRIALS.items():
        path = folder / f"{name}.csv.gz"
        try:
            got = csv_sha256(path)
        except OSError as e:
            problems.append(f"{path}: unreadable ({e})")
            continue
        if got != csv_sum:
            problems.append(f"{path}: SHA-256 {got} of its CSV, expected {csv_sum}")
    return problems


def quat_mul(a, b):
    """Hamilton product, row by row (numpy arrays of shape (…, 4))."""
    import numpy as np
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    w, x, y, z = np.moveaxis(b, -1, 0)
    return np.stack([aw * w - ax * x - ay * y - az * z,
                     aw * x + ax * w + ay * z - az * y,
                     aw * y - ax * z + ay * w + az * x,
                     aw * z + ax * y - ay * x + az * w], -1)


def convert(mat: bytes) -> str:
    """One BROAD trial's MATLAB file (its `imu_gyr`, `imu_acc`, `imu_mag`, `opt_quat`,
    `movement`, `sampling_rate`) as the replay CSV's text."""
    import numpy as np
    import scipy.io

    d = scipy.io.loadmat(io.BytesIO(mat), squeeze_me=True)
    # BROAD's IMU frame (x forward, y left, z up) turned 180° about x: (x, -y, -z) is FRD.
    frd = np.array([1.0, -1.0, -1.0])
    gyro, acc, mag = d["imu_gyr"] * frd, d["imu_acc"] * frd, d["imu_mag"] * frd / 100.0  # µT→G
    # q_ned_from_frd = q_ned_from_enu * q_enu_from_imu * q_imu_from_frd.
    ned_from_enu = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])
    imu_from_frd = np.array([0.0, 1.0, 0.0, 0.0])
    truth = quat_mul(quat_mul(ned_from_enu, np.atleast_2d(d["opt_quat"])), imu_from_frd)
    rate = float(d["sampling_rate"])
    movement = np.atleast_1d(d["movement"]).astype(int)
    n = len(gyro)
    if not (acc.shape == mag.shape == gyro.shape == (n, 3) and truth.shape == (n, 4)
            and movement.shape == (n,)):
        raise ValueError("not a BROAD trial: its arrays differ in length or width")
    g = lambda v: "%.10g" % (v + 0.0)  # + 0.0: no "-0"
    lines = [HEADER]
    for i in range(n):
        q = ",".join("%.7f" % v for v in truth[i]) if np.isfinite(truth[i, 0]) else ",,,"
        sensors = ",".join(g(v) for v in (*gyro[i], *acc[i], *mag[i]))
        lines.append(f"{g(i / rate)},{sensors},{q},{movement[i]}")
    return "\n".join(lines) + "\n"


def download(url: str, attempts: int = 3) -> bytes:
    """The bytes at `url` (http(s) or file), tried `attempts` times."""
    for attempt in range(1, attempts + 1):
        try:
            with urllib.request.urlopen(url, timeout=60) as r:
                return r.read()
        except OSError as e:
            if attempt == attempts:
                raise OSError(f"{url}: {e}") from e
            time.sleep(2 * attempt)
    raise AssertionError("unreachable")


def write_atomically(path: Path, data: bytes) -> None:
    """`data` at `path`, whole or not at all (a temporary file beside it, then a rename)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        os.fchmod(fd, 0o644)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def fetch(dest: Path, source: str = SOURCE, log=print) -> None:
    """Every trial not yet in `dest`: downloaded from `source` (a URL, or a folder of BROAD's
    .mat files), checked, converted, checked again and written. Raises ValueError on a checksum
    that does not match; nothing unchecked reaches `dest`."""
    if "://" not in source:
        source = Path(source).resolve().as_uri()
    dest.mkdir(parents=True, exist_ok=True)
    write_atomically(dest / "README.md",
                     ATTRIBUTION.format(commit=SOURCE.split("/")[-2]).encode())
    for k, (name, (mat_sum, csv_sum)) in enumerate(TRIALS.items(), 1):
        path = dest / f"{name}.csv.gz"
        if holds(path, csv_sum):
            log(f"[{k}/{len(TRIALS)}] {name}: already here")
            continue
        mat = download(f"{source}/{name}.mat")
        if sha256(mat) != mat_sum:
            raise ValueError(f"{name}.mat from {source}: SHA-256 {sha256(mat)}, expected "
                             f"{mat_sum}: not the pinned BROAD file, nothing written")
        csv = convert(mat).encode()
        if sha256(csv) != csv_sum:
            raise ValueError(f"{name}: the converted CSV's SHA-256 is {sha256(csv)}, expected "
                             f"{csv_sum} (a numpy or scipy that reads the file differently?)")
        write_atomically(path, gzip.compress(csv, compresslevel=9, mtime=0))
        log(f"[{k}/{len(TRIALS)}] {name}: {len(mat) / 1e6:.1f} MB, checked, converted")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("where", help="print the folder the tests will read, or why there is none")
    f = sub.add_parser("fetch", help="download, check and convert the trials into a folder")
    f.add_argument("--dest", type=Path, default=None,
                   help=f"default: ${ENV_DIR} if set, else the cache ({cache_dir()})")
    f.add_argument("--source", default=SOURCE,
                   help="BROAD's data_mat folder: a URL or a local folder (a mirror)")
    v = sub.add_parser("verify", help="check a folder's trials against the pinned checksums")
    v.add_argument("dir", type=Path, nargs="?", help="default: the folder `where` finds")
    a = ap.parse_args()
    if a.command == "where":
        found = trials_dir()
        print(found if found else why_none(), file=sys.stdout if found else sys.stderr)
        return 0 if found else 1
    if a.command == "fetch":
        dest = a.dest or Path(os.environ.get(ENV_DIR) or cache_dir())
        try:
            fetch(dest, a.source, log=lambda s: print(s, file=sys.stderr, flush=True))
        except (OSError, ValueError) as e:
            print(f"broad.py fetch: {e}", file=sys.stderr)
            return 1
        print(dest)
        return 0
    folder = a.dir or trials_dir()
    if folder is None:
        print(why_none(), file=sys.stderr)
        return 1
    problems = verify(folder)
    for p in problems:
        print(p, file=sys.stderr)
    if not problems:
        print(f"{folder}: the {len(TRIALS)} trials match their checksums")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
