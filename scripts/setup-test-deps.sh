#!/usr/bin/env bash
# Installs what the test suite uses besides the Rust toolchain (idempotent, quick when done):
# - crates.io: cargo-nextest, the test runner of scripts/test.sh (the machine image has it in
#   /usr/local/bin; elsewhere it is built once with `cargo install --locked`, a few minutes);
# - Debian: dovecot-imapd (the real IMAP server of `buslab mail`'s test, started per test on a
#   loopback port with a throwaway configuration); mosquitto (the MQTT broker of the joined-buses
#   tests, likewise); sigrok-cli (decodes our VCD waveforms independently); can-utils (log2asc/asc2log,
#   the log-format interop tests) and tshark/editcap (decode buslab's pcap and pcapng); for the
#   SocketCAN test VM (scripts/vm/, crates/buslab/tests/vm_socketcan.rs): qemu-system-x86,
#   busybox-static, cpio, can-utils, binutils, and Debian's kernel package downloaded (not
#   installed) into target/vm-cache/; sdcc-ucsim (s51) and as31 for the MCS-51 core; qemu-user (qemu-ppc) and the
#   PowerPC cross binutils and gcc for the PowerPC 403 core and examples/ppc/;
# - PyPI, into .venv/: the pinned packages of scripts/test-requirements.txt (pyserial, python-can,
#   can-cannelloni);
#   python-can's source distribution (pinned by hash) into target/python-can-sdist/, for the log
#   files of its test/data that crates/buslab/tests/log_python_can_data.rs reads with python-can
#   and buslab (downloaded, not committed: python-can is LGPL-3.0, see docs/decisions.md);
#   cantools' source distribution (its tests/files/dbc) into target/cantools-sdist/ and
#   opendbc's wheel (its opendbc/dbc) into target/opendbc-wheel/, both pinned by hash, for the
#   DBC files that crates/dbc/tests/golden.rs decodes with cantools and buslab.
# Whatever cannot be installed stops the script with a message and a non-zero exit: the interop
# tests must not pass by skipping (under CI=1 they fail when a tool is missing).
#
# It looks first and says what it is about to install, and from where, before installing
# anything; Debian packages need root and apt-get: without them it names every missing package
# at once and stops before changing anything. `--check` only says what is missing (exit 1 if
# anything is).
set -euo pipefail
cd "$(dirname "$0")/.."

check_only=false
case "${1:-}" in
--check) check_only=true ;;
"") ;;
*) echo "usage: scripts/setup-test-deps.sh [--check]" >&2; exit 2 ;;
esac

fail() {
    echo "setup-test-deps: error: $*" >&2
    exit 1
}

has() { command -v "$1" >/dev/null 2>&1; }

# --- What is missing (nothing is installed in this part) ---------------------------------

need_nextest=false
has cargo && cargo nextest --version >/dev/null 2>&1 || need_nextest=true

debs=()
# The Debian package PACKAGE, once.
want_deb() {
    local d
    for d in "${debs[@]}"; do [ "$d" = "$1" ] && return 0; done
    debs+=("$1")
}
# TOOL:PACKAGE...: the package of each tool that is not on PATH.
want_tools() {
    local pair
    for pair in "$@"; do
        has "${pair%%:*}" || want_deb "${pair#*:}"
    done
}

# sigrok-cli decodes our VCD waveforms independently.
want_tools sigrok-cli:sigrok-cli
# The MQTT broker of the joined-buses tests (crates/buslab/tests/join_buses.rs starts its own
# on a free loopback port; the service the package enables on 1883 is not used).
[ -x /usr/sbin/mosquitto ] || want_deb mosquitto
# The mail notifier's IMAP server (crates/buslab/tests/mail_dovecot.rs runs /usr/sbin/dovecot).
[ -x /usr/sbin/dovecot ] || want_deb dovecot-imapd
# The mail tests make a throwaway certificate authority with it (Dovecot's TLS, the hostile
# server's STARTTLS); dovecot-core depends on it, this is in case it did not come.
want_tools openssl:openssl
# The web dashboard's browser test (crates/buslab/tests/web_browser.rs): headless Chromium
# driven over WebDriver.
want_tools chromium:chromium chromedriver:chromium-driver
# The SocketCAN test VM: QEMU (software emulation), a busybox initramfs with can-utils.
want_tools qemu-system-x86_64:qemu-system-x86 busybox:busybox-static cpio:cpio \
    candump:can-utils slcand:can-utils strip:binutils
