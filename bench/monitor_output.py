#!/usr/bin/env python3
"""`buslab monitor`'s output path against `cat` of the same text (issue 28, deliverable 5).

The monitor is a full-screen program: what it prints is not the frames but a screen of them,
redrawn on a clock. So it runs here as a user runs it, on a pseudo-terminal of ROWS × COLS,
fed by a socketcand server that sends FRAMES frames as fast as the monitor takes them; this
script is the terminal (it reads everything the monitor writes and keeps the top line, where
the monitor counts the frames it has taken). It measures

- the monitor's CPU time (user + system of all its threads, from /proc/PID/task/*/schedstat)
  from its start to the screen showing the last frame: frames per CPU second and CPU time per
  frame, against `cat` writing the same frames as text (candump log lines, one per frame) to a
  terminal of the same size (the best of three runs): the cat ratio (how many times faster cat
  passes the frames);
- the monitor's CPU time while the bus is silent afterwards (IDLE_S seconds, its table full of
  the frames' IDs): what its redraws cost on their own, in per cent of one core;
- the bytes the monitor wrote to the terminal, against cat's;
- whether the screen stays current while frames pour in: the screen updates seen and the
  longest time the top line did not move from when the server began sending to when the
  screen showed the last frame;
- `buslab dump` on the same terminal and frames (the text printer of the same bus), for scale;
- callgrind's instructions per frame: the difference between runs on FRAMES_CG and
  FRAMES_CG / 2 frames, over the frames between them, with the screen redraws of the longer
  run (under valgrind a run lasts longer, so it redraws more often per frame than natively, and
  this column moves with the machine's load) and without them (less the inclusive count of
  `Monitor::draw` that callgrind_annotate gives: what taking a frame costs, far steadier; the
  log lines formatted for each redraw, outside draw, stay in).

Nothing here waits without a bound: every wait ends when its work is done or after a time
derived from the work (frames × a generous time per frame, plus a start-up allowance), and then
the run fails with what the screen last showed and the monitor's error output.

usage: monitor_output.py [--frames N] [--cg-frames N] NAME:BINARY...
"""

import argparse
import fcntl
import os
import random
import re
import select
import shutil
import struct
import subprocess
import sys
import tempfile
import termios
import time

# The per-thread CPU clock of the bus benchmarks (/proc/PID/task/*/schedstat).
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import can_bus_serve as cbs  # noqa: E402

ROWS, COLS = 40, 120
# Allowances (generous: the machine is shared and often loaded; valgrind is 50-100× slower).
START_S = 60.0
PER_FRAME_S = 200e-6
PER_FRAME_CG_S = 5e-3
# The silent stretch after the frames, to see what the redraws cost on their own.
IDLE_S = 3.0

SERVER = r"""
import socket, sys
blob = open(sys.argv[1], "rb").read()
srv = socket.socket()
srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
srv.bind(("127.0.0.1", 0))
srv.listen(1)
print(srv.getsockname()[1], flush=True)
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
                # The handshake is over: the frames, then the connection stays open (a live
                # bus that fell silent) until the client leaves.
                print("sending", flush=True)
                conn.sendall(blob)
except OSError:
    pass
"""


class Failure(Exception):
    pass


def entries(n):
    """The frames of bench/output_paths.sh: a busy two-interface bus, 30 % extended IDs."""
    r = random.Random(42)
    t = 1_700_000_000_000_000
    for _ in range(n):
        t += r.randrange(50, 500)
        iface = "can1" if r.random() < 0.2 else "can0"
        ident = f"{r.randrange(0x20000000):08X}" if r.random() < 0.3 else f"{r.randrange(0x800):03X}"
        data = "".join(f"{r.randrange(256):02X}" for _ in range(r.randrange(9)))
        yield t, iface, ident, data


def write_inputs(work, n):
    """FRAMES as socketcand messages and as candump log lines; their paths."""
    sc, log = f"{work}/frames{n}.sc", f"{work}/frames{n}.log"
    with open(sc, "w") as s, open(log, "w") as l:
        for t, iface, ident, data in entries(n):
            stamp = f"{t // 1_000_000}.{t % 1_000_000:06d}"
            s.write(f"< frame {ident} {stamp} {data} >")
            l.write(f"({stamp}) {iface} {ident}#{data}\n")
    return sc, log


