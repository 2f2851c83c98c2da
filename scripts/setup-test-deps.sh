#!/usr/bin/env bash
# Installs what the interop tests use besides the Rust toolchain (idempotent, quick when done):
# - Debian: sigrok-cli (decodes our VCD waveforms independently);
# - PyPI, into .venv/: the pinned packages of scripts/test-requirements.txt (pyserial, python-can).
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v sigrok-cli >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "installing sigrok-cli (Debian)"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq sigrok-cli >/dev/null
    else
        echo "warning: sigrok-cli is missing and cannot be installed here (needs root and apt-get)" >&2
    fi
fi

requirements=scripts/test-requirements.txt
stamp=.venv/.requirements
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
if ! cmp -s "$requirements" "$stamp"; then
    echo "installing Python test packages into .venv"
    .venv/bin/pip install --quiet --disable-pip-version-check -r "$requirements"
    cp "$requirements" "$stamp"
fi
