#!/usr/bin/env bash
# The whole test suite: unit, integration, end-to-end (the buslab binary over pseudo-terminals
# and loopback TCP) and interop tests, then the doctests. Installs its own test tools first
# (scripts/setup-test-deps.sh; `--no-setup` skips that, for scripts that did it once already).
#
# The tests run under cargo-nextest: each in its own process, those of every crate side by side,
# so the many that wait on the wall clock overlap. .config/nextest.toml sets the pool size, no
# retries (a flake must show), and kills a test still running after 5 minutes. nextest does not
# run doctests: `cargo test --doc` does. Both run even when the first fails; the exit status is
# non-zero if either failed.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ "${1:-}" = --no-setup ]; then
    shift
else
    bash scripts/setup-test-deps.sh
fi
[ $# = 0 ] || { echo "usage: scripts/test.sh [--no-setup]" >&2; exit 2; }

status=0
cargo nextest run --workspace --locked || status=$?
echo "== doctests"
cargo test --workspace --doc --locked || status=$?
exit "$status"
