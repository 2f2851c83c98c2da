#!/usr/bin/env bash
# The PowerPC 403 core (crates/ppc403) against QEMU's user-mode emulator qemu-ppc on a fresh
# random sample of cases: random machine states and 1-8 random user-level integer
# instructions (arithmetic with its overflow and record forms, logic, rotates, shifts,
# compares, CR and XER moves, every load and store form, string and multiple ones, branches
# with every BO), built into programs with the cross binutils, run in qemu-ppc and in the
# core, every GPR, CR, XER, LR, CTR and the scratch memory compared
# (crates/ppc403/examples/qemu_vectors.rs). The committed vectors run without qemu
# (crates/ppc403/tests/qemu_vectors.rs); this finds what they miss. CI runs it after the tests.
#
# Then whole programs: crates/ppc403/tests/data/int_mix.c (64-bit arithmetic through libgcc,
# 32-bit multiply/divide, bit counts, sub-word structure fields, hashed) built with
# powerpc-linux-gnu-gcc at -O0, -O1, -O2, -Os, -O3 and run on the core
# (crates/ppc403/examples/run_elf.rs) and in qemu-ppc: the printed hashes must be equal.
#
# COUNT cases (default 5000, a few seconds); SEED fixes the sample (default: a new one each
# run, printed, so a difference can be replayed with SEED=...). Exit 1 when any case or
# program differs.
set -euo pipefail
cd "$(dirname "$0")/.."

COUNT=${COUNT:-5000}
SEED=${SEED:-$(date +%s%N)}

for tool in qemu-ppc powerpc-linux-gnu-as powerpc-linux-gnu-ld powerpc-linux-gnu-gcc; do
    command -v "$tool" >/dev/null || {
        echo "scripts/ppc403-vs-qemu.sh: $tool is missing (Debian qemu-user, binutils-powerpc-linux-gnu, gcc-powerpc-linux-gnu; scripts/setup-test-deps.sh installs them)" >&2
        exit 1
    }
done
echo "ppc403 vs qemu-ppc: $COUNT cases, SEED=$SEED"
cargo build --release -q --locked -p buslab-ppc403 --example qemu_vectors --example run_elf
status=0
target/release/examples/qemu_vectors compare "$COUNT" "$SEED" || status=$?

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
agree=0
levels=(-O0 -O1 -O2 -Os -O3)
for level in "${levels[@]}"; do
    elf="$work/int_mix$level"
    powerpc-linux-gnu-gcc "$level" -mcpu=403 -static -nostdlib -ffreestanding -fno-stack-protector \
        -fno-pie -no-pie -Wl,-Ttext=0x30000 -Wl,-z,noseparate-code -Wl,--build-id=none \
        -o "$elf" crates/ppc403/tests/data/int_mix.c -lgcc
    qemu=$(qemu-ppc -cpu 405 "$elf") || qemu="(qemu-ppc failed: $?)"
    ours=$(target/release/examples/run_elf "$elf" 2>"$work/err") || ours="(the core failed: $(cat "$work/err"))"
    if [ "$qemu" = "$ours" ]; then
        agree=$((agree + 1))
    else
        echo "DIFFERENT int_mix.c $level: qemu-ppc $qemu, core $ours"
        status=1
    fi
done
echo "ppc403 vs qemu-ppc: $agree/${#levels[@]} programs agree (int_mix.c at ${levels[*]})"
exit "$status"
