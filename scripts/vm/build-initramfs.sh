#!/usr/bin/env bash
# Builds the SocketCAN test VM: Debian's kernel (unpacked from the package that
# scripts/setup-test-deps.sh downloads, never installed) and an initramfs with busybox, the CAN
# modules, a buslab binary with the shared libraries ldd lists, and can-utils' candump, cansend,
# cangen and slcand. Everything is cached under OUT (the kernel by package, the initramfs until
# the binary or these scripts change), so a second run takes a moment.
#
# Usage: scripts/vm/build-initramfs.sh [OUT [BUSLAB]]
#   OUT     default target/vm
#   BUSLAB  default target/release/buslab (built if missing); the test passes its own binary.
# Prints KERNEL=PATH and INITRD=PATH on stdout. Fails loudly when a piece is missing.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
out="${1:-$root/target/vm}"
buslab="${2:-$root/target/release/buslab}"

fail() {
    echo "build-initramfs: error: $*" >&2
    exit 1
}

mkdir -p "$out"
out="$(cd "$out" && pwd)"

for tool in busybox cpio gzip dpkg-deb strip ldd candump cansend cangen slcand; do
    command -v "$tool" >/dev/null 2>&1 ||
        fail "$tool is missing: run scripts/setup-test-deps.sh (Debian packages busybox-static, cpio, can-utils, binutils)"
done
if [ ! -x "$buslab" ]; then
    [ "$buslab" = "$root/target/release/buslab" ] || fail "no buslab binary at $buslab"
    (cd "$root" && cargo build --release -p buslab) || fail "cannot build the release buslab binary"
fi

deb="$(ls -t "$root"/target/vm-cache/linux-image-*-amd64_*.deb 2>/dev/null | head -n 1 || true)"
[ -n "$deb" ] || fail "no kernel package in target/vm-cache/: run scripts/setup-test-deps.sh"
version="$(basename "$deb" | sed -E 's/^linux-image-([^_]+)_.*/\1/')"

# The kernel and the five modules, once per kernel package.
kernel_dir="$out/kernel-$version"
if [ ! -f "$kernel_dir/vmlinuz" ]; then
    rm -rf "$kernel_dir.tmp"
    mkdir -p "$kernel_dir.tmp/unpacked" "$kernel_dir.tmp/modules"
    dpkg-deb -x "$deb" "$kernel_dir.tmp/unpacked"
    cp "$kernel_dir.tmp/unpacked/boot/vmlinuz-$version" "$kernel_dir.tmp/vmlinuz"
    mods="$kernel_dir.tmp/unpacked/lib/modules/$version/kernel"
    for m in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko \
        drivers/net/can/vcan.ko drivers/net/can/slcan/slcan.ko; do
        [ -f "$mods/$m" ] || fail "the kernel package has no $m"
        cp "$mods/$m" "$kernel_dir.tmp/modules/"
    done
    rm -rf "$kernel_dir.tmp/unpacked" "$kernel_dir"
    mv "$kernel_dir.tmp" "$kernel_dir"
fi

# The initramfs, rebuilt when the binary or these scripts are newer.
initrd="$out/initrd-$version.gz"
here="$(dirname "$0")"
fresh=true
for input in "$buslab" "$here/build-initramfs.sh" "$here/init" "$here/socketcan-test.sh"; do
    [ "$initrd" -nt "$input" ] || fresh=false
done
if ! $fresh; then
    tree="$(mktemp -d "$out/initramfs.XXXXXX")"
    trap 'rm -rf "$tree"' EXIT
    mkdir -p "$tree"/{bin,sbin,usr/bin,usr/sbin,proc,sys,dev,tmp,modules}
    cp "$(command -v busybox)" "$tree/bin/busybox"
    for applet in $("$tree/bin/busybox" --list); do
        [ "$applet" = busybox ] || ln -sf /bin/busybox "$tree/bin/$applet"
    done
    cp "$kernel_dir"/modules/*.ko "$tree/modules/"
    # Dynamically linked programs with their libraries at the same paths.
    add_program() {
        local src="$1" dst="$tree/bin/$2"
        cp "$src" "$dst"
        for lib in $(ldd "$src" | grep -oE '/[^ ]+'); do
            mkdir -p "$tree$(dirname "$lib")"
            cp -L "$lib" "$tree$lib"
        done
    }
    strip --strip-debug -o "$out/buslab.stripped" "$buslab"
    add_program "$out/buslab.stripped" buslab
    for tool in candump cansend cangen slcand; do
        add_program "$(command -v "$tool")" "$tool"
    done
    cp "$here/init" "$tree/init"
    cp "$here/socketcan-test.sh" "$tree/vmtest.sh"
    chmod +x "$tree/init" "$tree/vmtest.sh"
    (cd "$tree" && find . | cpio -o -H newc --quiet | gzip -1 >"$initrd.tmp")
    mv "$initrd.tmp" "$initrd"
fi
echo "KERNEL=$kernel_dir/vmlinuz"
echo "INITRD=$initrd"
