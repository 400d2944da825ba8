#!/usr/bin/env bash
# Many vehicles as separate processes, as PX4's sitl_multiple_run.sh: N simulator processes
# (`sitl -i k`) and N autopilots (`autopilot -i k`), k = 0 … N − 1. Instance k is MAVLink
# system k + 1; its simulator talks to it on UDP HIL_PORT + k; its ground-station ports are the
# autopilot's defaults offset by k (QGroundControl hears every vehicle on 14550, MAVSDK finds
# vehicle k on 14540 + k, TCP on 5760 + k); its home is 3 k m east of the site's.
#
#   tools/swarm.sh N [autopilot options …]
#   tools/swarm.sh 5 --takeoff 5 --hover 10          # five take off, hover and land on their own
#
# The options after N go to every autopilot (--airframe goes to the simulators too). Ctrl-C
# lands every vehicle (twice: stops at once); the run ends when every autopilot has ended, and
# each one's summary line is printed. Environment: SWARM_BIN (the binaries' directory; default
# target/release, built if missing), SWARM_LOG_DIR (each process's output; default
# logs/swarm), SWARM_HIL_PORT (default 4560; the N ports from it must lie outside the kernel's
# ephemeral range, where a simulator's own port could take an autopilot's: refused otherwise),
# SWARM_SITL_ARGS (more simulator options, e.g. "--speed 1" to watch in real time). The exit
# status is 0 when every autopilot's was.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() { sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[[ $# -ge 1 && $1 =~ ^[0-9]+$ && $1 -ge 1 && $1 -le 251 ]] || usage
count=$1
shift
bin=${SWARM_BIN:-target/release}
log_dir=${SWARM_LOG_DIR:-logs/swarm}
hil_port=${SWARM_HIL_PORT:-4560}
read -r -a sitl_args <<<"${SWARM_SITL_ARGS:-}"
# Each simulator sends from a port the kernel picks in its ephemeral range: an autopilot's HIL
# port in that range could be taken before the autopilot binds it. Outside it, never.
read -r eph_low eph_high </proc/sys/net/ipv4/ip_local_port_range 2>/dev/null || eph_low='' eph_high=''
if [[ -n $eph_low ]] && ((hil_port <= eph_high && hil_port + count - 1 >= eph_low)); then
    echo "swarm: HIL ports $hil_port-$((hil_port + count - 1)) overlap the kernel's ephemeral ports" \
        "$eph_low-$eph_high (a simulator's own port could take an autopilot's):" \
        "set SWARM_HIL_PORT below $((eph_low - count + 1)) or above $eph_high" >&2
    exit 2
fi
if [[ ! -x $bin/sitl || ! -x $bin/autopilot ]]; then
    [[ $bin == target/release ]] || { echo "swarm: no sitl/autopilot in $bin" >&2; exit 1; }
    cargo build --release --bins
fi
# The airframe, if given, is the simulators' too.
airframe=()
for ((a = 1; a <= $#; a++)); do
    if [[ ${!a} == --airframe ]]; then
        next=$((a + 1))
        airframe=(--airframe "${!next}")
    fi
done
mkdir -p "$log_dir"

sims=() aps=()
stop_sims() {
    for p in "${sims[@]}"; do kill -INT "$p" 2>/dev/null || true; done
    wait "${sims[@]}" 2>/dev/null || true
}
trap stop_sims EXIT
trap 'for p in "${aps[@]}"; do kill -INT "$p" 2>/dev/null || true; done' INT TERM

for ((k = 0; k < count; k++)); do
    "$bin/autopilot" -i "$k" --source "udp://127.0.0.1:$hil_port" "$@" \
        >"$log_dir/autopilot_$k.log" 2>&1 &
    aps+=($!)
    "$bin/sitl" -i "$k" --autopilot "127.0.0.1:$hil_port" --seed $((k + 1)) \
        --status-interval 0 --duration 86400 "${airframe[@]}" "${sitl_args[@]}" \
        >"$log_dir/sitl_$k.log" 2>&1 &
    sims+=($!)
done
echo "swarm: $count vehicles (systems 1 to $count), output in $log_dir/" >&2

failed=0
for ((k = 0; k < count; k++)); do
    p=${aps[$k]}
    # A trapped Ctrl-C interrupts `wait`: wait again until the autopilot has ended.
    while true; do
        status=0
        wait "$p" || status=$?
        kill -0 "$p" 2>/dev/null || break
    done
    if [[ $status -ne 0 ]]; then
        failed=$((failed + 1))
        echo "swarm: autopilot $k exited with status $status (see $log_dir/autopilot_$k.log)" >&2
    fi
    grep -h "^autopilot summary:" "$log_dir/autopilot_$k.log" | sed "s/\$/ system_id=$((k + 1))/" || true
done
echo "swarm: $((count - failed)) of $count autopilots ended cleanly" >&2
[[ $failed -eq 0 ]]
