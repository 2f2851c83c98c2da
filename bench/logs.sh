#!/usr/bin/env bash
# Log conversion speed and memory, buslab against its peers in the same run, as one table:
# - candump log → ASC: `buslab log convert` vs can-utils `log2asc` vs `python -m can.logconvert`
#   on a deterministic 1 M-frame candump log (targets: ≥ 5× log2asc, ≥ 30× python-can);
# - candump parsing on one core (target ≥ 10 M frames/s): crates/logs/examples/candump_rate,
#   per second of the thread's own CPU time (the machine is shared; wall time is shown too;
#   `cargo bench -p buslab-logs --bench candump` is the criterion view of the same loop);
# - peak RSS converting a 1 GB candump log to ASC and to BLF (target < 50 MB).
#
# Needs what scripts/setup-test-deps.sh installs (can-utils, .venv with python-can) and
# /usr/bin/time. FRAMES and BIG_MB change the sizes. Machines are noisy: compare the ratios.
set -euo pipefail
cd "$(dirname "$0")/.."

FRAMES=${FRAMES:-1000000}
BIG_MB=${BIG_MB:-1024}
PYTHON=${PYTHON:-.venv/bin/python}

for tool in log2asc /usr/bin/time "$PYTHON"; do
    command -v "$tool" >/dev/null 2>&1 || {
        echo "bench/logs.sh: $tool is missing (scripts/setup-test-deps.sh installs it)" >&2
        exit 1
    }
done

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p buslab --bin buslab
cargo build --release -q -p buslab-logs --example candump_rate
buslab=target/release/buslab

# A candump log like a busy two-interface bus: 30 % extended IDs, 0..8 bytes, 50..500 µs apart.
"$PYTHON" - "$work/in.log" "$FRAMES" <<'EOF'
import random, sys
r = random.Random(42)
t = 1_700_000_000_000_000
with open(sys.argv[1], "w") as f:
    for _ in range(int(sys.argv[2])):
        t += r.randrange(50, 500)
        iface = "can1" if r.random() < 0.2 else "can0"
        ident = f"{r.randrange(0x20000000):08X}" if r.random() < 0.3 else f"{r.randrange(0x800):03X}"
        data = "".join(f"{r.randrange(256):02X}" for _ in range(r.randrange(9)))
        f.write(f"({t // 1_000_000}.{t % 1_000_000:06d}) {iface} {ident}#{data}\n")
EOF

# Runs a command; sets secs and rss_mb from /usr/bin/time.
measure() {
    /usr/bin/time -f "%e %M" -o "$work/time" "$@" >/dev/null 2>"$work/err" || {
        cat "$work/err" >&2
        exit 1
    }
    read -r secs rss_kb <"$work/time"
    rss_mb=$(awk -v k="$rss_kb" 'BEGIN { printf "%.1f", k / 1024 }')
}

rate() { awk -v n="$1" -v s="$2" 'BEGIN { printf "%.2f", n / s / 1e6 }'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1fx", a / b }'; }

load_before=$(cut -d' ' -f1-3 /proc/loadavg)

measure "$buslab" -q log convert "$work/in.log" "$work/buslab.asc"
b_secs=$secs b_rss=$rss_mb
measure log2asc -I "$work/in.log" -O "$work/log2asc.asc" can0 can1
l_secs=$secs l_rss=$rss_mb
measure "$PYTHON" -m can.logconvert "$work/in.log" "$work/python.asc"
p_secs=$secs p_rss=$rss_mb
parse=$(target/release/examples/candump_rate "$work/in.log" 5)
parse_cpu=$(sed -E 's/.*: ([0-9.]+) M frames\/s of CPU.*/\1/' <<<"$parse")
parse_wall=$(sed -E 's/.*, ([0-9.]+) M frames\/s of wall.*/\1/' <<<"$parse")

# The 1 GB input: the log again and again (a streaming reader cannot tell).
size=$(stat -c %s "$work/in.log")
copies=$(( (BIG_MB * 1024 * 1024 + size - 1) / size ))
for _ in $(seq "$copies"); do cat "$work/in.log"; done >"$work/big.log"
big_mb=$(( $(stat -c %s "$work/big.log") / 1024 / 1024 ))
rm -f "$work/buslab.asc" "$work/log2asc.asc" "$work/python.asc"
measure "$buslab" -q log convert "$work/big.log" "$work/big.asc"
g_secs=$secs g_rss=$rss_mb
rm -f "$work/big.asc"
measure "$buslab" -q log convert "$work/big.log" "$work/big.blf"
gb_secs=$secs gb_rss=$rss_mb

printf '\ncandump -> ASC, %s frames (%s MB); load average %s before, %s after\n\n' \
    "$FRAMES" $((size / 1024 / 1024)) "$load_before" "$(cut -d' ' -f1-3 /proc/loadavg)"
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "run" "time (s)" "M frames/s" "RSS (MB)" "buslab is"
printf '|%s|%s|%s|%s|%s|\n' "$(printf -- '-%.0s' {1..46})" "-----------" "---------------" "-----------" "----------------------------------"
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "buslab log convert in.log out.asc" "$b_secs" "$(rate "$FRAMES" "$b_secs")" "$b_rss" ""
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "log2asc (can-utils 2020.11)" "$l_secs" "$(rate "$FRAMES" "$l_secs")" "$l_rss" "$(ratio "$l_secs" "$b_secs") faster (target >= 5x)"
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "python -m can.logconvert (python-can 4.6.1)" "$p_secs" "$(rate "$FRAMES" "$p_secs")" "$p_rss" "$(ratio "$p_secs" "$b_secs") faster (target >= 30x)"
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "candump parse, one core, best round (CPU)" "" "$parse_cpu" "" "target >= 10"
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "candump parse, one core, best round (wall)" "" "$parse_wall" "" ""
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "buslab log convert, ${big_mb} MB .log -> .asc" "$g_secs" "$(rate $((FRAMES * copies)) "$g_secs")" "$g_rss" "RSS target < 50 MB"
printf '| %-44s | %9s | %13s | %9s | %-32s |\n' "buslab log convert, ${big_mb} MB .log -> .blf" "$gb_secs" "$(rate $((FRAMES * copies)) "$gb_secs")" "$gb_rss" "RSS target < 50 MB"
