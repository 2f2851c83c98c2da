#!/usr/bin/env python3
"""CPU of an idle `buslab bus serve` and the latency of a single frame through it, for one or
more buslab binaries side by side (e.g. the one before a change and the one after).

Usage: python3 bench/bus_serve_idle.py [--seconds 10] [--frames 400] [--runs 1] NAME=PATH [NAME=PATH ...]
       (default: `current=target/release/buslab`, built with `cargo build --release -p buslab`)

Rows:
- idle CPU: the server at 10x real time (and at 100x with no client), 8 raw socketcand clients
  connected in raw mode and silent; CPU time of the server process (utime + stime from
  /proc) over the wall time, in per cent of one core;
- latency: at real time (500 kbit/s), client A sends `123#` (DLC 0: 44 bits from start to
  end of frame and 1 stuff bit, 0.09 ms on the wire), client B waits for it; one frame at a
  time, from A's send call to B's receive call; p50 and p99 over `--frames` frames, and the
  frame's own wire time for reference.

With `--runs N` every binary is measured N times, the binaries taking turns, and each column
is the median of its N values (the machine's load comes and goes; the load average is printed
before and after).

Plain sockets, no python-can: the client's own overhead stays small and the same for every
binary. The machine is shared: compare rows of the same run, not runs of different days.
"""

import argparse
import os
import socket
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


class Server:
    def __init__(self, binary, *args):
        self.proc = subprocess.Popen(
            [binary, "-q", "bus", "serve", "--listen", "127.0.0.1:0", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        url = self.proc.stdout.readline().strip()
        hostport = url.split("//", 1)[1].split("/", 1)[0]
        host, port = hostport.rsplit(":", 1)
        self.addr = (host, int(port))

    def stop(self):
        self.proc.terminate()
        self.proc.wait()


class Client:
    """A socketcand client in raw mode on vcan0."""

    def __init__(self, addr):
        self.s = socket.create_connection(addr)
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""
        self.expect(b"< hi >")
        self.s.sendall(b"< open vcan0 >")
        self.expect(b"< ok >")
        self.s.sendall(b"< rawmode >")
        self.expect(b"< ok >")

    def expect(self, text):
        while text not in self.buf:
            chunk = self.s.recv(65536)
            if not chunk:
                raise RuntimeError("server closed")
            self.buf += chunk
        self.buf = self.buf[self.buf.index(text) + len(text):]

    def close(self):
        self.s.close()


def idle_cpu(binary, speed, clients, seconds):
    server = Server(binary, "--speed", str(speed))
    conns = [Client(server.addr) for _ in range(clients)]
    time.sleep(0.5)
    c0, t0 = cpu_seconds(server.proc.pid), time.monotonic()
    time.sleep(seconds)
    c1, t1 = cpu_seconds(server.proc.pid), time.monotonic()
    for c in conns:
        c.close()
    server.stop()
    return 100.0 * (c1 - c0) / (t1 - t0)


def latency(binary, frames):
    server = Server(binary)
    a, b = Client(server.addr), Client(server.addr)
    # Frames wait 50 ms after the rawmode reply (python-can's quirk); then warm up.
    time.sleep(0.2)
    samples = []
    for i in range(frames + 20):
        t0 = time.perf_counter_ns()
        a.s.sendall(b"< send 123 0 >")
        b.expect(b"< frame 123 ")
        t1 = time.perf_counter_ns()
        if i >= 20:
            samples.append((t1 - t0) / 1e6)
        time.sleep(0.002)
    a.close()
    b.close()
    server.stop()
    samples.sort()
    return samples[len(samples) // 2], samples[int(len(samples) * 0.99)]


def median(values):
    values = sorted(values)
    middle = len(values) // 2
    return values[middle] if len(values) % 2 else (values[middle - 1] + values[middle]) / 2


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--frames", type=int, default=400)
    p.add_argument("--runs", type=int, default=1, help="measure each binary this often (medians)")
    p.add_argument("binaries", nargs="*", help="NAME=PATH of a buslab binary")
    args = p.parse_args()
    binaries = [b.split("=", 1) for b in args.binaries]
    if not binaries:
        subprocess.run(
            ["cargo", "build", "--release", "--quiet", "-p", "buslab"], cwd=ROOT, check=True
        )
        binaries = [("current", os.path.join(ROOT, "target/release/buslab"))]
    load_before = os.getloadavg()
    runs = {name: [] for name, _ in binaries}
    for run in range(args.runs):
        # Taking turns, and in the other order every other run, so a change of load over
        # the measurement falls on every binary alike.
        order = binaries if run % 2 == 0 else binaries[::-1]
        for name, path in order:
            idle10 = idle_cpu(path, 10, 8, args.seconds)
            idle100 = idle_cpu(path, 100, 0, args.seconds)
            p50, p99 = latency(path, args.frames)
            runs[name].append((idle10, idle100, p50, p99))
    rows = [(name, *map(median, zip(*runs[name]))) for name, _ in binaries]
    load_after = os.getloadavg()
    wire_ms = 45 / 500_000 * 1e3
    print()
    medians = f", medians of {args.runs} runs" if args.runs > 1 else ""
    print(f"bus serve, idle CPU over {args.seconds:.0f} s and single-frame latency at 500 kbit/s{medians}")
    print(
        "load average (1, 5, 15 min): before "
        + ", ".join(f"{x:.2f}" for x in load_before)
        + "; after "
        + ", ".join(f"{x:.2f}" for x in load_after)
    )
    print(f"(123# is 45 bits: {wire_ms:.2f} ms on the wire, which any latency includes)")
    print()
    print(f"{'binary':<12} {'idle 10x, 8 clients':>20} {'idle 100x, none':>16} {'p50 latency':>12} {'p99 latency':>12}")
    for name, idle10, idle100, p50, p99 in rows:
        print(f"{name:<12} {idle10:>18.1f} % {idle100:>14.1f} % {p50:>9.3f} ms {p99:>9.3f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
