#!/usr/bin/env bash
# Installs what the interop tests use besides the Rust toolchain, into .venv/ (idempotent).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
if ! .venv/bin/python -c 'import serial' 2>/dev/null; then
    .venv/bin/pip install --quiet --disable-pip-version-check -r scripts/test-requirements.txt
fi
