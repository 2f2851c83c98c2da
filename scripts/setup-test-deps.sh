#!/usr/bin/env bash
# Installs what the test suite uses besides the Rust toolchain (idempotent, quick when done):
# - crates.io: cargo-nextest, the test runner of scripts/test.sh (the machine image has it in
#   /usr/local/bin; elsewhere it is built once with `cargo install --locked`, a few minutes);
# - Debian: dovecot-imapd (the real IMAP server of `buslab mail`'s test, started per test on a
#   loopback port with a throwaway configuration); sigrok-cli (decodes our VCD waveforms independently); can-utils (log2asc/asc2log,
#   the log-format interop tests) and tshark/editcap (decode buslab's pcap and pcapng); for the
#   SocketCAN test VM (scripts/vm/, crates/buslab/tests/vm_socketcan.rs): qemu-system-x86,
#   busybox-static, cpio, can-utils, binutils, and Debian's kernel package downloaded (not
#   installed) into target/vm-cache/; sdcc-ucsim (s51) and as31 for the MCS-51 core;
# - PyPI, into .venv/: the pinned packages of scripts/test-requirements.txt (pyserial, python-can);
#   python-can's source distribution (pinned by hash) into target/python-can-sdist/, for the log
#   files of its test/data that crates/buslab/tests/log_python_can_data.rs reads with python-can
#   and buslab (downloaded, not committed: python-can is LGPL-3.0, see docs/decisions.md).
# Whatever cannot be installed stops the script with a message and a non-zero exit: the interop
# tests must not pass by skipping (under CI=1 they fail when a tool is missing).
set -euo pipefail
cd "$(dirname "$0")/.."

fail() {
    echo "setup-test-deps: error: $*" >&2
    exit 1
}

if ! cargo nextest --version >/dev/null 2>&1; then
    echo "installing cargo-nextest (crates.io, built once)"
    cargo install --locked cargo-nextest ||
        fail "cannot install cargo-nextest (cargo install --locked cargo-nextest); scripts/test.sh needs it"
fi

