#!/usr/bin/env bash
# Simulator speed on a bus that mixes every node kind, frame-level fast path against the
# bit-level reference in the same run: `buslab sim --quiet` at 125 kbit/s (the SLIO's highest
# rate) with 4 SJA1000 nodes operated by buslab's driver, 3 protocol controllers and a host
# that keeps 3 SLIO demo boards calibrated and reads their inputs (its frames and the SLIOs'
# answers have the higher priority, so the SLIOs stay calibrated); the other senders offer
# about 2.5 times what the bus carries. Prints the real-time factor (simulated seconds per second,
# per wall second and per CPU second), the share of frames applied whole is shown by
# `cargo nextest run -p buslab-canbus -E 'binary(whole_frames_mixed)' --no-capture`.
#
# BEFORE=path/to/another/buslab adds a row for that binary (e.g. one built before the SJA1000
# and SLIO nodes took whole frames). FAST_S and BIT_S set the simulated seconds of each run.
set -euo pipefail
cd "$(dirname "$0")/.."

FAST_S=${FAST_S:-100}
BIT_S=${BIT_S:-10}
BEFORE=${BEFORE:-}

[ -x /usr/bin/time ] || {
    echo "bench/mixed_sim_speed.sh: /usr/bin/time is missing (apt-get install time)" >&2
    exit 1
}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p buslab --bin buslab
buslab=target/release/buslab

file=$work/mixed.toml
{
    echo 'bitrate = 125000'
    echo 'duration = "1s"'
    echo 'seed = 1'
    printf '[[nodes]]\nname = "host"\n'
    printf '  [[nodes.traffic]]\n  kind = "periodic"\n  frame = "0AA#AA04"\n  period = "5000bits"\n'
    for slio in 0 3 A; do
        # A remote frame for the SLIO's answer identifier reads its inputs.
        case $slio in 0) id=285 ;; 3) id=29D ;; A) id=395 ;; esac
        printf '  [[nodes.traffic]]\n  kind = "periodic"\n  frame = "%s#R3"\n  period = "10ms"\n' "$id"
    done
    for slio in 0 3 A; do
        printf '[[nodes]]\nname = "slio%s"\nkind = "slio"\nid = "%s"\n' "$slio" "$slio"
    done
    for i in 0 1 2 3; do
        printf '[[nodes]]\nname = "sja%d"\nkind = "sja1000"\n' "$i"
        printf '  [[nodes.traffic]]\n  kind = "periodic"\n  frame = "%03X#%02X55AA0001020304"\n  period = "2400us"\n' $((0x500 + i)) "$i"
    done
    for i in 0 1 2; do
        printf '[[nodes]]\nname = "c%d"\n' "$i"
        printf '  [[nodes.traffic]]\n  kind = "periodic"\n  frame = "%03X#%02X55AA0001020304"\n  period = "2400us"\n' $((0x600 + i)) "$i"
    done
} >"$file"

# run BINARY SECONDS OUT [ARGS...]: prints "wall cpu" in seconds.
run() {
    local bin=$1 secs=$2 out=$3
    shift 3
    /usr/bin/time -f "%e %U %S" -o "$work/time" \
        "$bin" sim "$file" --quiet --duration "${secs}s" "$@" >"$out"
    awk '{ printf "%s %.3f", $1, $2 + $3 }' "$work/time"
}

factor() { awk -v s="$1" -v t="$2" 'BEGIN { printf (t > 0 ? "%.1f" : "inf"), s / t }'; }

row() {
    local name=$1 secs=$2 wall=$3 cpu=$4 same=$5
    printf '%-26s %8s %10s %10s %10s× %10s× %s\n' "$name" "${secs}s" "$wall" "$cpu" \
        "$(factor "$secs" "$wall")" "$(factor "$secs" "$cpu")" "$same"
}

echo "# buslab sim, mixed 125 kbit/s bus (4 SJA1000 + 3 SLIO boards + 4 controllers), saturated"
echo "# load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '%-26s %8s %10s %10s %11s %11s %s\n' run simulated "wall s" "CPU s" "RT (wall)" \
    "RT (CPU)" "same output as --bit-level"
read -r bw bc <<<"$(run "$buslab" "$BIT_S" "$work/bit.out" --bit-level)"
read -r fw fc <<<"$(run "$buslab" "$FAST_S" "$work/fast.out")"
run "$buslab" "$BIT_S" "$work/fast_short.out" >/dev/null
same=no
cmp -s "$work/fast_short.out" "$work/bit.out" && same=yes
row "fast path" "$FAST_S" "$fw" "$fc" "$same"
row "--bit-level" "$BIT_S" "$bw" "$bc" "(reference)"
if [ -n "$BEFORE" ]; then
    read -r ow oc <<<"$(run "$BEFORE" "$FAST_S" "$work/before.out")"
    run "$BEFORE" "$BIT_S" "$work/before_short.out" >/dev/null
    same=no
    cmp -s "$work/before_short.out" "$work/bit.out" && same=yes
    row "BEFORE (its fast path)" "$FAST_S" "$ow" "$oc" "$same"
fi
echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
