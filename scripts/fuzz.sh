#!/usr/bin/env bash
# Fuzzes every parser that takes outside input (the targets in fuzz/fuzz_targets/, see
# docs/fuzzing.md) for SECONDS each with libFuzzer, then prints a table: target, executions,
# executions/s, crashes, corpus size. Exits non-zero if any target crashed (a panic, an
# overflow, a failed check, a hang over --timeout, or running out of memory); each crashing
# input is kept under fuzz/artifacts/TARGET/ and its path printed.
#
#   scripts/fuzz.sh [--runs N] [--timeout S] SECONDS [TARGET...]
#   scripts/fuzz.sh --build        (only build the targets)
#   scripts/fuzz.sh --list         (the target names)
#
# --runs N stops a target after N executions if that comes before SECONDS (the long run uses
# it: `scripts/fuzz.sh --runs 10000000 3600`). SIGINT to a target's process stops it early
# with its statistics (reported as interrupted, not as a crash). Each target starts from its
# committed seeds in fuzz/corpus/TARGET/ plus the corpus earlier runs grew in
# fuzz/target/corpus/TARGET/.
#
# Engine: libFuzzer through the libfuzzer-sys crate (crates.io), built by the stable toolchain
# with the coverage flags cargo-fuzz passes (no nightly, no sanitizer: the code is safe Rust;
# debug assertions and overflow checks are on). It needs a C++ compiler for libFuzzer itself;
# a missing one is installed from Debian (g++) or the script stops. `cargo fuzz run TARGET`
# works on the same layout for anyone with a nightly toolchain.
#
# A parser still to come gets a target when it lands: add fuzz/fuzz_targets/NAME.rs, its
# [[bin]] in fuzz/Cargo.toml and seeds in fuzz/corpus/NAME/; this script finds it by itself.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

usage() {
    echo "usage: scripts/fuzz.sh [--runs N] [--timeout S] SECONDS [TARGET...] | --build | --list" >&2
    exit 2
}
fail() {
    echo "fuzz.sh: error: $*" >&2
    exit 1
}

runs=0
timeout=10
build_only=false
list_only=false
while [ $# -gt 0 ]; do
    case "$1" in
    --runs) runs=${2:?--runs needs a count}; shift 2 ;;
    --timeout) timeout=${2:?--timeout needs seconds}; shift 2 ;;
    --build) build_only=true; shift ;;
    --list) list_only=true; shift ;;
    -*) usage ;;
    *) break ;;
    esac
done

all_targets=$(sed -n 's/^name = "\(.*\)"$/\1/p' fuzz/Cargo.toml | grep -v '^buslab-fuzz$')
if $list_only; then
    echo "$all_targets"
    exit 0
fi
if ! $build_only; then
    [ $# -ge 1 ] || usage
    seconds=$1
    shift
    [[ $seconds =~ ^[1-9][0-9]*$ ]] || fail "SECONDS must be a whole number above 0, not '$seconds'"
    [[ $runs =~ ^[0-9]+$ ]] || fail "--runs must be a count, not '$runs'"
    [[ $timeout =~ ^[1-9][0-9]*$ ]] || fail "--timeout must be whole seconds, not '$timeout'"
fi
targets=${*:-$all_targets}
for t in $targets; do
    grep -qx "$t" <<<"$all_targets" || fail "no fuzz target '$t' (scripts/fuzz.sh --list)"
done

# libFuzzer is C++: libfuzzer-sys compiles it with the system's C++ compiler.
if ! command -v c++ >/dev/null 2>&1 && ! command -v g++ >/dev/null 2>&1; then
    [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 ||
        fail "no C++ compiler (libFuzzer needs one): install Debian's 'g++' package"
    echo "installing g++ (Debian), which libFuzzer is built with"
    apt-get update -qq || fail "apt-get update failed"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq g++ >/dev/null ||
        fail "apt-get install g++ failed"
fi

# cargo-fuzz's instrumentation: SanitizerCoverage feeding libFuzzer (8-bit counters, PC table,
# comparison tracing), and `cfg(fuzzing)`. --target keeps these flags off build scripts and
# proc macros, which run on the host and must not be instrumented.
host=$(rustc -vV | sed -n 's/^host: //p')
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing ${FUZZ_RUSTFLAGS:-}"
echo "== building the fuzz targets (fuzz/, release with debug assertions and overflow checks)"
bins=()
for t in $targets; do bins+=(--bin "$t"); done
# Not --locked: fuzz/Cargo.lock pins what it has, and a dependency the crates gained since
# (main moves on without building fuzz/) is added to it rather than failing CI.
(cd fuzz && cargo build --release --target "$host" "${bins[@]}") ||
    fail "building the fuzz targets failed"
$build_only && exit 0

# The longest input worth trying, per target (libFuzzer's default is the longest seed or 4096
# bytes): a model driven step by step, a stream or a log costs time in proportion to its
# input, and beyond these lengths an input only repeats what shorter ones reach (more frames,
# lines or steps of the same kinds from the same state). Without an entry, libFuzzer's
# default. See docs/fuzzing.md ("Speed").
max_len() {
    case "$1" in
    ppc_node | monican_app | cpu196_board | zelle_cell | slio_node | slcan_adapter) echo 512 ;;
    served_file_names) echo 256 ;;
    logs_candump | can_wire_receiver | cpu196_decoder) echo 1024 ;;
    logs_csv) echo 2048 ;;
    *) ;;
    esac
}

