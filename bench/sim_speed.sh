#!/usr/bin/env bash
# Simulator speed, frame-level fast path against the bit-level reference in the same run, as
# one table: the real-time factor (simulated seconds per second) of `buslab sim --quiet` on a
# saturated 1 Mbit/s bus with 2, 16, 32 and 64 controller nodes, each offering about 2.5 times
# what the bus carries (8-byte frames, as `cargo bench -p buslab-sim`), with and without
# `--bit-level`. Both outputs are compared too (they must be identical).
#
# Per wall second and per second of CPU time (user + system; the machine is shared). FAST_S
# and BIT_S set the simulated seconds of each run; NODES the sizes; REPEAT how many runs each
# figure is the median of (by CPU time). Machines are noisy: compare the ratios of one run,
# and read the load average printed with the table.
#
# BASELINE=path/to/an/older/buslab adds, in the same run, that binary's fast path (CPU time)
# and how many times faster this one is: e.g. one built from main before a change.
#
# Instructions per frame (load-independent) come from callgrind: the fast path run for CG_S
# and for 2 × CG_S simulated seconds, the difference in instructions over the difference in
# frames (start-up cancels out). A second table does the same with the trace printed (not
# --quiet; stdout to a file), as `buslab sim` prints it, for TRACE_S simulated seconds; its
# outputs of both paths are compared over TRACE_CMP_S (default TRACE_S: the bit-level path is
# slow).
set -euo pipefail
cd "$(dirname "$0")/.."

FAST_S=${FAST_S:-30}
BIT_S=${BIT_S:-2}
NODES=${NODES:-"2 16 32 64"}
BASELINE=${BASELINE:-}
CG_S=${CG_S:-0.5}
TRACE_S=${TRACE_S:-$BIT_S}
# The traced outputs of both paths are compared over TRACE_CMP_S (the bit-level path is slow).
TRACE_CMP_S=${TRACE_CMP_S:-$TRACE_S}
REPEAT=${REPEAT:-1}


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