# busybox must be the static one: the initramfs has no libraries for it.
if has busybox && ldd "$(command -v busybox)" >/dev/null 2>&1; then
    want_deb busybox-static
fi
# Debian's current amd64 kernel package (linux-image-amd64 depends on it), kept in target/.
need_kernel=false
ls target/vm-cache/linux-image-*-amd64_*.deb >/dev/null 2>&1 || need_kernel=true
# log2asc/asc2log (the log-format interop tests), tshark/editcap (decode buslab's pcap and
# pcapng).
want_tools log2asc:can-utils asc2log:can-utils tshark:tshark editcap:tshark
# The MCS-51 core's differential check against SDCC's simulator s51 (Debian sdcc-ucsim;
# scripts/mcs51-vs-s51.sh, run by .ci/run) and the assembler of its benchmark programs (as31;
# crates/mcs51/tests/bench_program.rs, bench/mcs51_speed.sh); SDCC builds the C example of
# the ZELLE cell's programs (examples/zelle/, crates/buslab/tests/zelle_programs.rs).
want_tools s51:sdcc-ucsim as31:as31 sdcc:sdcc
# The PowerPC 403 core (crates/ppc403): its differential test against QEMU's user-mode
# emulator (qemu-ppc) on programs the cross toolchain builds, and the example programs the
# PowerPC node loads over CAN (examples/ppc/).
want_tools qemu-ppc:qemu-user powerpc-linux-gnu-as:binutils-powerpc-linux-gnu \
    powerpc-linux-gnu-gcc:gcc-powerpc-linux-gnu
# The CPU196 user programs (examples/cpu196/, crates/buslab/tests/cpu196_programs.rs): hooks
# in C built by Debian's clang for wasm32 and linked by lld's wasm-ld, hooks in WAT assembled
# by wabt's wat2wasm.
want_tools clang:clang wasm-ld:lld wat2wasm:wabt
# Python for the interop tests, with its venv module (Debian's python3 needs python3-venv).
requirements=scripts/test-requirements.txt
stamp=.venv/.requirements
need_venv=false
[ -x .venv/bin/python ] || need_venv=true
if $need_venv; then
    want_tools python3:python3
    has python3 && ! python3 -c "import ensurepip" >/dev/null 2>&1 && want_deb python3-venv
fi
need_pip=false
cmp -s "$requirements" "$stamp" || need_pip=true
# python-can's own test logs (Vector ASC/BLF, PEAK TRC 1.0..2.1), from its sdist on PyPI.
pycan_version=4.6.1
pycan_sha256=290fea135d04b8504ebff33889cc6d301e2181a54099116609f940825ffe5005
pycan_dir=target/python-can-sdist
pycan_data=$pycan_dir/python_can-$pycan_version/test/data
need_sdist=false
[ -f "$pycan_data/logfile.asc" ] || need_sdist=true
# cantools' own test DBCs (tests/files/dbc in its sdist) and opendbc's real vehicle DBCs (its
# wheel's opendbc/dbc), for the DBC golden comparison (crates/dbc/tests/golden.rs).
cantools_version=45.1.0
cantools_sha256=ea1619f3d6108a1c3ecd0f81c952ff2dffd023b244704f6f7a17c4f4dca75f73
cantools_dir=target/cantools-sdist
cantools_dbc=$cantools_dir/cantools-$cantools_version/tests/files/dbc
need_cantools_sdist=false
[ -f "$cantools_dbc/motohawk.dbc" ] || need_cantools_sdist=true
opendbc_version=0.3.1
opendbc_sha256=5552994344a885d85836f2487b85e958e69ab1a0e8d11e30ec508d316bf58ae1
opendbc_dir=target/opendbc-wheel
opendbc_dbc=$opendbc_dir/opendbc/dbc
need_opendbc=false
[ -f "$opendbc_dbc/tesla_can.dbc" ] || need_opendbc=true

