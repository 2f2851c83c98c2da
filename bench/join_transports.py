#!/usr/bin/env python3
"""Frames/s and latency between two buses joined through each transport (`bus serve --join`:
Mosquitto MQTT, cannelloni UDP, cannelloni TCP) on loopback, against the same sender and
receiver on one bus through socketcand alone.

Usage: .venv/bin/python bench/join_transports.py [--frames N] [--rate R] [--binary PATH]
(python-can in .venv and Debian's mosquitto come from scripts/setup-test-deps.sh; builds buslab
with --release first unless --binary is given; takes about two minutes)

python-can (socketcand interface) sends N frames of 8 bytes on bus A, each carrying its number
and the sender's monotonic clock (µs); another python-can process receives on bus B (on bus A
itself for the socketcand row). "saturated" sends as fast as bus A takes frames (it pushes
back); "paced" sends R frames/s so latency is not queueing. frames/s is what the receiver got
per second from its first frame to its last; loss is what never came (the receiver stops 5 s
after the last frame); latency is from the send call to the receive call, through bus A,
the transport, and bus B. The buses run at 1 Mbit/s in real time (at most about 7.7 k frames/s
of 8 bytes), and `10x` rows run them ten times faster than real time, so that the transport and
python-can, not the simulated wire, set the rate.
"""

import argparse
import multiprocessing as mp
import os
import socket
import subprocess
import sys
import tempfile
import time

import can

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MOSQUITTO = "/usr/sbin/mosquitto"


def now_us():
    return time.monotonic_ns() // 1000


def percentile(values, p):
    if not values:
        return float("nan")
    values = sorted(values)
    return values[min(len(values) - 1, int(round(p / 100 * (len(values) - 1))))]


def free_port(kind=socket.SOCK_STREAM):
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def connect(port):
    return can.Bus(interface="socketcand", host="127.0.0.1", port=port, channel="vcan0")


def receiver(port, count, ready, results):
    bus = connect(port)
    ready.set()
    got, latencies, first, last = 0, [], None, None
    while got < count:
        msg = bus.recv(timeout=5)
        if msg is None:
            break
        t = now_us()
        first = first or t
        last = t
        sent = int.from_bytes(msg.data[4:8], "little")
        latencies.append(((t & 0xFFFFFFFF) - sent) % (1 << 32) / 1000)
        got += 1
    bus.shutdown()
    results.put((got, latencies, (last - first) / 1e6 if got > 1 else float("nan")))


def sender(port, count, rate):
    bus = connect(port)
    start = time.monotonic()
    for k in range(count):
        if rate:
            wait = start + k / rate - time.monotonic()
            if wait > 0:
                time.sleep(wait)
        data = k.to_bytes(4, "little") + (now_us() & 0xFFFFFFFF).to_bytes(4, "little")
        bus.send(can.Message(arbitration_id=0x123, data=data, is_extended_id=False))
    bus.shutdown()


def serve(binary, speed, join=None):
    cmd = [binary, "bus", "serve", "--listen", "127.0.0.1:0", "--bitrate", "1000000",
           "--speed", str(speed), "--client-queue", "1048576"]
    if join:
        cmd += ["--join", join]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = p.stdout.readline().strip()
    return p, int(line.rsplit(":", 1)[1].split("/")[0])


def measure(tx_port, rx_port, frames, rate):
    results = mp.Queue()
    ready = mp.Event()
    rx = mp.Process(target=receiver, args=(rx_port, frames, ready, results))
    rx.start()
    ready.wait()
    time.sleep(0.2)  # the receiver's connection is set up on the server side
    sender(tx_port, frames, rate)
    got, latencies, elapsed = results.get()
    rx.join()
    return {
        "frames_s": got / elapsed if elapsed == elapsed and elapsed > 0 else float("nan"),
        "loss": 100 * (frames - got) / frames,
        "p50": percentile(latencies, 50),
        "p99": percentile(latencies, 99),
    }


def run_transport(binary, transport, speed, frames, rate, broker_port):
    procs = []
    try:
        if transport == "socketcand":
            a, pa = serve(binary, speed)
            procs = [a]
            return measure(pa, pa, frames, rate)
        if transport == "mqtt":
            prefix = "bench/%d" % os.getpid() + "/%d" % time.monotonic_ns()
            url = "mqtt://127.0.0.1:%d/%s" % (broker_port, prefix)
            ja = jb = url
        elif transport == "cannelloni udp":
            ua, ub = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
            ja = "cannelloni://127.0.0.1:%d?listen=127.0.0.1:%d" % (ub, ua)
            jb = "cannelloni://127.0.0.1:%d?listen=127.0.0.1:%d" % (ua, ub)
        else:
            t = free_port()
            ja = "cannelloni+tcp://127.0.0.1:%d?role=server" % t
            jb = "cannelloni+tcp://127.0.0.1:%d" % t
        a, pa = serve(binary, speed, ja)
        procs.append(a)
        b, pb = serve(binary, speed, jb)
        procs.append(b)
        return measure(pa, pb, frames, rate)
    finally:
        for p in procs:
            p.terminate()
            p.wait()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--rate", type=int, default=2000)
    ap.add_argument("--binary")
    args = ap.parse_args()
    binary = args.binary
    if not binary:
        subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "buslab"], cwd=ROOT,
                       check=True)
        target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
        binary = os.path.join(target, "release", "buslab")
    conf_dir = tempfile.TemporaryDirectory()
    broker_port = free_port()
    conf = os.path.join(conf_dir.name, "mosquitto.conf")
    with open(conf, "w") as f:
        f.write("listener %d 127.0.0.1\nallow_anonymous true\npersistence false\n" % broker_port)
    broker = subprocess.Popen([MOSQUITTO, "-c", conf], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    while socket.socket().connect_ex(("127.0.0.1", broker_port)) != 0:
        time.sleep(0.05)
    rows = []
    try:
        for transport in ["socketcand", "mqtt", "cannelloni udp", "cannelloni tcp"]:
            for label, speed, rate, frames in [
                ("saturated", 1, 0, args.frames),
                ("saturated, 10x", 10, 0, args.frames),
                ("paced %d/s" % args.rate, 1, args.rate, args.frames // 4),
            ]:
                r = run_transport(binary, transport, speed, frames, rate, broker_port)
                rows.append((transport, label, r))
                print("%s, %s: %s" % (transport, label, r), file=sys.stderr)
    finally:
        broker.terminate()
        broker.wait()
    print("%d frames of 8 bytes (paced: %d), python-can sender and receiver, loopback"
          % (args.frames, args.frames // 4))
    print()
    print("| path | run | frames/s | loss | latency p50 | latency p99 |")
    print("|---|---|---|---|---|---|")
    for transport, label, r in rows:
        path = ("one bus, socketcand only" if transport == "socketcand"
                else "bus A -> %s -> bus B" % transport)
        print("| %s | %s | %.0f | %.2f %% | %.2f ms | %.2f ms |"
              % (path, label, r["frames_s"], r["loss"], r["p50"], r["p99"]))


if __name__ == "__main__":
    main()
