#!/usr/bin/env bash
# MCS-51 core speed against SDCC's s51 on the same program in one run, as one table.
#
# The program is crates/mcs51/benches/checksum.a51 (a checksum over 2 KiB, 255 passes: 6.27 M
# machine cycles, 4.71 M instructions, no branch depending on data), assembled here with as31.
# s51 (ucsim, -t 80C51) runs it once from a command file (load, break at `done`, run, state);
# this core runs it REPEAT times (the example crates/mcs51/examples/run_hex.rs, a trap at
# `done`). Both report machine cycles and instructions; the table checks they ran the same
# instruction stream (equal cycles and instructions per run; s51 counts the instruction at its
# breakpoint too, which is taken off).
#
# Rates per second of CPU time (user + system) and of wall time: the machine is shared, so
# compare the CPU columns and the ratios of one run, and read the load average printed above
# the table. "× real time" is against the ZELLE cell's 11.0592 MHz crystal, 921 600 machine
# cycles a second. Goals: at least 100× real time, at least 20× s51.
set -euo pipefail
cd "$(dirname "$0")/.."

REPEAT=${REPEAT:-20}

for tool in as31 s51; do
    command -v "$tool" >/dev/null || {
        echo "bench/mcs51_speed.sh: $tool is missing (scripts/setup-test-deps.sh installs it)" >&2
        exit 1
    }
done
[ -x /usr/bin/time ] || {
    echo "bench/mcs51_speed.sh: /usr/bin/time is missing (apt-get install time)" >&2
    exit 1
}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

as31 -Fhex -O"$work/checksum.hex" crates/mcs51/benches/checksum.a51 >"$work/as31.log" 2>&1 || {
    cat "$work/as31.log" >&2
    exit 1
}
cargo build --release -q -p buslab-mcs51 --example run_hex

/usr/bin/time -f "%e %U %S" -o "$work/time.ours" \
    target/release/examples/run_hex "$work/checksum.hex" 0x17 "$REPEAT" >"$work/ours"
printf 'file "%s"\nbreak 0x17\nrun\nstate\nquit\n' "$work/checksum.hex" >"$work/s51.cmd"
/usr/bin/time -f "%e %U %S" -o "$work/time.s51" \
    s51 -t 80C51 -b -q -C "$work/s51.cmd" </dev/null >"$work/s51.out"

read -r ours_wall ours_user ours_sys <"$work/time.ours"
read -r s51_wall s51_user s51_sys <"$work/time.s51"
ours_cycles=$(awk '{ print $2 }' "$work/ours")
ours_insns=$(awk '{ print $4 }' "$work/ours")
s51_insns=$(sed -n 's/^Inst= \([0-9]*\).*/\1/p' "$work/s51.out" | tail -1)
s51_clocks=$(sed -n 's/^Total time since last reset=.*(\([0-9]*\) clks).*/\1/p' "$work/s51.out" | tail -1)
[ -n "$s51_insns" ] && [ -n "$s51_clocks" ] || {
    echo "bench/mcs51_speed.sh: no instruction or clock count in s51's output:" >&2
    cat "$work/s51.out" >&2
    exit 1
}
s51_cycles=$((s51_clocks / 12))
# s51's instruction count includes the instruction at the breakpoint, which it does not run.
s51_insns=$((s51_insns - 1))

echo "# MCS-51 cores on crates/mcs51/benches/checksum.a51 (as31): buslab-mcs51 $REPEAT runs, s51 1 run"
echo "# $(s51 -v | sed 's/^s51: /ucsim /'), -t 80C51; load average: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) CPUs"
if [ $((ours_cycles / REPEAT)) -eq "$s51_cycles" ] && [ $((ours_insns / REPEAT)) -eq "$s51_insns" ]; then
    echo "# same instruction stream: $s51_insns instructions, $s51_cycles machine cycles a run in both"
else
    echo "# WARNING: runs differ: core $((ours_cycles / REPEAT)) cycles $((ours_insns / REPEAT)) instructions a run, s51 $s51_cycles cycles $s51_insns instructions"
fi
awk -v oc="$ours_cycles" -v oi="$ours_insns" -v ow="$ours_wall" -v ou="$ours_user" -v os="$ours_sys" \
    -v sc="$s51_cycles" -v si="$s51_insns" -v sw="$s51_wall" -v su="$s51_user" -v ss="$s51_sys" '
function row(name, c, i, w, cpu) {
    printf "| %-12s | %11d | %11d | %6.2f | %6.2f | %8.1f | %8.1f | %8.0f× | %8.1f |\n", name, c, i, cpu, w,
        c / cpu / 1e6, i / cpu / 1e6, c / cpu / 921600, c / w / 1e6
}
BEGIN {
    oc_cpu = ou + os; sc_cpu = su + ss
    if (oc_cpu <= 0) oc_cpu = 0.01
    if (sc_cpu <= 0) sc_cpu = 0.01
    print "| core         | mach. cycles | instructions | CPU s | wall s | M cyc/s CPU | M ins/s CPU | real time CPU | M cyc/s wall |"
    print "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    row("buslab-mcs51", oc, oi, ow, oc_cpu)
    row("s51", sc, si, sw, sc_cpu)
    printf "| ratio        |             |             |        |        | %7.1f× | %7.1f× |           | %7.1f× |\n",
        (oc / oc_cpu) / (sc / sc_cpu), (oi / oc_cpu) / (si / sc_cpu), (oc / ow) / (sc / sw)
}'