class TopLine:
    """The first row of a VT100 screen, from the bytes written to it: enough of a terminal for
    what crossterm writes (cursor moves, SGR, erases; one cell per character)."""

    TOKEN = re.compile(rb"\x1b\[([0-9;?]*)([@-~])|\x1b[^\[]|([\x00-\x1f])|([^\x00-\x1f\x1b]+)")

    def __init__(self):
        self.row, self.col = 0, 0
        self.cells = [" "] * COLS
        self.tail = b""

    def feed(self, data):
        data = self.tail + data
        end = 0
        for m in self.TOKEN.finditer(data):
            if m.start() != end:
                break
            csi, final, control, text = m.group(1), m.group(2), m.group(3), m.group(4)
            if final is not None:
                self.csi(csi, final)
            elif control is not None:
                if control == b"\r":
                    self.col = 0
                elif control == b"\n":
                    self.row += 1
            elif text is not None:
                # A UTF-8 sequence cut by the read stays for the next one.
                try:
                    chars = text.decode()
                except UnicodeDecodeError as e:
                    if e.start == 0:
                        break
                    chars = text[: e.start].decode()
                    end = m.start() + e.start
                    self.put(chars)
                    break
                self.put(chars)
            end = m.end()
        self.tail = data[end:]

    def csi(self, params, final):
        if final == b"H":
            parts = [int(p) if p else 1 for p in params.split(b";")] if params else [1, 1]
            self.row, self.col = parts[0] - 1, (parts[1] - 1 if len(parts) > 1 else 0)
        elif final == b"J" and params == b"2":
            self.cells = [" "] * COLS
        elif final == b"K" and self.row == 0:
            for c in range(self.col, COLS):
                self.cells[c] = " "

    def put(self, chars):
        if self.row == 0:
            for ch in chars:
                if self.col < COLS:
                    self.cells[self.col] = ch
                self.col += 1
        else:
            self.col += len(chars)

    def text(self):
        return "".join(self.cells).rstrip()

    def frames(self):
        m = re.search(r"  (\d+) frames  ", self.text())
        return int(m.group(1)) if m else None


def cpu_of(pid):
    """CPU seconds (user + system) of PID's threads so far, to the nanosecond."""
    return cbs.cpu_ns(pid) / 1e9


def read_for(master, seconds, top):
    """Reads the terminal for SECONDS (a measuring window, not a wait); the bytes read."""
    read = 0
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        r, _, _ = select.select([master], [], [], left)
        if r:
            data = os.read(master, 65536)
            read += len(data)
            top.feed(data)
    return read


def pty_pair():
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
    return master, slave


def wait_exit(pid, master, deadline, what):
    """Reads the terminal until PID exits (its last screen writes must not block it); its exit
    status and CPU seconds (user + system); the bytes read meanwhile."""
    read = 0
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            return status, usage.ru_utime + usage.ru_stime, read
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            raise Failure(f"{what} did not exit within its allowance")
        r, _, _ = select.select([master], [], [], 0.05)
        if r:
            try:
                read += len(os.read(master, 65536))
            except OSError:
                pass


def drain(master, pid, deadline, what):
    """Reads the terminal until PID exits; (bytes, CPU seconds, wall seconds)."""
    start = time.monotonic()
    read = 0
    while True:
        r, _, _ = select.select([master], [], [], 0.05)
        if r:
            try:
                data = os.read(master, 65536)
            except OSError:  # EIO: every writer has closed the terminal
                data = b""
            read += len(data)
            if data:
                continue
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            # What is still buffered in the terminal.
            while select.select([master], [], [], 0)[0]:
                try:
                    data = os.read(master, 65536)
                except OSError:
                    break
                if not data:
                    break
                read += len(data)
            if status != 0:
                raise Failure(f"{what} failed (wait status {status})")
            return read, usage.ru_utime + usage.ru_stime, time.monotonic() - start
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            raise Failure(f"{what} did not finish within its allowance")


def start_server(work, sc, deadline):
    server = subprocess.Popen([sys.executable, "-c", SERVER, sc], stdout=subprocess.PIPE)
    r, _, _ = select.select([server.stdout], [], [], max(0.0, deadline - time.monotonic()))
    line = server.stdout.readline() if r else b""
    if not line.strip():
        server.kill()
        server.wait()
        raise Failure("the socketcand server did not start")
    return server, int(line)


def stop(proc):
    if proc.poll() is None:
        proc.kill()
    proc.wait()


