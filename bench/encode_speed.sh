#!/usr/bin/env bash
# The wire encoder's speed, as one table: frames per second of CPU time (the example
# crates/can/examples/encode_cost.rs on the fixed mix of crates/can/benches/support/mix.rs,
# the same frames as `cargo bench -p buslab-can --bench wire -- wire-encode`) and callgrind's
# instruction count per frame (load-independent), for this tree and, with BEFORE=<git rev>,
# for that revision built the same way in a temporary worktree (the example and the mix are
# copied in, so both encode the same frames), with the ratio of both.
#
# Goal (issue 33): at least 30 M frames/s. Frames/s are the best of RUNS runs of one thread (the machine is
# shared; read the load average printed above the table); instructions are exact.
set -euo pipefail
cd "$(dirname "$0")/.."

ROUNDS=${ROUNDS:-2000}
RUNS=${RUNS:-5}
BEFORE=${BEFORE:-}

command -v valgrind >/dev/null || {
    echo "bench/encode_speed.sh: valgrind is missing (apt-get install valgrind)" >&2
    exit 1
}

work=$(mktemp -d)
cleanup() {
    [ -z "$BEFORE" ] || git worktree remove --force "$work/before" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT

# build DIR TARGET: the example's binary, built in checkout DIR.
build() {
    (cd "$1" && CARGO_TARGET_DIR=$2 cargo build -q --release -p buslab-can --example encode_cost)
    echo "$2/release/examples/encode_cost"
}

# instructions BINARY: per frame, from two runs that differ by 100 rounds (start-up cancels).
instructions() {
    local a b
    a=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null "$1" 10 2>&1 | awk '/Collected/ { print $4 }')
    b=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null "$1" 110 2>&1 | awk '/Collected/ { print $4 }')
    frames=$("$1" 1 | awk '/^mix:/ { print $2 }')
    awk -v a="$a" -v b="$b" -v f="$frames" 'BEGIN { printf "%.0f", (b - a) / (100 * f) }'
}

# rate BINARY: the best of RUNS runs, in M frames/s.
rate() {
    for ((i = 0; i < RUNS; i++)); do
        "$1" "$ROUNDS" | awk '/^encoded/ { print $(NF - 2) }'
    done | sort -g | tail -1
}

target=${CARGO_TARGET_DIR:-$PWD/target}
after=$(build . "$target")
echo "# wire encoder, $("$after" 1 | sed -n 's/^mix: //p')"
echo "# load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '%-28s %16s %14s\n' encoder "M frames/s (best)" "instr/frame"
ia=$(instructions "$after")
ra=$(rate "$after")
if [ -n "$BEFORE" ]; then
    git worktree add -q --detach "$work/before" "$BEFORE"
    mkdir -p "$work/before/crates/can/examples" "$work/before/crates/can/benches/support"
    cp crates/can/examples/encode_cost.rs "$work/before/crates/can/examples/"
    cp crates/can/benches/support/mix.rs "$work/before/crates/can/benches/support/"
    before=$(build "$work/before" "$work/target")
    ib=$(instructions "$before")
    rb=$(rate "$before")
    printf '%-28s %16s %14s\n' "before ($BEFORE)" "$rb" "$ib"
fi
printf '%-28s %16s %14s\n' "this tree" "$ra" "$ia"
if [ -n "$BEFORE" ]; then
    awk -v ra="$ra" -v rb="$rb" -v ia="$ia" -v ib="$ib" \
        'BEGIN { printf "%-28s %15.2f× %13.2f×\n", "this tree / before", ra / rb, ib / ia }'
fi
