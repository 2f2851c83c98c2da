#!/usr/bin/env bash
# The --dbc tools (issue 29) against a saturated 1 Mbit/s bus: can `buslab dump --dbc` and
# `buslab log cat --dbc` decode frames as fast as such a bus carries them, on one core of a
# loaded machine? One table.
#
# The input: a generated database (24 messages of 8 bytes: scaled 16-bit signals with units,
# a value table, a signed signal with an offset; every sixth message multiplexed) and a
# candump log of FRAMES 8-byte frames 114 µs apart (a saturated 1 Mbit/s bus: 111 bits per
# frame without stuff bits, and the 3-bit intermission, so at most 8 772 frames/s), 90 % of
# them messages of the database, 10 % other IDs. The same frames are served by a socketcand
# server (python, as fast as the client takes them) for `dump`.
#
# Every buslab run is pinned to core 0 (taskset) while two busy loops (`while :; do :; done`,
# unpinned) load the machine's cores, so buslab gets about half of one core; the server
# feeding `dump` is pinned to core 1. Columns: frames per wall second under that load, frames
# per CPU second (user + system; what the work costs, whatever the load), and the wall rate
# over 8 772 frames/s ("× bus": 1.0× keeps up with a saturated bus).
#
# Peer: cantools' `decode` (`candump | python -m cantools decode`, the layout buslab copies)
# on CANTOOLS_FRAMES frames of the same log, when a Python with cantools is given in
# CANTOOLS_PYTHON (e.g. a throwaway venv: python3 -m venv /tmp/ct && /tmp/ct/bin/pip install
# cantools) or python3 imports it; pinned and loaded alike.
#
# FRAMES (default 1000000), CANTOOLS_FRAMES (default 100000) change the sizes. Needs python3,
# taskset, /usr/bin/time.
set -euo pipefail
cd "$(dirname "$0")/.."

FRAMES=${FRAMES:-1000000}
CANTOOLS_FRAMES=${CANTOOLS_FRAMES:-100000}
CANTOOLS_PYTHON=${CANTOOLS_PYTHON:-python3}
BUS_RATE=8772

for tool in python3 taskset /usr/bin/time; do
    command -v "$tool" >/dev/null 2>&1 || {
        echo "bench/dbc_tools.sh: $tool is missing" >&2
        exit 1
    }
done

work=$(mktemp -d)
server=
busy=()
cleanup() {
    [ -z "$server" ] || kill "$server" 2>/dev/null || true
    for pid in "${busy[@]}"; do kill "$pid" 2>/dev/null || true; done
    rm -rf "$work"
}
trap cleanup EXIT

cargo build --release -q -p buslab --bin buslab
buslab=$PWD/target/release/buslab

python3 - "$work" "$FRAMES" "$CANTOOLS_FRAMES" <<'EOF'
import random, sys
work, frames, peer = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
r = random.Random(29)
messages = []
with open(f"{work}/car.dbc", "w") as f:
    f.write('VERSION ""\n\nNS_ :\n\nBS_:\n\nBU_: ECU Dash\n\n')
    for m in range(24):
        ident = 0x100 + m
        messages.append(ident)
        f.write(f"BO_ {ident} Message{m}: 8 ECU\n")
        if m % 6 == 5:
            f.write(' SG_ Page M : 0|8@1+ (1,0) [0|1] "" Dash\n')
            for page in range(2):
                for k in range(3):
                    f.write(f' SG_ P{page}S{k} m{page} : {8 + 16 * k}|16@1+ (0.01,0) [0|655.35] "V" Dash\n')
        else:
            for k in range(4 if m % 2 else 3):
                f.write(f' SG_ Value{k} : {16 * k}|16@1+ (0.1,-100) [-100|6453.5] "km/h" Dash\n')
            if m % 2 == 0:
                f.write(' SG_ Mode : 48|2@1+ (1,0) [0|3] "" Dash\n')
                f.write(' SG_ Temp : 56|8@1- (1,-40) [-168|87] "degC" Dash\n')
        f.write("\n")
    for m in range(0, 24, 2):
        if m % 6 != 5:
            f.write(f'VAL_ {0x100 + m} Mode 0 "Off" 1 "On" 2 "Eco" 3 "Sport" ;\n')
def log(path, n):
    t = 1_700_000_000_000_000
    with open(path, "w") as f:
        for _ in range(n):
            t += 114
            ident = r.choice(messages) if r.random() < 0.9 else 0x600 + r.randrange(256)
            data = bytearray(r.randrange(256) for _ in range(8))
            if ident >= 0x100 and (ident - 0x100) % 6 == 5:
                data[0] = r.randrange(2)
            f.write(f"({t // 1_000_000}.{t % 1_000_000:06d}) can0 {ident:03X}#{data.hex().upper()}\n")
log(f"{work}/in.log", frames)
log(f"{work}/peer.log", peer)
# The same frames for the socketcand server.
with open(f"{work}/in.log") as src, open(f"{work}/frames.sc", "w") as dst:
    for line in src:
        ts, _, frame = line.split()
        ident, data = frame.split("#")
        dst.write(f"< frame {ident} {ts[1:-1]} {data} >")
