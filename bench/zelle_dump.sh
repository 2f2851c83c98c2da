#!/usr/bin/env bash
# Throughput of a data RAM dump from the ZELLE model over a pseudo-terminal at 9600 8N2,
# pipelined vs stop-and-wait, as a share of the line's byte rate (872.7 B/s).
# Usage: bench/zelle_dump.sh [BYTES]   (default 8192; takes about 30 s)
set -euo pipefail
cd "$(dirname "$0")/.."
exec cargo run --quiet --release -p buslab-zelle --example dump_bench -- "$@"
