#!/usr/bin/env bash
# Coverage-guided fuzzing (cargo fuzz, libFuzzer) of every target in fuzz/: each runs for
# SECONDS (default 30) and its figures are printed (executions, executions per second, coverage
# edges and features, corpus size). Needs the nightly toolchain; without it this says so and
# skips (it never passes in silence). A crash fails the run and leaves its input in
# fuzz/artifacts/TARGET/ (replay it: cargo +nightly fuzz run TARGET FILE).
#   tools/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-30}"
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -eq 0 ]; then
    echo "usage: tools/fuzz.sh [SECONDS] [TARGET...] (SECONDS a whole number above 0, not $seconds)" >&2
    exit 2
fi
shift || true
if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "== fuzz: SKIPPED: no nightly toolchain (cargo +nightly), which cargo fuzz needs"
    exit 0
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    cargo install --quiet --locked cargo-fuzz --version 0.13.2
fi
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    listed="$(cargo +nightly fuzz list --fuzz-dir fuzz)"
    mapfile -t targets <<<"$listed"
fi
if [ ${#targets[@]} -eq 0 ] || [ -z "${targets[0]}" ]; then
    echo "== fuzz: no targets found in fuzz/" >&2
    exit 1
fi
# Safe Rust: no address sanitizer (twice the speed); panics and overflows abort as crashes.
flags=(--fuzz-dir fuzz --sanitizer none --release --debug-assertions)
echo "== fuzz: building ${targets[*]}"
cargo +nightly fuzz build "${flags[@]}"
for t in "${targets[@]}"; do
    mkdir -p "fuzz/corpus/$t"
    log="$(mktemp)"
    if ! cargo +nightly fuzz run "${flags[@]}" "$t" -- -max_total_time="$seconds" \
        -print_final_stats=1 -rss_limit_mb=2048 >"$log" 2>&1; then
        tail -n 40 "$log"
        echo "== fuzz: $t FAILED (a crash leaves its input in fuzz/artifacts/$t/; log: $log)"
        exit 1
    fi
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
    speed=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
    last=$(grep -E '^#[0-9]+' "$log" | tail -n 1 || true)
    cov=$(sed -n 's/.* cov: \([0-9]*\) .*/\1/p' <<<"$last")
    ft=$(sed -n 's/.* ft: \([0-9]*\) .*/\1/p' <<<"$last")
    corpus=$(sed -n 's/.* corp: \([0-9]*\)\/.*/\1/p' <<<"$last")
    peak=$(sed -n 's/^stat::peak_rss_mb: *//p' "$log")
    echo "== fuzz: $t: ${seconds} s, ${runs} executions (${speed}/s), coverage ${cov} edges ${ft} features, corpus ${corpus} inputs, peak RSS ${peak} MB, no crash"
    rm -f "$log"
done
