"""Helpers shared by the Python end-to-end tests: find the binaries, run them on free ports."""

import os
import socket
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def binary(name: str) -> Path:
    """A binary built by tools/test.sh (debug profile unless PROFILE says otherwise)."""
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    path = target / os.environ.get("PROFILE", "debug") / name
    if not path.exists():
        pytest.fail(f"{path} not built: run tools/test.sh (it builds before testing)")
    return path


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def scenario(tmp_path):
    """Writes scenario TOML text to a file and returns its path."""

    def write(text: str) -> Path:
        path = tmp_path / "scenario.toml"
        path.write_text(text)
        return path

    return write


def run_sitl(args, port):
    return subprocess.Popen(
        [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--status-interval", "0",
         "--connect-timeout", "20", "--autopilot", f"127.0.0.1:{port}", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