apt_updated=false
apt_install() {
    [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 ||
        fail "$1 is missing and cannot be installed here (needs root and apt-get): install Debian's '$1' package"
    if ! $apt_updated; then
        apt-get update -qq || fail "apt-get update failed"
        apt_updated=true
    fi
    echo "installing $1 (Debian)"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$1" >/dev/null ||
        fail "apt-get install $1 failed"
}

if ! command -v sigrok-cli >/dev/null 2>&1; then
    apt_install sigrok-cli
    command -v sigrok-cli >/dev/null 2>&1 || fail "sigrok-cli is still missing after installing it"
fi

# The mail notifier's IMAP server (crates/buslab/tests/mail_dovecot.rs runs /usr/sbin/dovecot).
if [ ! -x /usr/sbin/dovecot ]; then
    apt_install dovecot-imapd
    [ -x /usr/sbin/dovecot ] || fail "dovecot is still missing after installing dovecot-imapd"
fi
# The mail tests make a throwaway certificate authority with it (Dovecot's TLS, the hostile
# server's STARTTLS); dovecot-core depends on it, this is in case it did not come.
if ! command -v openssl >/dev/null 2>&1; then
    apt_install openssl
    command -v openssl >/dev/null 2>&1 || fail "openssl is still missing after installing it"
fi

# The web dashboard's browser test (crates/buslab/tests/web_browser.rs): headless Chromium
# driven over WebDriver.
for tool in chromium:chromium chromedriver:chromium-driver; do
    if ! command -v "${tool%%:*}" >/dev/null 2>&1; then
        apt_install "${tool#*:}"
        command -v "${tool%%:*}" >/dev/null 2>&1 || fail "${tool%%:*} is still missing after installing ${tool#*:}"
    fi
done

# The SocketCAN test VM: QEMU (software emulation), a busybox initramfs with can-utils.
for tool in qemu-system-x86_64:qemu-system-x86 busybox:busybox-static cpio:cpio \
    candump:can-utils slcand:can-utils strip:binutils; do
    if ! command -v "${tool%%:*}" >/dev/null 2>&1; then
        apt_install "${tool#*:}"
        command -v "${tool%%:*}" >/dev/null 2>&1 || fail "${tool%%:*} is still missing after installing ${tool#*:}"
    fi
done
# busybox must be the static one: the initramfs has no libraries for it.
busybox_path="$(command -v busybox)"
if ldd "$busybox_path" >/dev/null 2>&1; then
    apt_install busybox-static
    ldd "$(command -v busybox)" >/dev/null 2>&1 && fail "busybox is dynamically linked; install busybox-static"
fi
# Debian's current amd64 kernel package (linux-image-amd64 depends on it), kept in target/.
if ! ls target/vm-cache/linux-image-*-amd64_*.deb >/dev/null 2>&1; then
    if ! $apt_updated && [ "$(id -u)" = 0 ]; then
        apt-get update -qq || fail "apt-get update failed"
        apt_updated=true
    fi
    kernel="$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-/ { print $2; exit }')"
    [ -n "$kernel" ] || fail "apt-cache finds no kernel package behind linux-image-amd64 (apt-get update?)"
    echo "downloading $kernel (Debian; unpacked for the SocketCAN test VM, not installed)"
    mkdir -p target/vm-cache
    (cd target/vm-cache && apt-get download -qq "$kernel" 2>/dev/null) ||
        fail "apt-get download $kernel failed"
    ls target/vm-cache/linux-image-*-amd64_*.deb >/dev/null 2>&1 ||
        fail "apt-get download $kernel left no package in target/vm-cache/"
fi

if ! command -v log2asc >/dev/null 2>&1 || ! command -v asc2log >/dev/null 2>&1; then
    apt_install can-utils
    command -v log2asc >/dev/null 2>&1 || fail "log2asc is still missing after installing can-utils"
fi

if ! command -v tshark >/dev/null 2>&1 || ! command -v editcap >/dev/null 2>&1; then
    # tshark asks whether non-root users may capture: answer no, without a dialog.
    echo "wireshark-common wireshark-common/install-setuid boolean false" | debconf-set-selections ||
        fail "cannot preseed wireshark-common/install-setuid (debconf-set-selections)"
    apt_install tshark
    command -v tshark >/dev/null 2>&1 && command -v editcap >/dev/null 2>&1 ||
        fail "tshark or editcap is still missing after installing tshark"
fi

# The MCS-51 core's differential check against SDCC's simulator s51 (Debian sdcc-ucsim;
# scripts/mcs51-vs-s51.sh, run by .ci/run) and the assembler of its benchmark programs (as31;
# crates/mcs51/tests/bench_program.rs, bench/mcs51_speed.sh).
for tool in s51:sdcc-ucsim as31:as31; do
    if ! command -v "${tool%%:*}" >/dev/null 2>&1; then
        apt_install "${tool#*:}"
        command -v "${tool%%:*}" >/dev/null 2>&1 || fail "${tool%%:*} is still missing after installing ${tool#*:}"
    fi
done

requirements=scripts/test-requirements.txt
stamp=.venv/.requirements
if [ ! -x .venv/bin/python ]; then
    command -v python3 >/dev/null 2>&1 || fail "python3 is missing (the interop tests need it)"
    if ! python3 -m venv .venv; then
        rm -rf .venv
        # Debian's own python3 needs its venv module as a package.
        apt_install python3-venv
        python3 -m venv .venv || fail "python3 -m venv .venv failed"
    fi
fi
if ! cmp -s "$requirements" "$stamp"; then
    echo "installing Python test packages into .venv"
    .venv/bin/pip install --quiet --disable-pip-version-check -r "$requirements" ||
        fail "pip could not install $requirements into .venv"
    cp "$requirements" "$stamp"
fi
.venv/bin/python -c "import serial, can" ||
    fail "the .venv lacks pyserial or python-can; delete .venv and run this script again"

# python-can's own test logs (Vector ASC/BLF, PEAK TRC 1.0..2.1), from its sdist on PyPI.
pycan_version=4.6.1
pycan_sha256=290fea135d04b8504ebff33889cc6d301e2181a54099116609f940825ffe5005
pycan_dir=target/python-can-sdist
pycan_data=$pycan_dir/python_can-$pycan_version/test/data
if [ ! -f "$pycan_data/logfile.asc" ]; then
    echo "downloading python-can $pycan_version's source distribution (PyPI, for its test logs)"
    mkdir -p "$pycan_dir"
    printf 'python-can==%s --hash=sha256:%s\n' "$pycan_version" "$pycan_sha256" >"$pycan_dir/requirements.txt"
    .venv/bin/pip download --quiet --disable-pip-version-check --no-deps --no-binary :all: \
        --require-hashes -r "$pycan_dir/requirements.txt" -d "$pycan_dir" ||
        fail "pip could not download python-can $pycan_version's sdist into $pycan_dir"
    tar -xzf "$pycan_dir/python_can-$pycan_version.tar.gz" -C "$pycan_dir" \
        "python_can-$pycan_version/test/data" "python_can-$pycan_version/LICENSE.txt" ||
        fail "cannot unpack test/data from $pycan_dir/python_can-$pycan_version.tar.gz"
    [ -f "$pycan_data/logfile.asc" ] || fail "python-can's sdist has no test/data/logfile.asc"
fi
