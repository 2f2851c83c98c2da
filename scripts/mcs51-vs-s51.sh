#!/usr/bin/env bash
# The MCS-51 core (crates/mcs51) against SDCC's simulator s51 on a fresh random sample of
# per-opcode vectors: random opcodes and machine states, one instruction each, run in s51 and
# in the core, registers, RAM, SFRs, external data and cycles compared
# (crates/mcs51/examples/s51_vectors.rs). The committed vectors cover every opcode without s51
# (crates/mcs51/tests/s51_vectors.rs); this finds what they miss. CI runs it after the tests.
#
# COUNT vectors (default 2000, about 20 s); SEED fixes the sample (default: a new one each run,
# printed, so a difference can be replayed with SEED=...). Exit 1 when any vector differs.
set -euo pipefail
cd "$(dirname "$0")/.."

COUNT=${COUNT:-2000}
SEED=${SEED:-}

command -v s51 >/dev/null || {
    echo "scripts/mcs51-vs-s51.sh: s51 is missing (Debian sdcc-ucsim; scripts/setup-test-deps.sh installs it)" >&2
    exit 1
}
cargo build --release -q --locked -p buslab-mcs51 --example s51_vectors
# shellcheck disable=SC2086 # an empty SEED is no argument
target/release/examples/s51_vectors compare "$COUNT" $SEED
