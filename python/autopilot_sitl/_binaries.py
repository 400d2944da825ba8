"""Where the `autopilot` and `sitl` binaries are: the ones a directory named by
AUTOPILOT_SITL_BIN_DIR holds (a source checkout's target/debug), else the ones installed with
this package (the environment's scripts directory), else the first on PATH."""

import os
import shutil
import sysconfig
from pathlib import Path


def binary(name: str) -> Path:
    """The path of binary `name` (`autopilot` or `sitl`); FileNotFoundError naming where it
    looked if there is none."""
    looked = []
    given = os.environ.get("AUTOPILOT_SITL_BIN_DIR")
    if given:
        path = Path(given) / name
        if path.is_file():
            return path
        looked.append(str(path))
    scripts = Path(sysconfig.get_path("scripts")) / name
    if scripts.is_file():
        return scripts
    looked.append(str(scripts))
    found = shutil.which(name)
    if found:
        return Path(found)
    looked.append(f"{name} on PATH")
    raise FileNotFoundError(
        f"no {name} binary: looked at {', '.join(looked)} (install the autopilot-sitl wheel, "
        "or set AUTOPILOT_SITL_BIN_DIR to a directory holding it)")
