#!/usr/bin/env bash
# The whole test suite: unit, integration, end-to-end (the buslab binary over pseudo-terminals
# and loopback TCP) and interop tests, then the doctests.
#
#   bash scripts/test.sh [--no-setup]
#
# First it installs the test tools this machine lacks with scripts/setup-test-deps.sh, which
# says what it is about to install before it does: cargo-nextest (crates.io), Debian packages
# (apt-get: needs root; as another user it names the missing packages and stops), Python
# packages into .venv/ and python-can's test logs (PyPI). `--no-setup` skips that (for a
# machine set up once already, or to run without them: the interop tests then say SKIPPED,
# and fail under CI=1); `bash scripts/setup-test-deps.sh --check` only says what is missing.
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
    echo "== test tools (scripts/setup-test-deps.sh; scripts/test.sh --no-setup skips this)"
    bash scripts/setup-test-deps.sh
fi
[ $# = 0 ] || { echo "usage: scripts/test.sh [--no-setup]" >&2; exit 2; }

status=0
cargo nextest run --workspace --locked || status=$?
echo "== doctests"
cargo test --workspace --doc --locked || status=$?
exit "$status"
