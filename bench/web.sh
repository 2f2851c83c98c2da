#!/usr/bin/env bash
# buslab web under a saturated bus: a 1 Mbit/s virtual bus filled by `buslab gen --gap 0s`
# (8-byte frames, about 8 k frames/s), VIEWERS live dashboards (SSE streams read by curl),
# and the web server's CPU time over MEASURE_SECONDS (20) seconds (its own utime+stime from /proc, as a
# share of one core). Targets (issue 12): keeps up with the bus (frames/s as the bus's own),
# CPU < 30 % of a core with 5 viewers, at most 20 updates per second per viewer.
#
# Needs curl. VIEWERS, MEASURE_SECONDS and BUSLAB change the run. Machines are noisy: run it more than once.
set -euo pipefail
cd "$(dirname "$0")/.."

VIEWERS=${VIEWERS:-5}
SECONDS_MEASURED=${MEASURE_SECONDS:-20}
command -v curl >/dev/null 2>&1 || { echo "bench/web.sh: curl is missing" >&2; exit 1; }

# BUSLAB=path measures that binary instead of a fresh release build (a debug build gives an
# upper bound).
if [ -n "${BUSLAB:-}" ]; then
    buslab=$BUSLAB
else
    cargo build --release -q -p buslab --bin buslab
    buslab=target/release/buslab
fi
work=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT

# Waits for a process's first line of output, failing (never hanging) if it died first or
# said nothing for a minute.
first_line() { # FILE PID WHAT
    local tries=0
    until [ -s "$1" ]; do
        kill -0 "$2" 2>/dev/null || { echo "bench/web.sh: $3 exited: $(cat "$1.err" 2>/dev/null)" >&2; exit 1; }
        tries=$((tries + 1))
        [ "$tries" -lt 600 ] || { echo "bench/web.sh: $3 said nothing for 60 s" >&2; exit 1; }
        sleep 0.1
    done
    head -1 "$1"
}

"$buslab" -q bus serve --listen 127.0.0.1:0 --bitrate 1000000 >"$work/serve.out" 2>"$work/serve.out.err" &
serve_pid=$!
pids+=($serve_pid)
bus=$(first_line "$work/serve.out" "$serve_pid" "buslab bus serve")
"$buslab" -q gen --bus "$bus" --gap 0s -L 8 >/dev/null 2>&1 &
pids+=($!)
"$buslab" -q web --bus "$bus" --listen 127.0.0.1:0 >"$work/web.out" 2>"$work/web.out.err" &
web_pid=$!
pids+=($web_pid)
url=$(first_line "$work/web.out" "$web_pid" "buslab web")
for i in $(seq 1 "$VIEWERS"); do
    curl -sN "${url}api/events" >"$work/viewer$i" &
    pids+=($!)
done
sleep 5 # the viewers connected and the bus is full

ticks() { awk '{print $14 + $15}' "/proc/$web_pid/stat"; }
hz=$(getconf CLK_TCK)
before=$(ticks)
lines_before=$(cat "$work"/viewer* | grep -c '^event: update' || true)
sleep "$SECONDS_MEASURED"
after=$(ticks)
lines_after=$(cat "$work"/viewer* | grep -c '^event: update' || true)
state=$(curl -s --max-time 30 "${url}api/state?n=0")
fps=$(printf '%s' "$state" | sed -n 's/.*"frames_per_s":\([0-9]*\).*/\1/p')
load=$(printf '%s' "$state" | grep -o '"percent":[0-9.]*' | tail -1 | cut -d: -f2)
cpu=$(awk -v a="$after" -v b="$before" -v hz="$hz" -v s="$SECONDS_MEASURED" \
    'BEGIN { printf "%.1f", 100 * (a - b) / hz / s }')
updates=$(awk -v a="$lines_after" -v b="$lines_before" -v v="$VIEWERS" -v s="$SECONDS_MEASURED" \
    'BEGIN { printf "%.1f", (a - b) / v / s }')
lost=$(tail -n 50 "$work/viewer1" | grep -o '"lost":[0-9]*' | tail -1 | cut -d: -f2)

echo "| viewers | bus frames/s (seen by web) | bus load | web CPU (% of a core) | updates/s per viewer | frames lost by viewer 1 |"
echo "|---|---|---|---|---|---|"
echo "| $VIEWERS | $fps | ${load:-?} % | $cpu | $updates | ${lost:-?} |"
