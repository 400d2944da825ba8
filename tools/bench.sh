#!/usr/bin/env bash
# Prints the project's speed figures (criterion benchmarks) as one table.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo bench -p sitl-core --bench physics -- --warm-up-time 1 --measurement-time 3 "$@" 2>&1 |
    awk '/^(physics|flight)/ {name=$1} /time:/ {sub(/.*time: *\[/, ""); split($0, v, " "); printf "%-50s %s %s\n", name, v[3], v[4]}'