# run FILE SECONDS OUT [ARGS...]: prints "wall cpu" in seconds (binary: $bin, else $buslab),
# the median of REPEAT runs by CPU time, read with wait4 to the microsecond (GNU time's
# hundredths are a tenth of a 100 s run at 1 000×). QUIET=0 prints the trace.
run() {
    local file=$1 secs=$2 out=$3
    shift 3
    local quiet=--quiet
    [ "${QUIET:-1}" = 1 ] || quiet=
    python3 - "$REPEAT" "$out" "${bin:-$buslab}" sim "$file" $quiet --duration "${secs}s" "$@" <<'PY'
import os, subprocess, sys, time
repeat, out, argv = int(sys.argv[1]), sys.argv[2], sys.argv[3:]
runs = []
for _ in range(repeat):
    with open(out, "wb") as f:
        start = time.monotonic()
        child = subprocess.Popen(argv, stdout=f)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.monotonic() - start
    if status != 0:
        sys.exit(f"bench/sim_speed.sh: {' '.join(argv)} failed (wait status {status})")
    runs.append((usage.ru_utime + usage.ru_stime, wall))
cpu, wall = sorted(runs)[len(runs) // 2]
print(f"{wall:.4f} {cpu:.4f}")
PY
}

# frames OUT: the frame count of a run's summary.
frames() { sed -n 's/.* \([0-9][0-9]*\) frames, .*/\1/p' "$1" | tail -n 1; }

# irs FILE SECONDS: total instructions (callgrind) of the fast path for that long.
irs() {
    local quiet=--quiet
    [ "${QUIET:-1}" = 1 ] || quiet=
    valgrind --tool=callgrind --callgrind-out-file="$work/cg.out" \
        "${bin:-$buslab}" sim "$1" $quiet --duration "${2}s" >"$work/cg.txt" 2>/dev/null
    sed -n 's/^summary: \([0-9]*\).*/\1/p' "$work/cg.out"
}

# ir_per_frame FILE: instructions per frame, start-up cancelled (see the top).
ir_per_frame() {
    local a b fa fb
    a=$(irs "$1" "$CG_S")
    fa=$(frames "$work/cg.txt")
    b=$(irs "$1" "$(awk -v s="$CG_S" 'BEGIN { print 2 * s }')")
    fb=$(frames "$work/cg.txt")
    awk -v a="$a" -v b="$b" -v fa="$fa" -v fb="$fb" 'BEGIN { printf "%.0f", (b - a) / (fb - fa) }'
}

factor() { awk -v s="$1" -v t="$2" 'BEGIN { printf (t > 0 ? "%.1f" : "inf"), s / t }'; }

command -v valgrind >/dev/null || {
    echo "bench/sim_speed.sh: valgrind is missing (apt-get install valgrind)" >&2
    exit 1
}

echo "# buslab sim, saturated 1 Mbit/s bus, 8-byte frames; real-time factor = simulated s / s"
echo "# fast path: ${FAST_S} s simulated per run; --bit-level: ${BIT_S} s; median of ${REPEAT} run(s); load average: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# Ir/frame: callgrind instructions per frame of the fast path (${CG_S} s against $(awk -v s="$CG_S" 'BEGIN { print 2 * s }') s)"
[ -z "$BASELINE" ] || echo "# baseline: $BASELINE (fast path, CPU time, same scenario and duration)"
printf '%-6s %14s %14s %14s %14s %10s %10s %-11s %9s' nodes "fast (wall)" "fast (CPU)" \
    "bit (wall)" "bit (CPU)" "wall ratio" "CPU ratio" "same output" "Ir/frame"
[ -z "$BASELINE" ] && echo || printf ' %14s %9s %13s\n' "baseline (CPU)" "speed-up" "base Ir/frame"
for n in $NODES; do
    file=$work/sat$n.toml
    scenario "$n" "$file"
    read -r fw fc <<<"$(run "$file" "$FAST_S" "$work/fast.out")"
    read -r bw bc <<<"$(run "$file" "$BIT_S" "$work/bit.out" --bit-level)"
    # The same stretch of simulated time must print the same with either path.
    REPEAT=1 run "$file" "$BIT_S" "$work/fast_short.out" >/dev/null
    same=no
    cmp -s "$work/fast_short.out" "$work/bit.out" && same=yes
    ffw=$(factor "$FAST_S" "$fw")
    ffc=$(factor "$FAST_S" "$fc")
    fbw=$(factor "$BIT_S" "$bw")
    fbc=$(factor "$BIT_S" "$bc")
    printf '%-6s %13s× %13s× %13s× %13s× %9s× %9s× %-11s %9s' "$n" "$ffw" "$ffc" "$fbw" "$fbc" \
        "$(factor "$ffw" "$fbw")" "$(factor "$ffc" "$fbc")" "$same" "$(ir_per_frame "$file")"
    if [ -n "$BASELINE" ]; then
        read -r _ oc <<<"$(bin=$BASELINE run "$file" "$FAST_S" "$work/base.out")"
        fo=$(factor "$FAST_S" "$oc")
        printf ' %13s× %8s× %13s\n' "$fo" "$(factor "$ffc" "$fo")" "$(bin=$BASELINE ir_per_frame "$file")"
    else
        echo
    fi
done

echo "#"
echo "# the same with the trace printed (stdout to a file): ${TRACE_S} s simulated per run; outputs compared over ${TRACE_CMP_S} s"
printf '%-6s %14s %14s %-11s %9s' nodes "fast (wall)" "fast (CPU)" "same output" "Ir/frame"
[ -z "$BASELINE" ] && echo || printf ' %14s %9s %13s\n' "baseline (CPU)" "speed-up" "base Ir/frame"
for n in $NODES; do
    file=$work/sat$n.toml
    read -r fw fc <<<"$(QUIET=0 run "$file" "$TRACE_S" "$work/fast.out")"
    REPEAT=1 QUIET=0 run "$file" "$TRACE_CMP_S" "$work/bit.out" --bit-level >/dev/null
    REPEAT=1 QUIET=0 run "$file" "$TRACE_CMP_S" "$work/fast_short.out" >/dev/null
    same=no
    cmp -s "$work/fast_short.out" "$work/bit.out" && same=yes
    ffc=$(factor "$TRACE_S" "$fc")
    printf '%-6s %13s× %13s× %-11s %9s' "$n" "$(factor "$TRACE_S" "$fw")" "$ffc" "$same" \
        "$(QUIET=0 ir_per_frame "$file")"
    if [ -n "$BASELINE" ]; then
        read -r _ oc <<<"$(QUIET=0 bin=$BASELINE run "$file" "$TRACE_S" "$work/base.out")"
        fo=$(factor "$TRACE_S" "$oc")
        printf ' %13s× %8s× %13s\n' "$fo" "$(factor "$ffc" "$fo")" \
            "$(QUIET=0 bin=$BASELINE ir_per_frame "$file")"
    else
        echo
    fi
done
echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
