#!/usr/bin/env bash
# Prints the project's speed figures (criterion benchmarks) as one table.
set -euo pipefail
cd "$(dirname "$0")/.."
for bench in "sitl-core physics" "flight-core tick"; do
    set -- $bench
    cargo bench -p "$1" --bench "$2" -- --warm-up-time 1 --measurement-time 3 2>&1 |
        awk '/^(physics|flight)/ {name=$1} /time:/ {sub(/.*time: *\[/, ""); split($0, v, " "); printf "%-50s %s %s\n", name, v[3], v[4]}'
done
