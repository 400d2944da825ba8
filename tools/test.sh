#!/usr/bin/env bash
# Runs every test of the project on a fresh machine: formatting, lints, the Rust tests, then the
# Python end-to-end tests (pymavlink) from a pinned virtual environment this script creates.
set -euo pipefail
cd "$(dirname "$0")/.."

if command -v rustup >/dev/null 2>&1; then
    rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy"
cargo clippy --workspace --all-targets --quiet -- -D warnings
echo "== cargo test"
cargo test --workspace
# The Python tests drive the debug binaries that `cargo test` has just built.
cargo build --workspace --bins --quiet

echo "== python tests"
venv=.venv
stamp="$venv/.requirements"
if ! cmp -s tests/requirements.txt "$stamp" 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r tests/requirements.txt
    cp tests/requirements.txt "$stamp"
fi
"$venv/bin/python" -m pytest -q tests/python
