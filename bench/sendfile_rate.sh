#!/usr/bin/env bash
# buslab sendfile's rate against what the wire allows: a SIZE (100000) byte file of zeros, of
# the bytes i % 251 and of random bytes, sent on a BITRATE (125000) bit/s `buslab bus serve` to
# a listening recvfile. "The wire" is the same file sent by the simulator in virtual time
# (`buslab sim`, a scenario node with `file` traffic: one frame queued the moment the last one
# ended, so nothing but the frames and their 3-bit intermissions): its last frame's end is the
# shortest time the bus can carry the file in, stuff bits and all. Zeros need the most stuff bits
# (125 bits a frame on ID 123), random bytes about 114.
#
# BUSLAB=path measures that binary instead of a fresh release build; BUSLAB_BEFORE=path adds
# rows for another one (an older build) measured the same way.
set -euo pipefail
cd "$(dirname "$0")/.."

SIZE=${SIZE:-100000}
BITRATE=${BITRATE:-125000}

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
        kill -0 "$3" 2>/dev/null || { echo "bench/sendfile_rate.sh: $4 exited: $(cat "$1")" >&2; exit 1; }
        tries=$((tries + 1))
        [ "$tries" -lt 600 ] || { echo "bench/sendfile_rate.sh: no '$2' from $4 in 60 s" >&2; exit 1; }
        sleep 0.1
    done
}

head -c "$SIZE" /dev/zero >"$work/zeros.bin"
python3 -c "import sys; sys.stdout.buffer.write(bytes(i % 251 for i in range($SIZE)))" >"$work/counting.bin"
head -c "$SIZE" /dev/urandom >"$work/random.bin"

# The seconds the simulator's bus takes to carry FILE: the end of its last frame.
wire_seconds() { # FILE
    local scenario=$work/wire.toml
    {
        echo "bitrate = $BITRATE"
        # Long enough for the slowest file (every frame 135 bits) and then some.
        echo "duration = \"$(((SIZE / 8 + 1) * 135 * 2 / BITRATE + 1))s\""
        echo '[[nodes]]'
        echo 'name = "sender"'
        echo '  [[nodes.traffic]]'
        echo '  kind = "file"'
        echo '  id = "123"'
        echo "  hex = \"$(od -An -v -tx1 "$1" | tr -d ' \n')\""
        echo '[[nodes]]'
        echo 'name = "receiver"'
    } >"$scenario"
    "$buslab" sim "$scenario" | grep ' sender 123#' | tail -1 | sed 's/^(\([0-9.]*\)).*/\1/'
}

measure() { # BINARY LABEL
    local bin=$1 label=$2
    "$bin" -q bus serve --listen 127.0.0.1:0 --bitrate "$BITRATE" >"$work/serve.out" 2>"$work/serve.err" &
    local serve=$!
    pids+=("$serve")
    wait_for "$work/serve.out" socketcand "$serve" "buslab bus serve"
    local bus
    bus=$(head -1 "$work/serve.out")
    for pattern in zeros counting random; do
        local wire
        wire=$(wire_seconds "$work/$pattern.bin")
        "$bin" recvfile --id 0x123 "$work/out.bin" --bus "$bus" >/dev/null 2>"$work/recv.err" &
        local recv=$!
        pids+=("$recv")
        wait_for "$work/recv.err" "waiting for a file" "$recv" "buslab recvfile"
        "$bin" sendfile --id 0x123 "$work/$pattern.bin" --bus "$bus" 2>"$work/send.err" >/dev/null
        wait "$recv"
        cmp -s "$work/$pattern.bin" "$work/out.bin" ||
            { echo "bench/sendfile_rate.sh: $pattern arrived different" >&2; exit 1; }
        # `sent FILE (N bytes) on ID 123 in 12.9 s (7725 bytes/s)`, the receiver's likewise.
        local sent received
        sent=$(sed -n 's/.* (\([0-9]*\) bytes\/s)$/\1/p' "$work/send.err")
        received=$(sed -n 's/.* (\([0-9]*\) bytes\/s), written to .*/\1/p' "$work/recv.err")
        awk -v label="$label" -v p="$pattern" -v size="$SIZE" -v wire="$wire" -v s="$sent" -v r="$received" \
            'BEGIN { w = size / wire; printf "| %s | %s | %.3f s | %.0f B/s | %s B/s | %.1f %% | %s B/s |\n",
                     label, p, wire, w, s, 100 * s / w, r }'
    done
    kill "$serve" 2>/dev/null || true
    wait "$serve" 2>/dev/null || true
}

echo "a file of $SIZE bytes (zeros, i % 251, random) on ID 123 of a $BITRATE bit/s virtual bus (buslab bus serve), sendfile to recvfile:"
echo
echo "| binary | file | the wire's time (sim) | the wire allows | sendfile | of the wire | recvfile (first to last frame) |"
echo "|---|---|---|---|---|---|---|"
if [ -n "${BUSLAB_BEFORE:-}" ]; then
    measure "$BUSLAB_BEFORE" "$(basename "$BUSLAB_BEFORE") (before)"
fi
measure "$buslab" "$(basename "$buslab")"
