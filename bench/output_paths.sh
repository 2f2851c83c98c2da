#!/usr/bin/env bash
# buslab's output paths (issue 28): what printing costs next to the work behind it, as two
# tables.
#
# 1. `buslab sim` on a saturated 1 Mbit/s bus of 16 nodes (the scenario of bench/sim_speed.sh)
#    with its trace printed against `-q` (the summary only), same scenario and duration: the
#    real-time factor per wall second and per second of CPU time (user + system), lines
#    printed per CPU second, and callgrind's instructions per simulated second (the difference
#    between a CG_LONG and a CG_SHORT run, start-up left out). The target: the trace run at
#    least half the speed of -q (printing costs no more than the simulation).
# 2. `buslab log cat` (a candump log in, the same text out) and `buslab dump` (frames from a
#    socketcand server, printed in candump's terminal layout and, with -L, as log lines),
#    against `cat` of the same text: lines per CPU second, the ratio to cat, and callgrind's
#    instructions per line (the difference between two input sizes).
# 3. `buslab monitor` (the full-screen view) on a pseudo-terminal, fed by a socketcand server
#    as fast as it takes the frames, against `cat` of the same frames as text to the same
#    terminal: frames per CPU second, the bytes written to the terminal, how current the screen
#    stays, instructions per frame (bench/monitor_output.py, which says how).
#
# Every output goes to /dev/null; cat reads a file of the same text as the tool printed. The
# machine is shared and wall times are noisy: read the CPU columns and the instruction counts
# (they do not move with the load). BASELINE=path/to/an/older/buslab adds its rows, same
# inputs, same run (e.g. one built from main before a change). SIM_S (simulated seconds of the
# timed sim runs), LOG_LINES, DUMP_FRAMES, CG_LINES (lines under callgrind), CG_SHORT/CG_LONG
# (simulated seconds under callgrind), MONITOR_FRAMES, CG_FRAMES (frames under callgrind) change
# the sizes; TABLES=sim,text,monitor (the default) chooses the tables. Needs python3, valgrind,
# /usr/bin/time.
set -euo pipefail
cd "$(dirname "$0")/.."

SIM_S=${SIM_S:-300}
LOG_LINES=${LOG_LINES:-3000000}
DUMP_FRAMES=${DUMP_FRAMES:-1000000}
CG_LINES=${CG_LINES:-100000}
CG_SHORT=${CG_SHORT:-1}
CG_LONG=${CG_LONG:-3}
MONITOR_FRAMES=${MONITOR_FRAMES:-1000000}
CG_FRAMES=${CG_FRAMES:-100000}
TABLES=${TABLES:-sim,text,monitor}
BASELINE=${BASELINE:-}
table() { [[ ",$TABLES," == *",$1,"* ]]; }

for tool in python3 valgrind /usr/bin/time; do
    command -v "$tool" >/dev/null 2>&1 || {
        echo "bench/output_paths.sh: $tool is missing" >&2
        exit 1
    }
done

