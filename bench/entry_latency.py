#!/usr/bin/env python3
"""How long a frame takes to enter a virtual bus, hop by hop: a raw socketcand client sending
to `buslab bus serve` directly, against a frame entering through a buslab client (`buslab
bridge`, the gateway of `bus serve --join`), for one or more buslab binaries in the same run.

Usage: .venv/bin/python bench/entry_latency.py [--frames N] [--rate R] [--idle SECONDS]
       BINARY[=LABEL]...
(python-can in .venv from scripts/setup-test-deps.sh; about 5 s per binary, plus --idle)

Each row sends N frames of 8 bytes paced at R frames/s (so latency is not queueing), each
carrying its number and the sender's monotonic clock (µs); a python-can process receives on
the last bus and takes the difference (one clock: the same machine). Rows:

* `socketcand -> bus`: python-can sends to the bus it receives on (socketcand alone).
* `buslab_ext client -> bus`: a raw TCP client that turns buslab's extensions on (as buslab's
  own client does) sends to that bus: the server's side of a buslab client.
* `bridge A -> B`: python-can sends on bus A, `buslab bridge --one-way A B` copies to bus B
  (two pumps: A's receives, B's sends).
* `bridge A -> slcan adapter on B`: the same, B reached through an SLCAN adapter (`buslab slcan
  serve` on a pseudo-terminal, plugged into bus B): the bridge's pump hands frames to an
  `slcan:` bus.
* `cannelloni udp -> gateway -> bus`: a raw UDP socket sends one cannelloni packet per frame to
  `bus serve --join` (the gateway's pump hands it to the bus): a frame handed to a pump.

`--idle S` also runs an idle `buslab bridge` between two idle buses for S seconds and prints
the CPU time it used (a pump must not spin while it waits).
"""

import argparse
import multiprocessing as mp
import os
import socket
import struct
import subprocess
import sys
import tempfile
import time

import can

# The helpers of the joined-buses benchmark: one clock, one percentile, one python-can client.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from join_transports import connect, free_port, now_us, percentile  # noqa: E402


def payload(k):
    return k.to_bytes(4, "little") + (now_us() & 0xFFFFFFFF).to_bytes(4, "little")


def receiver(port, count, ready, results):
    bus = connect(port)
    ready.set()
    latencies = []
    while len(latencies) < count:
        msg = bus.recv(timeout=3)
        if msg is None:
            break
        t = now_us()
        sent = int.from_bytes(msg.data[4:8], "little")
        latencies.append(((t & 0xFFFFFFFF) - sent) % (1 << 32) / 1000)
    bus.shutdown()
    results.put(latencies)


def paced(count, rate, send):
    start = time.monotonic()
    for k in range(count):
        wait = start + k / rate - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        send(k)


def send_python_can(port, count, rate):
    bus = connect(port)
    paced(count, rate, lambda k: bus.send(
        can.Message(arbitration_id=0x123, data=payload(k), is_extended_id=False)))
    bus.shutdown()


def send_buslab_ext(port, count, rate):
    s = socket.create_connection(("127.0.0.1", port))
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    f = s.makefile("rb")

    def element():
        out = b""
        while not out.endswith(b">"):
            out += f.read(1)
        return out

    element()  # < hi >
    for cmd in [b"< open vcan0 >", b"< rawmode >", b"< buslab_ext >"]:
        s.sendall(cmd)
        element()
    paced(count, rate, lambda k: s.sendall(
        b"< send 123 8 %s >" % b" ".join(b"%02X" % b for b in payload(k))))
    time.sleep(0.1)
    s.close()


def send_cannelloni(own_port, peer_port, count, rate):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", own_port))
    paced(count, rate, lambda k: s.sendto(
        bytes([2, 0, k % 256, 0, 1]) + struct.pack(">IB", 0x123, 8) + payload(k),
        ("127.0.0.1", peer_port)))
    s.close()


def serve(binary, join=None):
    cmd = [binary, "bus", "serve", "--listen", "127.0.0.1:0", "--bitrate", "1000000"]
    if join:
        cmd += ["--join", join]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = p.stdout.readline().strip()
    return p, int(line.rsplit(":", 1)[1].split("/")[0])


def bridge(binary, pa, pb, log, to=None):
    p = subprocess.Popen(
        [binary, "bridge", "--one-way", "socketcand://127.0.0.1:%d/vcan0" % pa,
         to or "socketcand://127.0.0.1:%d/vcan0" % pb],
        stdout=subprocess.DEVNULL, stderr=log)
    # Both sides joined once the bridge says what it bridges.
    deadline = time.monotonic() + 30
    while b"bridge:" not in open(log.name, "rb").read():
        if time.monotonic() > deadline or p.poll() is not None:
            raise RuntimeError("the bridge did not start")
        time.sleep(0.02)
    return p


