#!/usr/bin/env bash
# buslab sendfile's memory against the size of the file it sends: a SIZE_MB (50) MB file sent
# on a 1 Mbit/s virtual bus to a listening recvfile; after MEASURE_SECONDS (15) of sending,
# each process's peak resident set (VmHWM from /proc) and the bytes received so far. A
# 50 MB file takes about 14 minutes on the bus: the peak of a sender that reads the whole
# file first is reached at its start, a streaming one's stays flat, so a part of the transfer
# shows both.
#
# BUSLAB=path measures that binary instead of a fresh release build; BUSLAB_BEFORE=path adds
# a row for another one (an older build) measured the same way.
set -euo pipefail
cd "$(dirname "$0")/.."

SIZE_MB=${SIZE_MB:-50}
MEASURED=${MEASURE_SECONDS:-15}

if [ -n "${BUSLAB:-}" ]; then
    buslab=$BUSLAB
else
    cargo build --release -q -p buslab --bin buslab
    buslab=target/release/buslab
fi
work=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT

# Waits until FILE holds TEXT, failing (never hanging) if PID died first or a minute passed.
wait_for() { # FILE TEXT PID WHAT
    local tries=0
    until grep -q "$2" "$1" 2>/dev/null; do
        kill -0 "$3" 2>/dev/null || { echo "bench/sendfile_memory.sh: $4 exited: $(cat "$1")" >&2; exit 1; }
        tries=$((tries + 1))
        [ "$tries" -lt 600 ] || { echo "bench/sendfile_memory.sh: no '$2' from $4 in 60 s" >&2; exit 1; }
        sleep 0.1
    done
}

peak_kib() { awk '/^VmHWM/ {print $2}' "/proc/$1/status"; }

head -c "$((SIZE_MB * 1000 * 1000))" /dev/urandom >"$work/in.bin"

measure() { # BINARY LABEL
    local bin=$1 label=$2
    "$bin" -q bus serve --listen 127.0.0.1:0 --bitrate 1000000 >"$work/serve.out" 2>"$work/serve.err" &
    local serve=$!
    pids+=("$serve")
    wait_for "$work/serve.out" socketcand "$serve" "buslab bus serve"
    local bus
    bus=$(head -1 "$work/serve.out")
    "$bin" recvfile --id 0x123 "$work/out.bin" --bus "$bus" >/dev/null 2>"$work/recv.err" &
    local recv=$!
    pids+=("$recv")
    wait_for "$work/recv.err" "waiting for a file" "$recv" "buslab recvfile"
    "$bin" sendfile --id 0x123 "$work/in.bin" --bus "$bus" >/dev/null 2>"$work/send.err" &
    local send=$!
    pids+=("$send")
    sleep "$MEASURED"
    kill -0 "$send" 2>/dev/null || { echo "bench/sendfile_memory.sh: sendfile exited: $(cat "$work/send.err")" >&2; exit 1; }
    local send_kib recv_kib sent
    send_kib=$(peak_kib "$send")
    recv_kib=$(peak_kib "$recv")
    # recvfile writes as it receives: the size of its temporary file (0 for a build that
    # keeps the file in memory until the end).
    sent=$(find "$work" -maxdepth 1 -name '.out.bin.*.tmp' -printf '%s\n' | head -1)
    awk -v label="$label" -v size="$SIZE_MB" -v s="$send_kib" -v r="$recv_kib" -v got="${sent:-?}" \
        'BEGIN { printf "| %s | %d MB | %.1f MiB | %.2f | %.1f MiB | %s |\n", label, size, s / 1024,
                 s * 1024 / (size * 1000 * 1000), r / 1024, got }'
    kill "$send" "$recv" "$serve" 2>/dev/null || true
    wait "$send" "$recv" "$serve" 2>/dev/null || true
    rm -f "$work"/.out.bin.*.tmp "$work/serve.out"
}

echo "after ${MEASURED} s of sending a ${SIZE_MB} MB file on a 1 Mbit/s virtual bus:"
echo
echo "| binary | file | sendfile peak RSS | peak / file size | recvfile peak RSS | bytes in recvfile's file |"
echo "|---|---|---|---|---|---|"
if [ -n "${BUSLAB_BEFORE:-}" ]; then
    measure "$BUSLAB_BEFORE" "$(basename "$BUSLAB_BEFORE") (before)"
fi
measure "$buslab" "$(basename "$buslab")"
