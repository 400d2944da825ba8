#!/usr/bin/env bash
# Runs every test of the project on a fresh machine: formatting, lints, the Rust tests, the
# Python end-to-end tests (pymavlink, MAVSDK-Python, MAVProxy) from a pinned virtual environment
# this script creates, the Python package's wheel installed into a fresh one with its examples
# run, then a short coverage-guided fuzzing run of every target.
set -euo pipefail
cd "$(dirname "$0")/.."

if command -v rustup >/dev/null 2>&1; then
    rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (at $SECONDS s)"
cargo clippy --workspace --all-targets --quiet -- -D warnings
echo "== layout lints (file length, unique type names) (at $SECONDS s)"
python3 tools/lint.py
echo "== cargo test (at $SECONDS s)"
cargo test --workspace
# The Python tests drive the debug binaries that `cargo test` has just built.
cargo build --workspace --bins --quiet

echo "== python tests (at $SECONDS s; $(df -h --output=avail /tmp | tail -1 | tr -d ' ') free in /tmp)"
venv=.venv
stamp="$venv/.requirements"
if ! cat tests/requirements.txt tests/requirements-nodeps.txt | cmp -s - "$stamp" 2>/dev/null; then
    python3 -m venv "$venv"
    pip=("$venv/bin/python" -m pip install --quiet --disable-pip-version-check)
    "${pip[@]}" -r tests/requirements.txt
    "${pip[@]}" --no-deps -r tests/requirements-nodeps.txt
    cat tests/requirements.txt tests/requirements-nodeps.txt > "$stamp"
fi
# -rs: the summary says why a test was skipped (the BROAD data not fetched, and how to fetch it).
# -n 2: two workers, one per CPU of the CI machine (every test takes its own ports and files).
# Only a failed test's files are kept: a passing run leaves nothing behind.
"$venv/bin/python" -m pytest -q -rs -n 2 --durations=20 -o tmp_path_retention_policy=failed tests/python

echo "== the Python package: its wheel in a fresh venv, its examples through the plugin (at $SECONDS s)"
tools/check_wheel.sh

echo "== fuzz (coverage-guided, a short run of each target) (at $SECONDS s)"
tools/fuzz.sh 12
echo "== all tests passed in $SECONDS s"
