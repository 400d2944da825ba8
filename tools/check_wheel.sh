#!/usr/bin/env bash
# The Python package as a user gets it: builds the autopilot-sitl wheel, installs it into a fresh
# virtual environment with nothing else of the project (only the examples' pinned dependencies),
# and runs python/examples/ through the pytest plugin, two tests at a time, from a directory
# outside the checkout, with an environment that has no Rust toolchain and no path into it.
# Prints the wheel's size; fails if a process of the run outlives it.
#
#   tools/check_wheel.sh          # the dev profile (what tools/test.sh has just built)
#   WHEEL_PROFILE=release tools/check_wheel.sh
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
work=$(mktemp -d "${TMPDIR:-/tmp}/autopilot-wheel.XXXXXX")
# setuptools builds in the tree: its byproducts go with the run, lest python/ on a path show the
# package as installed (its egg-info names the plugin's entry point).
trap 'rm -rf "$work" "$root/build" "$root"/python/*.egg-info' EXIT

echo "-- building the wheel (cargo profile ${WHEEL_PROFILE:-dev})"
SETUPTOOLS_RUST_CARGO_PROFILE=${WHEEL_PROFILE:-dev} \
    python3 -m pip wheel --quiet --disable-pip-version-check --no-deps -w "$work/dist" .
rm -rf build python/*.egg-info
wheel=$(ls "$work"/dist/autopilot_sitl-*.whl)
echo "-- $(basename "$wheel"): $(( $(stat -c %s "$wheel") / 1024 )) KiB"

echo "-- a fresh virtual environment: the wheel and the examples' pinned dependencies"
python3 -m venv "$work/venv"
pip=("$work/venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps)
"${pip[@]}" -r python/examples/requirements.txt
"${pip[@]}" "$wheel"
"$work/venv/bin/python" -m pip check --disable-pip-version-check

mkdir "$work/suite"
cp python/examples/test_*.py "$work/suite/"
cd "$work/suite"
# Nothing of the checkout or of Rust: a bare PATH, no AUTOPILOT_SITL_BIN_DIR, no CARGO_*.
run=(env -i HOME="$HOME" LANG=C.UTF-8 PATH="$work/venv/bin:/usr/bin:/bin")
if "${run[@]}" sh -c 'command -v cargo || command -v rustc'; then
    echo "a Rust toolchain is on the examples' PATH" >&2
    exit 1
fi
echo "-- the binaries: $("${run[@]}" sh -c 'command -v autopilot; command -v sitl' | tr '\n' ' ')"
case "$("${run[@]}" sh -c 'command -v autopilot')" in
    "$work/venv/bin/autopilot") ;;
    *) echo "autopilot is not the wheel's" >&2; exit 1 ;;
esac
"${run[@]}" autopilot --sim --takeoff 2 --hover 0 --speed max --mavlink none --log-dir none \
    --param-store none 2>/dev/null | grep "autopilot summary:.*landed=true" >/dev/null
echo "-- the examples, through the plugin (pytest -n 2)"
"${run[@]}" python -m pytest -q -n 2 -p no:cacheprovider --basetemp="$work/tmp" .
command -v pgrep >/dev/null || { echo "pgrep (procps) is needed to look for leftovers" >&2; exit 1; }
left=$(pgrep -f "$work" || true)
if [ -n "$left" ]; then
    echo "processes outlived the run: $left" >&2
    exit 1
fi
echo "-- the wheel installs and its examples pass (${SECONDS} s)"
cd "$root"