EOF

# A socketcand server that answers the handshake and sends the frames of FILE as fast as the
# client takes them (as bench/output_paths.sh's); prints its port.
cat >"$work/server.py" <<'EOF'
import socket, sys
blob = open(sys.argv[1], "rb").read()
srv = socket.socket()
srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
srv.bind(("127.0.0.1", 0))
srv.listen(4)
print(srv.getsockname()[1], flush=True)
while True:
    conn, _ = srv.accept()
    conn.sendall(b"< hi >")
    pending = b""
    try:
        while True:
            data = conn.recv(4096)
            if not data:
                break
            pending += data
            while b">" in pending:
                msg, pending = pending.split(b">", 1)
                word = msg.replace(b"<", b"").split()[:1]
                if word in ([b"open"], [b"rawmode"]):
                    conn.sendall(b"< ok >")
                else:
                    conn.sendall(b"< error unknown command >")
                if word == [b"buslab_ext"]:
                    conn.sendall(blob)
    except OSError:
        pass
    conn.close()
EOF

serve() {
    [ -z "$server" ] || { kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true; }
    coproc SERVER { exec taskset -c 1 python3 "$work/server.py" "$1"; }
    server=$SERVER_PID
    read -r port <&"${SERVER[0]}"
}

# timed OUT CMD...: CMD on core 0, stdout to OUT; sets wall and cpu (user + system).
timed() {
    local out=$1
    shift
    /usr/bin/time -f "%e %U %S" -o "$work/time" taskset -c 0 "$@" >"$out"
    read -r wall user sys <"$work/time"
    cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
}

div() { awk -v a="$1" -v b="$2" -v f="${3:-%.1f}" 'BEGIN { if (b > 0) printf f, a / b; else printf "inf" }'; }

row() { # NAME FRAMES
    printf '%-40s %9s %8s %8s %15s %14s %8s×\n' "$1" "$2" "$wall" "$cpu" \
        "$(div "$2" "$wall" "%.0f")" "$(div "$2" "$cpu" "%.0f")" \
        "$(div "$(div "$2" "$wall" "%.3f")" "$BUS_RATE")"
}

# The load: two busy loops.
for _ in 1 2; do
    sh -c 'while :; do :; done' &
    busy+=("$!")
done

echo "# --dbc tools against a saturated 1 Mbit/s bus ($BUS_RATE frames/s at most); load average: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# buslab pinned to core 0, two busy loops running; $FRAMES frames (8 bytes, 90 % of them messages of a 24-message database); dump reads them from a socketcand server as fast as it takes them"
printf '%-40s %9s %8s %8s %15s %14s %10s\n' tool frames "wall s" "CPU s" "frames/s (wall)" "frames/CPU s" "× bus"

timed "$work/out" "$buslab" log cat "$work/in.log"
row "buslab log cat (no --dbc)" "$FRAMES"
timed "$work/out" "$buslab" log cat "$work/in.log" --dbc "$work/car.dbc"
row "buslab log cat --dbc" "$FRAMES"
decoded=$(grep -c ' ::$' "$work/out" || true)
timed "$work/out" "$buslab" log cat "$work/in.log" --dbc "$work/car.dbc" --single-line
row "buslab log cat --dbc --single-line" "$FRAMES"
timed "$work/out" "$buslab" -q log convert "$work/in.log" "$work/out.csv" --dbc "$work/car.dbc"
row "buslab log convert --dbc (to CSV)" "$FRAMES"
serve "$work/frames.sc"
timed "$work/out" "$buslab" dump "socketcand://127.0.0.1:$port/vcan0" -n "$FRAMES"
row "buslab dump (no --dbc)" "$FRAMES"
serve "$work/frames.sc"
timed "$work/out" "$buslab" dump "socketcand://127.0.0.1:$port/vcan0" -n "$FRAMES" --dbc "$work/car.dbc"
row "buslab dump --dbc" "$FRAMES"
dumped=$(grep -c ' ::$' "$work/out" || true)

if "$CANTOOLS_PYTHON" -c 'import cantools' 2>/dev/null; then
    version=$("$CANTOOLS_PYTHON" -c 'import cantools; print(cantools.__version__)')
    timed "$work/out" "$CANTOOLS_PYTHON" -m cantools decode "$work/car.dbc" <"$work/peer.log"
    row "cantools $version decode" "$CANTOOLS_FRAMES"
    timed "$work/out" "$CANTOOLS_PYTHON" -m cantools decode --single-line "$work/car.dbc" <"$work/peer.log"
    row "cantools $version decode --single-line" "$CANTOOLS_FRAMES"
else
    echo "# cantools: not found ($CANTOOLS_PYTHON cannot import it; CANTOOLS_PYTHON=… names a Python that can)"
fi
echo "# frames decoded: log cat $decoded, dump $dumped of $FRAMES (the rest are IDs the database does not have)"
echo "# × bus: frames per wall second / $BUS_RATE; load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
