#!/usr/bin/env bash
# Simulator speed, frame-level fast path against the bit-level reference in the same run, as
# one table: the real-time factor (simulated seconds per second) of `buslab sim --quiet` on a
# saturated 1 Mbit/s bus with 2, 16, 32 and 64 controller nodes, each offering about 2.5 times
# what the bus carries (8-byte frames, as `cargo bench -p buslab-sim`), with and without
# `--bit-level`. Both outputs are compared too (they must be identical).
#
# Per wall second and per second of CPU time (user + system; the machine is shared). FAST_S
# and BIT_S set the simulated seconds of each run; NODES the sizes. Machines are noisy: compare
# the ratios of one run, and read the load average printed with the table.
#
# BASELINE=path/to/an/older/buslab adds, in the same run, that binary's fast path (CPU time)
# and how many times faster this one is: e.g. one built from main before a change.
set -euo pipefail
cd "$(dirname "$0")/.."

FAST_S=${FAST_S:-30}
BIT_S=${BIT_S:-2}
NODES=${NODES:-"2 16 32 64"}
BASELINE=${BASELINE:-}

[ -x /usr/bin/time ] || {
    echo "bench/sim_speed.sh: /usr/bin/time is missing (apt-get install time)" >&2
    exit 1
}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p buslab --bin buslab
buslab=target/release/buslab

# scenario NODES FILE: every node sends its own 8-byte frame every 50 µs × NODES.
scenario() {
    local n=$1
    {
        echo "bitrate = 1000000"
        echo "duration = \"1s\""
        for ((i = 0; i < n; i++)); do
            printf '[[nodes]]\nname = "n%d"\n  [[nodes.traffic]]\n  kind = "periodic"\n' "$i"
            printf '  frame = "%03X#%02X55AA0001020304"\n  period = "%dus"\n' $((0x100 + i)) "$i" $((50 * n))
        done
    } >"$2"
}

# run FILE SECONDS OUT [ARGS...]: prints "wall cpu" in seconds (binary: $bin, else $buslab).
run() {
    local file=$1 secs=$2 out=$3
    shift 3
    /usr/bin/time -f "%e %U %S" -o "$work/time" \
        "${bin:-$buslab}" sim "$file" --quiet --duration "${secs}s" "$@" >"$out"
    awk '{ printf "%s %.3f", $1, $2 + $3 }' "$work/time"
}

factor() { awk -v s="$1" -v t="$2" 'BEGIN { printf (t > 0 ? "%.1f" : "inf"), s / t }'; }

echo "# buslab sim, saturated 1 Mbit/s bus, 8-byte frames; real-time factor = simulated s / s"
echo "# fast path: ${FAST_S} s simulated per run; --bit-level: ${BIT_S} s; load average: $(cut -d' ' -f1-3 /proc/loadavg)"
[ -z "$BASELINE" ] || echo "# baseline: $BASELINE (fast path, CPU time, same scenario and duration)"
printf '%-6s %14s %14s %14s %14s %10s %10s %-11s' nodes "fast (wall)" "fast (CPU)" \
    "bit (wall)" "bit (CPU)" "wall ratio" "CPU ratio" "same output"
[ -z "$BASELINE" ] && echo || printf ' %14s %9s\n' "baseline (CPU)" "speed-up"
for n in $NODES; do
    file=$work/sat$n.toml
    scenario "$n" "$file"
    read -r fw fc <<<"$(run "$file" "$FAST_S" "$work/fast.out")"
    read -r bw bc <<<"$(run "$file" "$BIT_S" "$work/bit.out" --bit-level)"
    # The same stretch of simulated time must print the same with either path.
    run "$file" "$BIT_S" "$work/fast_short.out" >/dev/null
    same=no
    cmp -s "$work/fast_short.out" "$work/bit.out" && same=yes
    ffw=$(factor "$FAST_S" "$fw")
    ffc=$(factor "$FAST_S" "$fc")
    fbw=$(factor "$BIT_S" "$bw")
    fbc=$(factor "$BIT_S" "$bc")
    printf '%-6s %13s× %13s× %13s× %13s× %9s× %9s× %-11s' "$n" "$ffw" "$ffc" "$fbw" "$fbc" \
        "$(factor "$ffw" "$fbw")" "$(factor "$ffc" "$fbc")" "$same"
    if [ -n "$BASELINE" ]; then
        read -r _ oc <<<"$(bin=$BASELINE run "$file" "$FAST_S" "$work/base.out")"
        fo=$(factor "$FAST_S" "$oc")
        printf ' %13s× %8s×\n' "$fo" "$(factor "$ffc" "$fo")"
    else
        echo
    fi
done
echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
