#!/usr/bin/env bash
# The whole test suite: unit, integration, end-to-end (the buslab binary over pseudo-terminals
# and loopback TCP) and interop tests. Installs its own test tools first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-test-deps.sh
cargo test --workspace --locked
