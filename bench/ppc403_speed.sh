#!/usr/bin/env bash
# PowerPC 403 core speed against QEMU's user-mode emulator on the same program, as one table.
#
# The program is crates/ppc403/benches/crc_sieve.c (CRC-32 over 64 KiB 64 times, a sieve of
# Eratosthenes to 1,000,000 16 times: about 330 M instructions, all integer), built here with
# powerpc-linux-gnu-gcc -O2 -mcpu=403 as a static ELF with its own _start, its output through
# `sc` (write, exit: Linux's numbers, which the board's firmware serves too). This core runs
# it REPEAT times (crates/ppc403/examples/run_elf.rs, release build, a fresh core and memory
# each run); qemu-ppc (-cpu 405, TCG) runs it QEMU_REPEAT times. Both must print the same
# result. The instruction count is the core's: the program is deterministic, so qemu runs
# the same instruction stream (it does not count them).
#
# Rates per second of CPU time (user + system) and of wall time: the machine is shared, so
# compare the CPU columns and the ratio of one run, and read the load average printed above
# the table. "× real time" is the core's cycles (its cycle model) over the time taken, against
# the board's 25 MHz clock (a PPC403GA-25): above 1 the node keeps up with the real board.
set -euo pipefail
cd "$(dirname "$0")/.."

REPEAT=${REPEAT:-3}
QEMU_REPEAT=${QEMU_REPEAT:-10}
CLOCK_HZ=25000000

for tool in powerpc-linux-gnu-gcc qemu-ppc; do
    command -v "$tool" >/dev/null || {
        echo "bench/ppc403_speed.sh: $tool is missing (scripts/setup-test-deps.sh installs it)" >&2
        exit 1
    }
done
[ -x /usr/bin/time ] || {
    echo "bench/ppc403_speed.sh: /usr/bin/time is missing (apt-get install time)" >&2
    exit 1
}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

powerpc-linux-gnu-gcc -O2 -mcpu=403 -static -nostdlib -ffreestanding -fno-stack-protector \
    -fno-pie -no-pie -Wl,-Ttext=0x30000 -Wl,-z,noseparate-code -Wl,--build-id=none \
    -o "$work/crc_sieve" crates/ppc403/benches/crc_sieve.c
cargo build --release -q -p buslab-ppc403 --example run_elf

/usr/bin/time -f "%e %U %S" -o "$work/time.ours" \
    target/release/examples/run_elf "$work/crc_sieve" "$REPEAT" >"$work/ours.out" 2>"$work/ours.err" || {
    cat "$work/ours.err" >&2
    exit 1
}
/usr/bin/time -f "%e %U %S" -o "$work/time.qemu" \
    bash -c 'for _ in $(seq "$1"); do qemu-ppc -cpu 405 "$2" >"$3" || exit 1; done' \
    _ "$QEMU_REPEAT" "$work/crc_sieve" "$work/qemu.out"

if ! cmp -s "$work/ours.out" "$work/qemu.out"; then
    echo "bench/ppc403_speed.sh: the core and qemu-ppc printed different results:" >&2
    echo "  core:     $(cat "$work/ours.out")" >&2
    echo "  qemu-ppc: $(cat "$work/qemu.out")" >&2
    exit 1
fi
read -r ours_wall ours_user ours_sys <"$work/time.ours"
read -r qemu_wall qemu_user qemu_sys <"$work/time.qemu"
read -r _ _ _ insns _ cycles <"$work/ours.err"
insns=$((insns / REPEAT))
cycles=$((cycles / REPEAT))

echo "# crates/ppc403/benches/crc_sieve.c (gcc $(powerpc-linux-gnu-gcc -dumpversion) -O2 -mcpu=403): both print: $(cat "$work/ours.out")"
echo "# $insns instructions, $cycles cycles of the core's model a run ($(awk -v c="$cycles" -v hz="$CLOCK_HZ" 'BEGIN { printf "%.2f", c / hz }') s at 25 MHz)"
echo "# buslab-ppc403 $REPEAT runs, $(qemu-ppc --version | head -1) -cpu 405 $QEMU_REPEAT runs; load average: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) CPUs"
awk -v i="$insns" -v c="$cycles" -v hz="$CLOCK_HZ" \
    -v on="$REPEAT" -v ow="$ours_wall" -v ou="$ours_user" -v os="$ours_sys" \
    -v qn="$QEMU_REPEAT" -v qw="$qemu_wall" -v qu="$qemu_user" -v qs="$qemu_sys" '
function row(name, n, w, cpu) {
    printf "| %-13s | %11d | %4d | %6.2f | %6.2f | %8.1f | %8.1f | %8.1f× | %8.1f× |\n", name, i, n, cpu, w,
        i * n / cpu / 1e6, i * n / w / 1e6, c * n / cpu / hz, c * n / w / hz
}
BEGIN {
    oc = ou + os; qc = qu + qs
    if (oc <= 0) oc = 0.01
    if (qc <= 0) qc = 0.01
    if (ow <= 0) ow = 0.01
    if (qw <= 0) qw = 0.01
    print "| emulator      | instructions a run | runs | CPU s | wall s | MIPS CPU | MIPS wall | real time (25 MHz) CPU | real time wall |"
    print "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    row("buslab-ppc403", on, ow, oc)
    row("qemu-ppc", qn, qw, qc)
    printf "| core / qemu   |             |      |        |        | %7.2f× | %7.2f× |           |           |\n",
        (on / oc) / (qn / qc), (on / ow) / (qn / qw)
}'