bindir=$root/fuzz/target/$host/release
rows=()
crashed=()
for t in $targets; do
    seeds=$root/fuzz/corpus/$t
    work=$root/fuzz/target/corpus/$t
    artifacts=$root/fuzz/artifacts/$t
    log=$root/fuzz/target/logs/$t.log
    mkdir -p "$seeds" "$work" "$artifacts" "$(dirname "$log")"
    before=$(find "$artifacts" -type f | wc -l)
    echo "== $t: ${seconds}s$([ "$runs" = 0 ] || echo " or $runs executions")"
    start=$(date +%s.%N)
    status=0
    # The first folder collects what the run finds; the seeds are only read.
    options=()
    len=$(max_len "$t")
    [ -z "$len" ] || options+=(-max_len="$len")
    "$bindir/$t" -max_total_time="$seconds" -runs="$([ "$runs" = 0 ] && echo -1 || echo "$runs")" \
        -timeout="$timeout" -rss_limit_mb=2048 -malloc_limit_mb=2048 -print_final_stats=1 \
        "${options[@]}" -artifact_prefix="$artifacts/" "$work" "$seeds" >"$log" 2>&1 || status=$?
    elapsed=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    execs=${execs:-0}
    new=$(find "$artifacts" -type f | wc -l)
    crashes=$((new - before))
    # SIGINT to the target (stopping a long run early) ends it with libFuzzer's interrupt
    # code and its final statistics: a stop, not a crash.
    if [ "$status" = 72 ] && [ "$crashes" = 0 ] && grep -q "libFuzzer: run interrupted" "$log"; then
        echo "   interrupted (SIGINT): stopped after $execs executions"
        status=0
    fi
    if [ "$status" != 0 ] && [ "$crashes" = 0 ]; then
        crashes=1 # it died without writing an input (e.g. killed): show its log
    fi
    if [ "$crashes" != 0 ]; then
        crashed+=("$t")
        echo "   CRASH (exit $status): log $log"
        grep -E "panicked at|ERROR: libFuzzer|Test unit written|SUMMARY" "$log" | head -8 | sed 's/^/   /'
    fi
    corpus=$(find "$work" "$seeds" -type f | wc -l)
    rate=$(awk -v n="$execs" -v s="$elapsed" 'BEGIN { printf "%d", n / s }')
    rows+=("$(printf '%-22s %14s %10s %8s %8s' "$t" "$execs" "$rate" "$crashes" "$corpus")")
done

echo
printf '%-22s %14s %10s %8s %8s\n' target executions exec/s crashes corpus
for r in "${rows[@]}"; do echo "$r"; done
if [ ${#crashed[@]} != 0 ]; then
    echo
    echo "crashed: ${crashed[*]} (inputs under fuzz/artifacts/; reproduce with" \
        "fuzz/target/$host/release/TARGET INPUT)"
    exit 1
fi
