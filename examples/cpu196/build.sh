#!/usr/bin/env bash
# Builds the CPU196 user programs into WebAssembly modules: C with Debian's clang for wasm32
# (linked by lld's wasm-ld), WAT with wabt's wat2wasm (scripts/setup-test-deps.sh installs
# clang, lld and wabt):
#   examples/cpu196/build.sh [OUT_DIR]     (default: examples/cpu196, beside the sources)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
mkdir -p "$out"
for tool in clang wasm-ld wat2wasm; do
    command -v "$tool" >/dev/null || {
        echo "examples/cpu196/build.sh: $tool is missing (Debian clang, lld, wabt; scripts/setup-test-deps.sh installs them)" >&2
        exit 1
    }
done
for src in "$here"/*.c; do
    name=$(basename "$src" .c)
    # No C library: the kernel's services are the imports of kernel.h; -ffreestanding keeps
    # clang from taking fopen/fwrite for stdio's.
    clang --target=wasm32 -O2 -ffreestanding -nostdlib -Wl,--no-entry -Wl,-z,stack-size=4096 \
        -I "$here" -o "$out/$name.wasm" "$src"
    chmod a-x "$out/$name.wasm" # data, not a program of this machine
    echo "$out/$name.wasm"
done
for src in "$here"/*.wat; do
    name=$(basename "$src" .wat)
    wat2wasm "$src" -o "$out/$name.wasm"
    echo "$out/$name.wasm"
done