def run_monitor(work, binary, sc, n, prefix=(), per_frame=PER_FRAME_S):
    """`buslab monitor` on N frames until its screen shows all N, then `q`. A dict of results."""
    limit = START_S + n * per_frame
    deadline = time.monotonic() + limit
    server, port = start_server(work, sc, deadline)
    master, slave = pty_pair()
    errors = open(f"{work}/monitor.err", "w+")
    cmd = [*prefix, binary, "-q", "monitor", "--bus", f"socketcand://127.0.0.1:{port}/vcan0"]
    monitor = subprocess.Popen(cmd, stdin=slave, stdout=slave, stderr=errors, start_new_session=True)
    os.close(slave)
    top = TopLine()
    read = 0
    sending_at = None
    updates = []  # (time, frames shown) each time the count on the screen moved
    try:
        while True:
            now = time.monotonic()
            if now > deadline:
                raise Failure(
                    f"the monitor's screen did not show {n} frames within {limit:.0f} s "
                    f"(the top line: {top.text()!r})"
                )
            watch = [master] + ([server.stdout] if sending_at is None else [])
            r, _, _ = select.select(watch, [], [], min(0.1, deadline - now))
            if server.stdout in r:
                server.stdout.readline()
                sending_at = time.monotonic()
            if master in r:
                try:
                    data = os.read(master, 65536)
                except OSError:
                    data = b""
                if not data:
                    raise Failure(f"the monitor closed its terminal (the top line: {top.text()!r})")
                read += len(data)
                top.feed(data)
                shown = top.frames()
                if shown is not None and (not updates or shown != updates[-1][1]):
                    updates.append((time.monotonic(), shown))
                if shown is not None and shown > n:
                    raise Failure(f"the monitor shows {shown} frames; {n} were sent")
                if shown == n:
                    break
            done = monitor.poll()
            if done is not None:
                raise Failure(f"the monitor exited ({done}) before its screen showed {n} frames")
        cpu = cpu_of(monitor.pid)
        idle = None
        if not prefix:
            read += read_for(master, IDLE_S, top)
            idle = (cpu_of(monitor.pid) - cpu) / IDLE_S
        os.write(master, b"q")
        status, _, more = wait_exit(monitor.pid, master, deadline, "the monitor")
        monitor.returncode = os.waitstatus_to_exitcode(status)
        read += more
        if status != 0:
            raise Failure(f"the monitor exited with wait status {status} after q")
    except Failure as e:
        stop(monitor)
        errors.seek(0)
        text = errors.read().strip()
        raise Failure(f"{e}{'; its error output: ' + text if text else ''}") from None
    finally:
        stop(server)
        os.close(master)
        errors.close()
    # How stale the screen got while the frames came in: from the first byte sent to the
    # screen showing the last frame.
    times = [sending_at or updates[0][0]] + [t for t, shown in updates if shown > 0]
    stale = max(b - a for a, b in zip(times, times[1:])) if len(times) > 1 else 0.0
    updates = len([u for u in updates if u[1] > 0])
    return {"cpu": cpu, "idle": idle, "bytes": read, "updates": updates, "stale": stale}


def run_dump(work, binary, sc, n):
    """`buslab dump -n N` on the same frames and the same kind of terminal."""
    deadline = time.monotonic() + START_S + n * PER_FRAME_S
    server, port = start_server(work, sc, deadline)
    master, slave = pty_pair()
    cmd = [binary, "-q", "dump", f"socketcand://127.0.0.1:{port}/vcan0", "-n", str(n)]
    dump = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=slave, stderr=slave, start_new_session=True)
    os.close(slave)
    try:
        read, cpu, wall = drain(master, dump.pid, deadline, "buslab dump")
        dump.returncode = 0
    finally:
        stop(dump)
        stop(server)
        os.close(master)
    return {"cpu": cpu, "bytes": read, "wall": wall}


def run_cat(log, n):
    """`cat` of the frames as candump log lines to a terminal; CPU seconds, bytes."""
    deadline = time.monotonic() + START_S + n * PER_FRAME_S
    master, slave = pty_pair()
    cat = subprocess.Popen(["cat", log], stdout=slave, stderr=subprocess.DEVNULL, start_new_session=True)
    os.close(slave)
    try:
        read, cpu, _ = drain(master, cat.pid, deadline, "cat")
        cat.returncode = 0
    finally:
        stop(cat)
        os.close(master)
    return {"cpu": cpu, "bytes": read}