def slcan_adapter(binary, pb, tty):
    """`buslab slcan serve` plugged into bus B, its pseudo-terminal at `tty`."""
    p = subprocess.Popen(
        [binary, "slcan", "serve", "--bus", "socketcand://127.0.0.1:%d/vcan0" % pb,
         "--link", tty], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while not os.path.exists(tty):
        if time.monotonic() > deadline or p.poll() is not None:
            raise RuntimeError("the SLCAN adapter did not start")
        time.sleep(0.02)
    return p


def measure(rx_port, count, send):
    results = mp.Queue()
    ready = mp.Event()
    rx = mp.Process(target=receiver, args=(rx_port, count, ready, results))
    rx.start()
    ready.wait()
    time.sleep(0.2)  # the receiver's connection is set up on the server side
    send()
    latencies = results.get()
    rx.join()
    return {"got": len(latencies), "p50": percentile(latencies, 50),
            "p99": percentile(latencies, 99)}


def run_row(binary, row, frames, rate):
    procs = []
    log = tempfile.NamedTemporaryFile()
    try:
        if row == "socketcand -> bus":
            a, pa = serve(binary)
            procs.append(a)
            return measure(pa, frames, lambda: send_python_can(pa, frames, rate))
        if row == "buslab_ext client -> bus":
            a, pa = serve(binary)
            procs.append(a)
            return measure(pa, frames, lambda: send_buslab_ext(pa, frames, rate))
        if row == "bridge A -> B":
            a, pa = serve(binary)
            procs.append(a)
            b, pb = serve(binary)
            procs.append(b)
            procs.append(bridge(binary, pa, pb, log))
            return measure(pb, frames, lambda: send_python_can(pa, frames, rate))
        if row == "bridge A -> slcan adapter on B":
            a, pa = serve(binary)
            procs.append(a)
            b, pb = serve(binary)
            procs.append(b)
            tty = os.path.join(tempfile.mkdtemp(), "ttyACM0")
            procs.append(slcan_adapter(binary, pb, tty))
            procs.append(bridge(binary, pa, pb, log, "slcan:" + tty))
            return measure(pb, frames, lambda: send_python_can(pa, frames, rate))
        ua, ub = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
        b, pb = serve(binary, "cannelloni://127.0.0.1:%d?listen=127.0.0.1:%d" % (ua, ub))
        procs.append(b)
        return measure(pb, frames, lambda: send_cannelloni(ua, ub, frames, rate))
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait()


def idle_cpu(binary, seconds):
    """CPU seconds an idle bridge between two idle buses uses in `seconds`."""
    procs = []
    log = tempfile.NamedTemporaryFile()
    try:
        a, pa = serve(binary)
        procs.append(a)
        b, pb = serve(binary)
        procs.append(b)
        br = bridge(binary, pa, pb, log)
        procs.append(br)

        def cpu():
            fields = open("/proc/%d/stat" % br.pid).read().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

        before = cpu()
        time.sleep(seconds)
        return cpu() - before
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait()


ROWS = ["socketcand -> bus", "buslab_ext client -> bus", "bridge A -> B",
        "bridge A -> slcan adapter on B", "cannelloni udp -> gateway -> bus"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--rate", type=int, default=1000)
    ap.add_argument("--idle", type=float, default=0)
    ap.add_argument("binaries", nargs="+", metavar="BINARY[=LABEL]")
    args = ap.parse_args()
    binaries = [(b.split("=", 1) + [b])[:2] for b in args.binaries]
    results = {}
    # Rows interleaved between binaries, so a change in the machine's load hits all alike.
    for row in ROWS:
        for binary, label in binaries:
            r = run_row(binary, row, args.frames, args.rate)
            results[(row, label)] = r
            print("%s, %s: %s" % (label, row, r), file=sys.stderr)
    idle = {}
    if args.idle:
        for binary, label in binaries:
            idle[label] = idle_cpu(binary, args.idle)
    print("%d frames of 8 bytes paced at %d/s, python-can receiver, bus at 1 Mbit/s, loopback;"
          " load average %s" % (args.frames, args.rate,
                                " ".join("%.2f" % x for x in os.getloadavg())))
    print()
    labels = [label for _, label in binaries]
    print("| hop | " + " | ".join("%s p50 | %s p99" % (l, l) for l in labels) + " |")
    print("|---|" + "---|---|" * len(labels))
    for row in ROWS:
        cells = []
        for l in labels:
            r = results[(row, l)]
            lost = "" if r["got"] == args.frames else " (%d lost)" % (args.frames - r["got"])
            cells.append("%.2f ms%s | %.2f ms" % (r["p50"], lost, r["p99"]))
        print("| %s | %s |" % (row, " | ".join(cells)))
    if idle:
        print()
        print("idle `buslab bridge`, %.0f s: " % args.idle + ", ".join(
            "%s %.2f s CPU" % (l, idle[l]) for l in labels))


if __name__ == "__main__":
    main()