work=$(mktemp -d)
server=
cleanup() {
    [ -z "$server" ] || kill "$server" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT

cargo build --release -q -p buslab --bin buslab
buslab=$PWD/target/release/buslab
bins=("new:$buslab")
[ -z "$BASELINE" ] || bins+=("base:$(realpath "$BASELINE")")

# The saturated 16-node scenario of bench/sim_speed.sh: every node sends its own 8-byte frame
# every 800 µs, about 2.5 times what the bus carries.
{
    echo "bitrate = 1000000"
    echo "duration = \"1s\""
    for ((i = 0; i < 16; i++)); do
        printf '[[nodes]]\nname = "n%d"\n  [[nodes.traffic]]\n  kind = "periodic"\n' "$i"
        printf '  frame = "%03X#%02X55AA0001020304"\n  period = "800us"\n' $((0x100 + i)) "$i"
    done
} >"$work/sat16.toml"

# A candump log like a busy two-interface bus: 30 % extended IDs, 0..8 bytes, 50..500 µs
# apart (as bench/logs.sh). And the same frames as socketcand `< frame … >` messages.
table text && python3 - "$work" "$LOG_LINES" "$DUMP_FRAMES" "$CG_LINES" <<'EOF'
import random, sys
work, lines, frames, cg = sys.argv[1], *map(int, sys.argv[2:])
def entries(n):
    r = random.Random(42)
    t = 1_700_000_000_000_000
    for _ in range(n):
        t += r.randrange(50, 500)
        iface = "can1" if r.random() < 0.2 else "can0"
        ident = f"{r.randrange(0x20000000):08X}" if r.random() < 0.3 else f"{r.randrange(0x800):03X}"
        data = "".join(f"{r.randrange(256):02X}" for _ in range(r.randrange(9)))
        yield t, iface, ident, data
def log(path, n):
    with open(path, "w") as f:
        for t, iface, ident, data in entries(n):
            f.write(f"({t // 1_000_000}.{t % 1_000_000:06d}) {iface} {ident}#{data}\n")
def socketcand(path, n):
    with open(path, "w") as f:
        for t, _, ident, data in entries(n):
            f.write(f"< frame {ident} {t // 1_000_000}.{t % 1_000_000:06d} {data} >")
log(f"{work}/in.log", lines)
log(f"{work}/cg1.log", cg // 2)
log(f"{work}/cg2.log", cg)
socketcand(f"{work}/frames.sc", frames)
socketcand(f"{work}/cg1.sc", cg // 2)
socketcand(f"{work}/cg2.sc", cg)
EOF

# A socketcand server that answers the handshake (no buslab extensions) and sends the frames
# of FILE as fast as the client takes them, once per connection; prints its port.
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

# serve FILE: (re)starts the server on FILE; sets port.
serve() {
    [ -z "$server" ] || { kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true; }
    coproc SERVER { exec python3 "$work/server.py" "$1"; }
    server=$SERVER_PID
    read -r port <&"${SERVER[0]}"
}

# timed OUT CMD...: runs CMD with stdout to OUT; sets wall and cpu (user + system).
timed() {
    local out=$1
    shift
    /usr/bin/time -f "%e %U %S" -o "$work/time" "$@" >"$out"
    read -r wall user sys <"$work/time"
    cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
}

# instructions CMD...: callgrind's instruction count of CMD (stdout to /dev/null).
instructions() {
    valgrind --tool=callgrind --callgrind-out-file=/dev/null "$@" 2>&1 >/dev/null |
        sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}

div() { awk -v a="$1" -v b="$2" -v f="${3:-%.1f}" 'BEGIN { if (b > 0) printf f, a / b; else printf "inf" }'; }
lines_of() { grep -c '' "$1" || true; }

# cat of FILE: lines per CPU second, the file read over and over, about 2 GB in all (one read
# is too short to time: /usr/bin/time counts CPU time in hundredths of a second).
cat_rate() {
    local n size reps
    n=$(lines_of "$1")
    size=$(stat -c %s "$1")
    reps=$(((2000000000 + size - 1) / size))
    timed /dev/null xargs -a <(yes "$1" | head -n "$reps") cat
    div "$((reps * n))" "$cpu" "%.0f"
}

echo "# buslab output paths; load average: $(cut -d' ' -f1-3 /proc/loadavg)"
[ -z "$BASELINE" ] || echo "# base = $BASELINE, new = $buslab"
if table sim; then
echo
echo "## buslab sim, saturated 1 Mbit/s bus, 16 nodes, 8-byte frames: ${SIM_S} s simulated (timed), callgrind ${CG_LONG} s - ${CG_SHORT} s"
printf '%-16s %8s %8s %13s %13s %9s %14s %15s %14s\n' run "wall s" "CPU s" "×real (wall)" "×real (CPU)" lines "lines/CPU s" "Minstr/sim s" "vs -q (instr)"
for entry in "${bins[@]}"; do
    name=${entry%%:*} bin=${entry#*:}
    declare -A per=()
    for mode in quiet trace; do
        flag=()
        [ "$mode" = quiet ] && flag=(-q)
        timed "$work/sim.$mode" "$bin" "${flag[@]}" sim "$work/sat16.toml" --duration "${SIM_S}s"
        short=$(instructions "$bin" "${flag[@]}" sim "$work/sat16.toml" --duration "${CG_SHORT}s")
        long=$(instructions "$bin" "${flag[@]}" sim "$work/sat16.toml" --duration "${CG_LONG}s")
        per[$mode]=$(div "$((long - short))" "$((CG_LONG - CG_SHORT))" "%.0f")
        n=$(grep -vc '^#' "$work/sim.$mode" || true)
        printf '%-16s %8s %8s %12s× %12s× %9s %14s %15s %14s\n' "$name sim${flag[*]:+ -q}" "$wall" "$cpu" \
            "$(div "$SIM_S" "$wall")" "$(div "$SIM_S" "$cpu")" "$n" "$(div "$n" "$cpu" "%.0f")" \
            "$(div "${per[$mode]}" 1000000)" "$(div "${per[quiet]}" "${per[$mode]}" "%.2f")×"
    done
    cp "$work/sim.trace" "$work/trace.$name"
done
cmp -s "$work/trace.new" "$work/trace.${bins[-1]%%:*}" && same=yes || same=no
echo "# cat of the trace: $(cat_rate "$work/trace.new") lines/CPU s; vs -q (instr): -q's instructions per simulated second / this run's (1.00× = printing is free, ≥ 0.50× = the target); same trace from every binary: $same"
fi

if table text; then
echo

echo "## text out: ${LOG_LINES} log lines, ${DUMP_FRAMES} frames from a socketcand server; callgrind on ${CG_LINES} - $((CG_LINES / 2)) lines"
printf '%-22s %9s %8s %8s %14s %14s %10s %12s\n' tool lines "wall s" "CPU s" "lines/CPU s" "cat lines/s" "cat ratio" "instr/line"
for entry in "${bins[@]}"; do
    name=${entry%%:*} bin=${entry#*:}
    # log cat
    timed "$work/out" "$bin" log cat "$work/in.log"
    n=$(lines_of "$work/out")
    rate=$(div "$n" "$cpu" "%.0f")
    c=$(cat_rate "$work/out")
    i1=$(instructions "$bin" log cat "$work/cg1.log")
    i2=$(instructions "$bin" log cat "$work/cg2.log")
    printf '%-22s %9s %8s %8s %14s %14s %9s× %12s\n' "$name log cat" "$n" "$wall" "$cpu" "$rate" "$c" \
        "$(div "$c" "$rate")" "$(div "$((i2 - i1))" "$((CG_LINES - CG_LINES / 2))" "%.0f")"
    # dump, terminal layout and -L
    for layout in terminal -L; do
        flag=()
        [ "$layout" = -L ] && flag=(-L)
        serve "$work/frames.sc"
        timed "$work/out" "$bin" dump "socketcand://127.0.0.1:$port/vcan0" "${flag[@]}" -n "$DUMP_FRAMES"
        n=$(lines_of "$work/out")
        rate=$(div "$n" "$cpu" "%.0f")
        c=$(cat_rate "$work/out")
        serve "$work/cg1.sc"
        i1=$(instructions "$bin" dump "socketcand://127.0.0.1:$port/vcan0" "${flag[@]}" -n $((CG_LINES / 2)))
        serve "$work/cg2.sc"
        i2=$(instructions "$bin" dump "socketcand://127.0.0.1:$port/vcan0" "${flag[@]}" -n "$CG_LINES")
        printf '%-22s %9s %8s %8s %14s %14s %9s× %12s\n' "$name dump${flag[*]:+ -L}" "$n" "$wall" "$cpu" \
            "$rate" "$c" "$(div "$c" "$rate")" "$(div "$((i2 - i1))" "$((CG_LINES - CG_LINES / 2))" "%.0f")"
    done
done
echo "# cat ratio: how many times faster cat passes the same text (lower is better)"
fi

if table monitor; then
echo
python3 bench/monitor_output.py --frames "$MONITOR_FRAMES" --cg-frames "$CG_FRAMES" "${bins[@]}"
fi
echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
