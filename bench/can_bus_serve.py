#!/usr/bin/env python3
"""Frames/s, loss and latency through `buslab bus serve` with 1 sender and 8 receivers, and
python-can's udp_multicast bus measured the same way in the same run, as the peer.

Usage: .venv/bin/python bench/can_bus_serve.py [--frames N] [--receivers 8]
(needs python-can and msgpack in .venv, which scripts/setup-test-deps.sh installs; builds
 buslab with --release first; takes about a minute)

Every frame carries a sequence number and the sender's monotonic time (µs) in its 8 data
bytes; each receiver process counts what it got and the latency from the send call to its
own receive call. "saturated" sends as fast as the transport takes frames (bus serve pushes
back through TCP: the sender waits for the bus); "paced" sends at a fixed rate so the latency
is not queueing. A real-time 1 Mbit/s CAN bus carries at most about 7.7 k frames/s of 8 data
bytes (about 130 bits each with stuffing), so bus serve's frames/s is the bus, not the
software; the `--speed` rows run the simulated bus faster than real time and are labelled so.
The last column is the server's CPU time (user + system, all its threads) during the row over
the time from the first frame sent to the last one received (the receivers' joining and their
final idle time-out count as CPU but not as time: if anything, an overestimate); what is left
of a core is what it has to spare.
"""

import argparse
import multiprocessing as mp
import os
import socket
import struct
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GROUP = "239.74.163.2"


def now_us():
    return time.monotonic_ns() // 1000


def payload(seq):
    return struct.pack("<II", seq & 0xFFFFFFFF, now_us() & 0xFFFFFFFF)


def percentile(values, p):
    if not values:
        return float("nan")
    values = sorted(values)
    k = min(len(values) - 1, int(round(p / 100 * (len(values) - 1))))
    return values[k]


# ---------------------------------------------------------------- socketcand (bus serve)


class Socketcand:
    """A minimal raw-mode client (the bench measures the server, not a client library)."""

    def __init__(self, host, port):
        self.s = socket.create_connection((host, port))
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""
        assert self.element() == b"< hi >"
        self.s.sendall(b"< open vcan0 >")
        assert self.element() == b"< ok >"
        self.s.sendall(b"< rawmode >")
        assert self.element() == b"< ok >"

    def element(self):
        while b">" not in self.buf:
            chunk = self.s.recv(65536)
            if not chunk:
                raise EOFError
            self.buf += chunk
        end = self.buf.index(b">") + 1
        start = self.buf.index(b"<")
        e, self.buf = self.buf[start:end], self.buf[end:]
        return e

    def frames(self, timeout):
        """Yields (data bytes, receive µs) until `timeout` s pass without a frame."""
        self.s.settimeout(timeout)
        while True:
            try:
                chunk = self.s.recv(1 << 20)
            except socket.timeout:
                return
            if not chunk:
                return
            t = now_us()
            self.buf += chunk
            *complete, self.buf = self.buf.split(b">")
            for e in complete:
                parts = e.split()
                if len(parts) >= 5 and parts[1] == b"frame":
                    yield bytes.fromhex(parts[4].decode()), t


def sc_receiver(host, port, ready, results, idle):
    c = Socketcand(host, port)
    ready.put(1)
    count, lat, last = 0, [], 0
    for data, t in c.frames(idle):
        if len(data) == 8:
            _, sent = struct.unpack("<II", data)
            lat.append((t - sent) & 0xFFFFFFFF)
            count += 1
            last = t
    results.put((count, lat, last))


def sc_sender(host, port, frames, rate, results):
    c = Socketcand(host, port)
    start = time.monotonic()
    results.put(("start", now_us()))
    batch = []
    for seq in range(frames):
        if rate:
            due = start + seq / rate
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        d = payload(seq)
        cmd = b"< send 123 8 " + b" ".join(b"%02X" % b for b in d) + b" >"
        if rate:
            c.s.sendall(cmd)
        else:
            batch.append(cmd)
            if len(batch) == 16:
                c.s.sendall(b"".join(batch))
                batch = []
    if batch:
        c.s.sendall(b"".join(batch))
    # Stay on the bus until the frames are out (leaving pulls the node off the wire).
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        c.s.sendall(b"< buslab_status >")
        e = c.element()
        while not e.startswith(b"< buslab_status"):
            e = c.element()
        fields = dict(f.split(b"=", 1) for f in e.split() if b"=" in f)
        if int(fields[b"sent"]) >= frames:
            break
        time.sleep(0.05)
    results.put(("sender", time.monotonic() - start))


def pc_receiver(host, port, ready, results, idle):
    """A python-can receiver through its socketcand interface (what a python-can user runs)."""
    import logging

    import can

    # python-can warns each time a read ends inside an element, which is routine here.
    logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)
    bus = can.Bus(interface="socketcand", channel="vcan0", host=host, port=port)
    python_can_receive(bus, ready, results, idle)


def python_can_receive(bus, ready, results, idle):
    """Counts what a python-can `bus` receives until `idle` s pass without a frame."""
    ready.put(1)
    count, lat, last = 0, [], 0
    while True:
        m = bus.recv(idle)
        if m is None:
            break
        t = now_us()
        if len(m.data) == 8:
            _, sent = struct.unpack("<II", bytes(m.data))
            lat.append((t - sent) & 0xFFFFFFFF)
            count += 1
            last = t
    bus.shutdown()
    results.put((count, lat, last))


# ---------------------------------------------------------------- udp_multicast (python-can)