def instructions(work, binary, sc, n):
    """callgrind's instruction count of `buslab monitor` taking N frames, and the part of it
    spent in `Monitor::draw` (inclusive)."""
    out = f"{work}/callgrind.out"
    prefix = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", f"--log-file={work}/valgrind.log"]
    run_monitor(work, binary, sc, n, prefix, PER_FRAME_CG_S)
    with open(f"{work}/valgrind.log") as f:
        m = re.search(r"Collected : (\d+)", f.read())
    if not m:
        raise Failure("callgrind reported no instruction count")
    annotated = subprocess.run(
        ["callgrind_annotate", "--inclusive=yes", "--threshold=100", out],
        capture_output=True, text=True, timeout=START_S,
    ).stdout
    draw = re.search(r"^\s*([\d,]+) .*monitor\.rs:buslab::cmd::monitor::Monitor::draw \[", annotated, re.M)
    if not draw:
        raise Failure("callgrind_annotate shows no Monitor::draw (inlined? renamed?)")
    return int(m.group(1)), int(draw.group(1).replace(",", ""))


def per(cpu, n):
    return f"{cpu / n * 1e6:.2f}"


def rate(n, cpu):
    return f"{n / cpu:.0f}" if cpu > 0 else "inf"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=1_000_000)
    p.add_argument("--cg-frames", type=int, default=100_000)
    p.add_argument("binaries", nargs="+", metavar="NAME:BINARY")
    args = p.parse_args()
    for tool in ("cat", "valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            sys.exit(f"bench/monitor_output.py: {tool} is missing")
    n, cg = args.frames, args.cg_frames
    with tempfile.TemporaryDirectory() as work:
        sc, log = write_inputs(work, n)
        cg1, _ = write_inputs(work, cg // 2)
        cg2, _ = write_inputs(work, cg)
        cat = min((run_cat(log, n) for _ in range(3)), key=lambda c: c["cpu"])
        print(
            f"## buslab monitor on a {COLS}×{ROWS} pseudo-terminal: {n} frames from a socketcand "
            f"server as fast as it takes them; callgrind on {cg} - {cg // 2} frames"
        )
        head = ("run", "frames", "CPU s", "frames/CPU s", "µs/frame", "cat ratio", "term bytes", "updates", "stale ms", "idle CPU", "instr/frame", "w/o draw")
        row = "{:<18} {:>8} {:>7} {:>13} {:>9} {:>10} {:>11} {:>8} {:>9} {:>9} {:>12} {:>9}"
        print(row.format(*head))
        print(row.format("cat (log lines)", n, f"{cat['cpu']:.2f}", rate(n, cat["cpu"]), per(cat["cpu"], n), "1.0×", cat["bytes"], "-", "-", "-", "-", "-"))
        try:
            for entry in args.binaries:
                name, binary = entry.split(":", 1)
                m = run_monitor(work, binary, sc, n)
                (all2, draw2), (all1, draw1) = instructions(work, binary, cg2, cg), instructions(work, binary, cg1, cg // 2)
                i, j = all2 - all1, (all2 - draw2) - (all1 - draw1)
                ratio = (n / cat["cpu"]) / (n / m["cpu"]) if m["cpu"] > 0 and cat["cpu"] > 0 else float("inf")
                print(row.format(
                    f"{name} monitor", n, f"{m['cpu']:.2f}", rate(n, m["cpu"]), per(m["cpu"], n), f"{ratio:.1f}×",
                    m["bytes"], m["updates"], f"{m['stale'] * 1000:.0f}", f"{m['idle'] * 100:.1f} %",
                    f"{i / (cg - cg // 2):.0f}", f"{j / (cg - cg // 2):.0f}",
                ))
                d = run_dump(work, binary, sc, n)
                ratio = (n / cat["cpu"]) / (n / d["cpu"]) if d["cpu"] > 0 and cat["cpu"] > 0 else float("inf")
                print(row.format(
                    f"{name} dump", n, f"{d['cpu']:.2f}", rate(n, d["cpu"]), per(d["cpu"], n), f"{ratio:.1f}×",
                    d["bytes"], "-", "-", "-", "-", "-",
                ), flush=True)
        except Failure as e:
            sys.exit(f"bench/monitor_output.py: {e}")
    print(
        "# cat ratio: how many times faster cat writes the frames as text to the same terminal; "
        "term bytes: what each wrote to the terminal; updates: times the monitor's frame count "
        "moved on the screen; stale ms: the longest the screen showed no new count while the "
        "frames came in; idle CPU: the monitor's CPU time in the "
        f"{IDLE_S:.0f} s of silence after them, in per cent of one core; w/o draw: instructions per "
        "frame not counting the redraws"
    )


if __name__ == "__main__":
    main()