# --- Say it ---------------------------------------------------------------------------------

if ! $need_nextest && [ ${#debs[@]} = 0 ] && ! $need_kernel && ! $need_venv && ! $need_pip &&
    ! $need_sdist && ! $need_cantools_sdist && ! $need_opendbc; then
    $check_only && echo "setup-test-deps: every test tool is here"
    exit 0
fi
root_apt=false
[ "$(id -u)" = 0 ] && has apt-get && root_apt=true
echo "setup-test-deps: the test tools this machine lacks$($check_only || echo ", to be installed now"):"
$need_nextest && echo "  crates.io: cargo-nextest (cargo install --locked; built once, a few minutes)"
[ ${#debs[@]} = 0 ] || echo "  Debian, with apt-get as root: ${debs[*]}"
$need_kernel && echo "  Debian's amd64 kernel package, downloaded into target/vm-cache/ (not installed)"
$need_venv && echo "  a Python virtual environment in .venv/"
$need_pip && echo "  PyPI, into .venv/: $(grep -v '^#' "$requirements" | tr '\n' ' ')"
$need_sdist && echo "  PyPI, into $pycan_dir/: python-can $pycan_version's source distribution (for its test logs)"
$need_cantools_sdist && echo "  PyPI, into $cantools_dir/: cantools $cantools_version's source distribution (for its test DBC files)"
$need_opendbc && echo "  PyPI, into $opendbc_dir/: opendbc $opendbc_version's wheel (for its DBC files)"
if $check_only; then
    exit 1
fi
if [ ${#debs[@]} != 0 ] && ! $root_apt; then
    fail "installing Debian packages needs root and apt-get: install ${debs[*]} (sudo apt-get install ${debs[*]}), or run this script as root; nothing was installed. (scripts/test.sh --no-setup runs the tests without this setup; the interop tests then say SKIPPED for what is missing, and fail under CI=1.)"
fi

# --- Install --------------------------------------------------------------------------------

if $need_nextest; then
    cargo install --locked cargo-nextest ||
        fail "cannot install cargo-nextest (cargo install --locked cargo-nextest); scripts/test.sh needs it"
fi

apt_updated=false
apt_update() {
    if ! $apt_updated; then
        apt-get update -qq || fail "apt-get update failed"
        apt_updated=true
    fi
}
if [ ${#debs[@]} != 0 ]; then
    apt_update
    # tshark asks whether non-root users may capture: answer no, without a dialog.
    if [[ " ${debs[*]} " == *" tshark "* ]]; then
        echo "wireshark-common wireshark-common/install-setuid boolean false" | debconf-set-selections ||
            fail "cannot preseed wireshark-common/install-setuid (debconf-set-selections)"
    fi
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${debs[@]}" >/dev/null ||
        fail "apt-get install ${debs[*]} failed"
fi
# Every tool is there now.
for pair in sigrok-cli:sigrok-cli openssl:openssl chromium:chromium chromedriver:chromium-driver \
    qemu-system-x86_64:qemu-system-x86 busybox:busybox-static cpio:cpio candump:can-utils \
    slcand:can-utils strip:binutils log2asc:can-utils asc2log:can-utils tshark:tshark \
    editcap:tshark s51:sdcc-ucsim as31:as31 sdcc:sdcc qemu-ppc:qemu-user \
    powerpc-linux-gnu-as:binutils-powerpc-linux-gnu powerpc-linux-gnu-gcc:gcc-powerpc-linux-gnu \
    clang:clang wasm-ld:lld wat2wasm:wabt; do
    has "${pair%%:*}" || fail "${pair%%:*} is still missing after installing ${pair#*:}"
done
[ -x /usr/sbin/dovecot ] || fail "dovecot is still missing after installing dovecot-imapd"
[ -x /usr/sbin/mosquitto ] || fail "mosquitto is still missing after installing mosquitto"
ldd "$(command -v busybox)" >/dev/null 2>&1 && fail "busybox is dynamically linked; install busybox-static"

if $need_kernel; then
    $root_apt && apt_update
    kernel="$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-/ { print $2; exit }')"
    [ -n "$kernel" ] || fail "apt-cache finds no kernel package behind linux-image-amd64 (apt-get update?)"
    echo "downloading $kernel (Debian; unpacked for the SocketCAN test VM, not installed)"
    mkdir -p target/vm-cache
    (cd target/vm-cache && apt-get download -qq "$kernel" 2>/dev/null) ||
        fail "apt-get download $kernel failed"
    ls target/vm-cache/linux-image-*-amd64_*.deb >/dev/null 2>&1 ||
        fail "apt-get download $kernel left no package in target/vm-cache/"
fi

if $need_venv; then
    has python3 || fail "python3 is missing (the interop tests need it)"
    python3 -m venv .venv || { rm -rf .venv; fail "python3 -m venv .venv failed"; }
fi
if ! cmp -s "$requirements" "$stamp"; then
    echo "installing Python test packages into .venv"
    .venv/bin/pip install --quiet --disable-pip-version-check -r "$requirements" ||
        fail "pip could not install $requirements into .venv"
    cp "$requirements" "$stamp"
fi
.venv/bin/python -c "import serial, can, cantools" ||
    fail "the .venv lacks pyserial, python-can or cantools; delete .venv and run this script again"

if $need_sdist; then
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

if $need_cantools_sdist; then
    echo "downloading cantools $cantools_version's source distribution (PyPI, for its test DBC files)"
    mkdir -p "$cantools_dir"
    printf 'cantools==%s --hash=sha256:%s\n' "$cantools_version" "$cantools_sha256" >"$cantools_dir/requirements.txt"
    .venv/bin/pip download --quiet --disable-pip-version-check --no-deps --no-binary :all: \
        --require-hashes -r "$cantools_dir/requirements.txt" -d "$cantools_dir" ||
        fail "pip could not download cantools $cantools_version's sdist into $cantools_dir"
    tar -xzf "$cantools_dir/cantools-$cantools_version.tar.gz" -C "$cantools_dir" \
        "cantools-$cantools_version/tests/files/dbc" "cantools-$cantools_version/LICENSE" ||
        fail "cannot unpack tests/files/dbc from $cantools_dir/cantools-$cantools_version.tar.gz"
    [ -f "$cantools_dbc/motohawk.dbc" ] || fail "cantools' sdist has no tests/files/dbc/motohawk.dbc"
fi

if $need_opendbc; then
    echo "downloading opendbc $opendbc_version's wheel (PyPI, for its DBC files)"
    mkdir -p "$opendbc_dir"
    printf 'opendbc==%s --hash=sha256:%s\n' "$opendbc_version" "$opendbc_sha256" >"$opendbc_dir/requirements.txt"
    .venv/bin/pip download --quiet --disable-pip-version-check --no-deps --only-binary :all: \
        --require-hashes -r "$opendbc_dir/requirements.txt" -d "$opendbc_dir" ||
        fail "pip could not download opendbc $opendbc_version's wheel into $opendbc_dir"
    # A wheel is a zip: its DBC files (not the generator's parts) and the licence.
    .venv/bin/python - "$opendbc_dir/opendbc-$opendbc_version-py3-none-any.whl" "$opendbc_dir" <<'PY' ||
import sys, zipfile
wheel, into = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        top_dbc = name.startswith("opendbc/dbc/") and name.count("/") == 2 and name.endswith(".dbc")
        if top_dbc or name.endswith("dist-info/licenses/LICENSE"):
            z.extract(name, into)
PY
        fail "cannot unpack opendbc/dbc from $opendbc_dir/opendbc-$opendbc_version-py3-none-any.whl"
    [ -f "$opendbc_dbc/tesla_can.dbc" ] || fail "opendbc's wheel has no opendbc/dbc/tesla_can.dbc"
fi
