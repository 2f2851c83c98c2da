#!/usr/bin/env bash
# Runs the whole test suite N times on a loaded machine, to show that it does not flake:
#   bash scripts/stress-ci.sh N
# Installs the test tools and builds the tests once, then starts 4 busy-loop processes (killed
# on exit, Ctrl-C included) and runs the README's test command (scripts/test.sh, as CI does,
# with CI=1) N times. Prints `run i: passed` or `run i: FAILED (tests)` per run and a final
# `P passed/F failed` line; each run's log is kept in a temporary directory it names. The exit
# status is non-zero if any run failed.
set -euo pipefail
cd "$(dirname "$0")/.."

runs=${1:-}
if ! [[ $runs =~ ^[1-9][0-9]*$ ]] || [ $# != 1 ]; then
    echo "usage: scripts/stress-ci.sh N   (N >= 1 runs of the whole test suite under load)" >&2
    exit 2
fi
export CI=1
export CARGO_TERM_COLOR=never

logs=$(mktemp -d "${TMPDIR:-/tmp}/buslab-stress.XXXXXX")
echo "logs in $logs"

busy=()
suite=
# Ends what this script started, by process id: the busy loops and a running suite (started in
# its own process group, so cargo, nextest and the tests go with it).
stop_all() {
    if [ -n "$suite" ]; then
        kill -TERM -- "-$suite" 2>/dev/null || true
        wait "$suite" 2>/dev/null || true
        suite=
    fi
    if [ ${#busy[@]} -gt 0 ]; then
        kill "${busy[@]}" 2>/dev/null || true
        wait "${busy[@]}" 2>/dev/null || true
        busy=()
    fi
}
trap stop_all EXIT
trap 'stop_all; exit 130' INT
trap 'stop_all; exit 143' TERM

echo "setup and build (once, before the load)"
if ! { bash scripts/setup-test-deps.sh &&
    cargo nextest run --workspace --locked --no-run; } >"$logs/setup.log" 2>&1; then
    echo "setup or build failed: see $logs/setup.log" >&2
    tail -n 20 "$logs/setup.log" >&2
    exit 1
fi

for _ in 1 2 3 4; do
    bash -c 'while :; do :; done' &
    busy+=($!)
done
echo "load: ${#busy[@]} busy loops (pids ${busy[*]})"

# The tests that did not pass, from a run's log: nextest's final list (FAIL, TIMEOUT, SIGSEGV,
# ...), then the doctests' failures (after test.sh's "== doctests" line).
failed_tests() {
    local log=$1 doc
    {
        if grep -q '^ *Summary \[' "$log"; then
            sed -n '/^ *Summary \[/,/^== doctests$/p' "$log" |
                sed -nE 's/^ *(FAIL|TIMEOUT|SIG[A-Z]+|ABORT|LEAK-FAIL) +\[[^]]*\] +(\([^)]*\) +)?(.*)$/\3/p'
        else
            echo "nextest: no summary (build or runner error)"
        fi
        doc=$(sed -n '/^== doctests$/,$p' "$log")
        if grep -qE '^test result: FAILED|^error' <<<"$doc"; then
            sed -nE 's/^---- (.*) stdout ----$/doctest \1/p' <<<"$doc" | grep . ||
                echo "doctests (see the log)"
        fi
    } | sort -u | paste -sd, - | sed 's/,/, /g'
}

passed=0
failed=0
for ((i = 1; i <= runs; i++)); do
    log="$logs/run-$i.log"
    start=$SECONDS
    # In the background and waited for, so that Ctrl-C or a TERM is handled at once.
    setsid bash scripts/test.sh --no-setup >"$log" 2>&1 &
    suite=$!
    status=0
    wait "$suite" || status=$?
    suite=
    if [ "$status" = 0 ]; then
        passed=$((passed + 1))
        echo "run $i: passed ($((SECONDS - start)) s)"
    else
        failed=$((failed + 1))
        echo "run $i: FAILED ($(failed_tests "$log")) ($((SECONDS - start)) s, log $log)"
    fi
done
echo "$passed passed/$failed failed (of $runs runs under 4 busy loops; logs in $logs)"
[ "$failed" = 0 ]