def mc_receiver(ready, results, idle):
    import can

    python_can_receive(can.Bus(interface="udp_multicast", channel=GROUP), ready, results, idle)


def mc_sender(frames, rate, results):
    import can

    bus = can.Bus(interface="udp_multicast", channel=GROUP)
    start = time.monotonic()
    results.put(("start", now_us()))
    for seq in range(frames):
        if rate:
            due = start + seq / rate
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        bus.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=payload(seq)))
    results.put(("sender", time.monotonic() - start))
    bus.shutdown()


# ---------------------------------------------------------------- runs


def run(kind, frames, receivers, rate, addr=None):
    ctx = mp.get_context("fork")
    ready, results = ctx.Queue(), ctx.Queue()
    idle = 2.0
    procs = []
    for _ in range(receivers):
        if kind == "serve":
            p = ctx.Process(target=sc_receiver, args=(addr[0], addr[1], ready, results, idle))
        elif kind == "serve-python-can":
            p = ctx.Process(target=pc_receiver, args=(addr[0], addr[1], ready, results, idle))
        else:
            p = ctx.Process(target=mc_receiver, args=(ready, results, idle))
        p.start()
        procs.append(p)
    for _ in range(receivers):
        ready.get(timeout=30)
    time.sleep(0.2)
    if kind.startswith("serve"):
        s = ctx.Process(target=sc_sender, args=(addr[0], addr[1], frames, rate, results))
    else:
        s = ctx.Process(target=mc_sender, args=(frames, rate, results))
    s.start()
    got, lats, send_time, start, last = [], [], None, None, 0
    while len(got) < receivers or send_time is None:
        r = results.get(timeout=600)
        if r[0] == "sender":
            send_time = r[1]
        elif r[0] == "start":
            start = r[1]
        else:
            got.append(r[0])
            lats.extend(r[1])
            last = max(last, r[2])
    elapsed = (last - start) / 1e6 if start and last else float("nan")
    for p in procs + [s]:
        p.join(timeout=10)
    delivered = sum(got)
    expected = frames * receivers
    return {
        "frames_s": min(got) / elapsed if elapsed > 0 else float("nan"),
        "loss": 100.0 * (expected - delivered) / expected,
        "delivered": delivered,
        "min_rx": min(got),
        "p50": percentile(lats, 50) / 1000,
        "p99": percentile(lats, 99) / 1000,
        "elapsed": elapsed,
    }


def cpu_seconds(pid):
    """User + system CPU time of process `pid` so far (Linux /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        # The command name may hold spaces: the fields after it start past its ")".
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpu_ns(pid):
    """CPU time of all threads of process `pid` so far, in ns (/proc/PID/task/*/schedstat:
    nanoseconds, where /proc/PID/stat counts clock ticks of 10 ms, too coarse for a few
    hundred frames of tens of µs each). Threads that ended are not counted: the server's
    all live until it stops."""
    total = 0
    for task in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{task}/schedstat") as f:
                total += int(f.read().split()[0])
        except (FileNotFoundError, ProcessLookupError):
            pass
    return total


def start_server(binary, bitrate, speed):
    p = subprocess.Popen(
        [binary, "bus", "serve", "--listen", "127.0.0.1:0", "--bitrate", str(bitrate),
         "--speed", str(speed)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    url = p.stdout.readline().decode().strip()
    hostport = url[len("socketcand://"):].split("/")[0]
    host, port = hostport.rsplit(":", 1)
    return p, (host, int(port))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--receivers", type=int, default=8)
    ap.add_argument("--bitrate", type=int, default=1_000_000)
    args = ap.parse_args()
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "buslab"], cwd=ROOT, check=True)
    binary = os.path.join(target, "release", "buslab")

    rows = []
    n = args.frames
    for label, speed, rate, frames in [
        ("bus serve, 1 Mbit/s real time, saturated", 1.0, 0, n),
        ("bus serve, 1 Mbit/s real time, paced 4000/s", 1.0, 4000, n // 2),
        ("bus serve, 10x FASTER than real time, saturated", 10.0, 0, n),
    ]:
        server, addr = start_server(binary, args.bitrate, speed)
        try:
            cpu0 = cpu_seconds(server.pid)
            r = run("serve", frames, args.receivers, rate, addr)
            r["server_cpu"] = 100 * (cpu_seconds(server.pid) - cpu0) / r["elapsed"]
            rows.append((label, r))
        finally:
            server.terminate()
            server.wait()
    try:
        import msgpack  # noqa: F401

        for label, rate, frames in [
            ("python-can udp_multicast, saturated", 0, n),
            ("python-can udp_multicast, paced 4000/s", 4000, n // 2),
        ]:
            rows.append((label, run("multicast", frames, args.receivers, rate)))
    except ImportError:
        print("udp_multicast skipped: msgpack is not installed", file=sys.stderr)

    print(f"1 sender, {args.receivers} receivers, {n} frames of 8 bytes (paced runs: {n // 2})")
    print()
    print("| transport | frames/s (slowest receiver) | loss | latency p50 | latency p99 "
          "| bus serve CPU (% of a core) |")
    print("|---|---|---|---|---|---|")
    for label, r in rows:
        cpu = f"{r['server_cpu']:.0f} %" if "server_cpu" in r else "-"
        print(f"| {label} | {r['frames_s']:.0f} | {r['loss']:.2f} % | "
              f"{r['p50']:.2f} ms | {r['p99']:.2f} ms | {cpu} |")


if __name__ == "__main__":
    main()
