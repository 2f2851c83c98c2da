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
# COUNT cases (default 5000, a few seconds); SEED fixes the sample (default: a new one each
# run, printed, so a difference can be replayed with SEED=...). Exit 1 when any case differs.
set -euo pipefail
cd "$(dirname "$0")/.."

COUNT=${COUNT:-5000}
SEED=${SEED:-$(date +%s%N)}

for tool in qemu-ppc powerpc-linux-gnu-as powerpc-linux-gnu-ld; do
    command -v "$tool" >/dev/null || {
        echo "scripts/ppc403-vs-qemu.sh: $tool is missing (Debian qemu-user, binutils-powerpc-linux-gnu; scripts/setup-test-deps.sh installs them)" >&2
        exit 1
    }
done
echo "ppc403 vs qemu-ppc: $COUNT cases, SEED=$SEED"
cargo build --release -q --locked -p buslab-ppc403 --example qemu_vectors
target/release/examples/qemu_vectors compare "$COUNT" "$SEED"
