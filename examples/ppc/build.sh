#!/usr/bin/env bash
# Builds the example programs for the PowerPC node into S-records (.s37) with Debian's cross
# binutils (binutils-powerpc-linux-gnu; scripts/setup-test-deps.sh installs it):
#   examples/ppc/build.sh [OUT_DIR]     (default: examples/ppc, beside the sources)
# BITRATE=50000 builds them for the seed's 50 kbit/s bus (default: the lab's 125000).
# Each program is linked as the seed's loader expects (§4.4.2.3: code at 0x32000, interrupt
# handlers at 0x30000) with the library in lib/.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
bitrate=${BITRATE:-125000}
mkdir -p "$out"
for tool in powerpc-linux-gnu-as powerpc-linux-gnu-ld powerpc-linux-gnu-objcopy; do
    command -v "$tool" >/dev/null || {
        echo "examples/ppc/build.sh: $tool is missing (Debian binutils-powerpc-linux-gnu; scripts/setup-test-deps.sh installs it)" >&2
        exit 1
    }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
as() {
    powerpc-linux-gnu-as -a32 -mppc -mregnames -I "$here/include" --defsym BITRATE="$bitrate" -o "$2" "$1"
}
for lib in "$here"/lib/*.s; do
    as "$lib" "$work/lib_$(basename "$lib" .s).o"
done
for src in "$here"/*.s; do
    name=$(basename "$src" .s)
    as "$src" "$work/$name.o"
    powerpc-linux-gnu-ld -m elf32ppc -T "$here/ppc.ld" -o "$work/$name.elf" "$work/$name.o" "$work"/lib_*.o
    # S3 data records and an S7 entry point; the header record names the file (no path: the
    # output is the same on every machine).
    (cd "$work" && powerpc-linux-gnu-objcopy -O srec --srec-forceS3 --srec-len 32 "$name.elf" "$name.s37")
    mv "$work/$name.s37" "$out/$name.s37"
    echo "$out/$name.s37"
done
