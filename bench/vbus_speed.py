#!/usr/bin/env python3
"""How fast `buslab bus serve` delivers frames when the bus runs as fast as the CPU allows, with
its client nodes (SJA1000 chips operated by buslab's driver) on the simulator's frame-level
fast path; and python-can's udp_multicast measured the same way in the same run, as the peer.

Usage: .venv/bin/python bench/vbus_speed.py [--frames N] [--receivers 8] [--repeat 3] [--before BINARY]
       [--only max|latency] [--latency-frames 400] [--busy-loops N] [--callgrind [--marginal]]
(python-can and msgpack in .venv come from scripts/setup-test-deps.sh; without them the
udp_multicast row is left out. Builds buslab and the Rust client with --release first.)

1 sender and 8 receivers, 8-byte frames carrying a sequence number and the sender's monotonic
clock (µs). "Rust client" rows use buslab's own client library (`buslab_backends::open`, the
example `crates/vbus/examples/vbus_speed_client.rs`), one process per node; "python" rows use
bench/can_bus_serve.py's raw socketcand client (bus serve), python-can's socketcand interface
(bus serve, python-can receivers) or python-can (udp_multicast).
`--speed max` runs the bus as fast as the CPU allows (no pacing to the wall clock; frame
times are virtual). frames/s is what the
slowest receiver got per second from the first frame sent to its last frame; loss counts
frames any receiver missed (every receiver must get every frame, in order); latency is from
the send call to the receive call; CPU per delivered frame is the server's CPU time (all its
threads, /proc/PID/task/*/schedstat in ns; /proc/PID/stat's utime + stime count 10 ms ticks)
over the run divided by the frames it delivered (to all receivers).
`--before BINARY` adds the rows for another buslab binary (e.g. one built from main before a
change), measured the same way in the same run.

The second table is the latency of isolated frames at real time (`--latency-bitrates`,
500 kbit/s and 1 Mbit/s by default): a raw socketcand client sends `123#` (45 bits on the wire
with its stuff bit), another one waits for it, one frame every 2 ms; p50 and p99 from the send
call to the receive call, from the frame's timestamp (the Unix time of its end on the wire)
to the receive call (how late after its end it arrives: what the loop's wake-up adds, with
the receiver's own), and the server's CPU time per frame (/proc/PID/task/*/schedstat:
nanoseconds). The floor beside it is a plain TCP relay (a Python process that reads the
sender's bytes and writes a frame line to the receiver) plus the frame's wire time: what
any server that delivers a frame at its end on the wire can reach with these clients.
`--callgrind` adds the instructions the server executes per delivered frame at `max`
(valgrind's callgrind: load-independent; the whole run over the frames delivered, the server's
start and the clients' joining included); with `--marginal` also the same without the start
(a run with twice the frames against the first: the start drops out of the difference) and
what one more receiver costs per frame (a run with 1 receiver against one with
`--receivers`: the same frames and start, so the difference is the receivers' alone), and
`--busy-loops N` runs everything with N shell
busy loops beside (`while :; do :; done`), killed after.
"""

import argparse
import multiprocessing as mp
import os
import socket
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import can_bus_serve as cbs  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAX_SPEED = "max"


def rust_run(client, url, frames, receivers):
    """1 Rust sender, `receivers` Rust receivers on bus serve at `url`."""
    procs = []
    for _ in range(receivers):
        # A receiver stops after 10 s without a frame (a loaded host can stall the loop).
        p = subprocess.Popen([client, "recv", url, "10000"], stdout=subprocess.PIPE, text=True)
        procs.append(p)
    for p in procs:
        line = p.stdout.readline().strip()
        if line != "ready":
            raise RuntimeError(f"a receiver did not join: {line!r}")
    time.sleep(0.2)
    start = cbs.now_us()
    sender = subprocess.run([client, "send", url, str(frames)], stdout=subprocess.PIPE,
                            text=True, check=True)
    got, lats_p50, lats_p99, last, in_order = [], [], [], 0, True
    for p in procs:
        out, _ = p.communicate(timeout=600)
        f = out.split()
        fields = dict(zip(f[::2], f[1::2]))
        got.append(int(fields["count"]))
        in_order &= fields["in_order"] == "true"
        last = max(last, int(fields["last_us"]))
        lats_p50.append(int(fields["p50_us"]))
        lats_p99.append(int(fields["p99_us"]))
    # The receivers' idle wait is not part of the delivery time: `last` is their last frame.
    elapsed = (last - start) / 1e6
    expected = frames * receivers
    return {
        "frames_s": min(got) / elapsed if elapsed > 0 else float("nan"),
        "loss": 100.0 * (expected - sum(got)) / expected,
        "min_rx": min(got),
        "delivered": sum(got),
        "in_order": in_order,
        # The receivers' own percentiles: the worst receiver's.
        "p50": max(lats_p50) / 1000,
        "p99": max(lats_p99) / 1000,
        "sender": sender.stdout.strip(),
    }


# ---------------------------------------------------------------- isolated frames, real time

# `123#`: 44 bits from start of frame to the end of its end of frame, and one stuff bit.
WIRE_BITS = 45
ISOLATED_EVERY = 0.002
WARM_UP = 20


def isolated_latency(addr, frames):
    """p50 and p99 (ms) of single `123#` frames from A's send call to B's receive call, and
    the p50 (ms) from the frame's timestamp (the Unix time of its end on the wire) to B's
    receive call: how late after its end the frame arrives."""
    a, b = cbs.Socketcand(*addr), cbs.Socketcand(*addr)
    # Frames wait 50 ms after the rawmode reply (python-can's quirk).
    time.sleep(0.2)
    samples, after_end = [], []
    for i in range(frames + WARM_UP):
        t0 = time.perf_counter_ns()
        a.s.sendall(b"< send 123 0 >")
        # `< frame 123 SECONDS.MICROS >`: its timestamp is the frame's end on the wire.
        element = b.element()
        t1 = time.perf_counter_ns()
        now = time.time()
        if not element.startswith(b"< frame 123 "):
            raise RuntimeError(f"expected the frame back, got {element!r}")
        stamp = float(element.split()[3])
        if i >= WARM_UP:
            samples.append((t1 - t0) / 1e6)
            after_end.append((now - stamp) * 1e3)
        time.sleep(ISOLATED_EVERY)
    a.s.close()
    b.s.close()
    return cbs.percentile(samples, 50), cbs.percentile(samples, 99), cbs.percentile(after_end, 50)


def relay(ports):
    """A plain TCP relay speaking just enough socketcand: the sender's `< send … >` becomes
    one frame line to the receiver, nothing simulated."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(2)
    ports.put(listener.getsockname()[1])

    def joined():
        s, _ = listener.accept()
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        s.sendall(b"< hi >")
        got = b""
        for reply in (b"< ok >", b"< ok >"):
            while got.count(b">") < 1:
                got += s.recv(4096)
            got = got[got.index(b">") + 1:]
            s.sendall(reply)
        return s

    a = joined()
    b = joined()
    while True:
        chunk = a.recv(65536)
        if not chunk:
            return
        for _ in range(chunk.count(b">")):
            b.sendall(b"< frame 123 0.000000 >")


def relay_latency(frames):
    ctx = mp.get_context("fork")
    ports = ctx.Queue()
    p = ctx.Process(target=relay, args=(ports,))
    p.start()
    try:
        return isolated_latency(("127.0.0.1", ports.get(timeout=10)), frames), None
    finally:
        p.join(timeout=5)
        if p.is_alive():
            p.terminate()


def serve_latency(binary, bitrate, frames):
    """Latency and the server's CPU per isolated frame (µs) on a real-time bus serve."""
    server, addr = cbs.start_server(binary, bitrate, 1.0)
    try:
        cpu0 = cbs.cpu_ns(server.pid)
        lat = isolated_latency(addr, frames)
        cpu = (cbs.cpu_ns(server.pid) - cpu0) / (frames + WARM_UP) / 1000
        return lat, cpu
    finally:
        server.terminate()
        server.wait()


# ---------------------------------------------------------------- instructions (callgrind)


def callgrind_marginal(more, fewer):
    """Instructions per delivered frame from two runs (`callgrind_run`) that differ in
    receivers or in frames: the difference over the extra deliveries (what the server's start
    and the clients' joining cost is the same in both and drops out)."""
    extra = more[1] - fewer[1]
    return (more[0] - fewer[0]) / extra if more[0] and fewer[0] and extra > 0 else float("nan")


def callgrind_run(binary, client, frames, receivers, bitrate):
    """The server's instructions over a run at `max` (callgrind), and the frames delivered."""
    out = f"/tmp/vbus_speed.callgrind.{os.getpid()}"
    p = subprocess.Popen(
        ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", binary, "bus", "serve",
         "--listen", "127.0.0.1:0", "--bitrate", str(bitrate), "--speed", MAX_SPEED],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    url = p.stdout.readline().decode().strip()
    host, port = url[len("socketcand://"):].split("/")[0].rsplit(":", 1)
    try:
        r = rust_run(client, f"socketcand://{host}:{port}/vcan0", frames, receivers)
    finally:
        p.terminate()
        p.wait()
    total = None
    with open(out) as f:
        for line in f:
            if line.startswith(("summary:", "totals:")):
                total = int(line.split()[1])
    os.remove(out)
    return total, r["delivered"]


# ---------------------------------------------------------------- main


def busy_loops(n):
    return [subprocess.Popen(["sh", "-c", "while :; do :; done"]) for _ in range(n)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=50_000)
    ap.add_argument("--receivers", type=int, default=8)
    ap.add_argument("--bitrate", type=int, default=1_000_000)
    ap.add_argument("--before", help="another buslab binary to measure the same way")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per row, in rounds (the median run is shown)")
    ap.add_argument("--only", choices=["max", "latency"], help="one table only")
    ap.add_argument("--latency-frames", type=int, default=400)
    ap.add_argument("--latency-bitrates", default="500000,1000000")
    ap.add_argument("--busy-loops", type=int, default=0,
                    help="shell busy loops running beside every measurement")
    ap.add_argument("--callgrind", action="store_true",
                    help="instructions per delivered frame at max (valgrind)")
    ap.add_argument("--marginal", action="store_true",
                    help="with --callgrind: also the instructions per delivered frame without "
                         "the start (twice the frames against the first run) and per receiver "
                         "and frame (a run with 1 receiver against one with --receivers)")
    args = ap.parse_args()
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "buslab", "--bin", "buslab"],
                   cwd=ROOT, check=True)
    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "buslab-vbus", "--example",
                    "vbus_speed_client"], cwd=ROOT, check=True)
    binary = os.path.join(target, "release", "buslab")
    client = os.path.join(target, "release", "examples", "vbus_speed_client")
    n = args.frames

    binaries = [("bus serve", binary)]
    if args.before:
        binaries.append(("bus serve (BEFORE)", args.before))

    def served(bin_, measure):
        """One measurement on a fresh bus serve, with its CPU time."""
        server, (host, port) = cbs.start_server(bin_, args.bitrate, MAX_SPEED)
        try:
            cpu0 = cbs.cpu_ns(server.pid)
            r = measure(host, port)
            r["cpu_s"] = (cbs.cpu_ns(server.pid) - cpu0) / 1e9
            return r
        finally:
            server.terminate()
            server.wait()

    def rust(bin_):
        return served(bin_, lambda host, port: rust_run(
            client, f"socketcand://{host}:{port}/vcan0", n, args.receivers))

    def python_raw(bin_):
        return served(bin_, lambda host, port: cbs.run(
            "serve", n // 4, args.receivers, 0, (host, port)))

    def python_can(bin_):
        return served(bin_, lambda host, port: cbs.run(
            "serve-python-can", n // 4, args.receivers, 0, (host, port)))

    measures = []
    for name, bin_ in binaries:
        measures.append((f"{name} --speed max, Rust client (buslab_backends)", True,
                         lambda b=bin_: rust(b)))
        measures.append((f"{name} --speed max, python raw socketcand client", None,
                         lambda b=bin_: python_raw(b)))
    try:
        import can  # noqa: F401
        import msgpack  # noqa: F401

        measures.append(("bus serve --speed max, python-can receivers (interface socketcand)",
                         None, lambda: python_can(binary)))
        measures.append(("python-can udp_multicast, python-can sender and receivers", None,
                         lambda: cbs.run("multicast", n // 4, args.receivers, 0)))
    except ImportError:
        print("udp_multicast left out: python-can or msgpack is not installed", file=sys.stderr)
    if args.only == "latency":
        measures = []

    bitrates = [int(b) for b in args.latency_bitrates.split(",")]
    latencies = [] if args.only == "max" else [
        (bitrate, label, measure)
        for bitrate in bitrates
        for label, measure in
        [("TCP relay + wire time (floor)", lambda b=bitrate: relay_latency(args.latency_frames))]
        + [(name, lambda b=bitrate, path=path: serve_latency(path, b, args.latency_frames))
           for name, path in binaries]
    ]

    loops = busy_loops(args.busy_loops)
    try:
        load = open('/proc/loadavg').read().split()[0]
        # Rows in turn, `--repeat` rounds: each row's runs see the same changes of load.
        runs = {label: [] for label, _, _ in measures}
        lat_runs = {(b, label): [] for b, label, _ in latencies}
        for _ in range(args.repeat):
            for label, _, measure in measures:
                runs[label].append(measure())
            for b, label, measure in latencies:
                lat_runs[(b, label)].append(measure())
        instructions, marginal, steady = {}, {}, {}
        if args.callgrind and args.only != "latency":
            for name, bin_ in binaries:
                cg_frames = max(n // 20, 1000)
                many = callgrind_run(bin_, client, cg_frames, args.receivers, args.bitrate)
                instructions[name] = many[0] / many[1] if many[0] and many[1] else float("nan")
                if args.marginal:
                    longer = callgrind_run(bin_, client, 2 * cg_frames, args.receivers,
                                           args.bitrate)
                    steady[name] = callgrind_marginal(longer, many)
                if args.marginal and args.receivers > 1:
                    one = callgrind_run(bin_, client, cg_frames, 1, args.bitrate)
                    marginal[name] = callgrind_marginal(many, one)
    finally:
        for p in loops:
            p.kill()
            p.wait()

    beside = f"; {args.busy_loops} busy loops beside" if args.busy_loops else ""
    if measures:
        print(f"1 sender, {args.receivers} receivers, 8-byte frames; {args.bitrate} bit/s bus; "
              f"Rust rows {n} frames, python rows {n // 4}; {args.repeat} runs per row, the "
              f"median run shown; load average {load}{beside}")
        print()
        print("| transport | frames/s (slowest receiver), median run | all runs | loss (worst run) "
              "| in order | latency p50 | latency p99 | server CPU per delivered frame |")
        print("|---|---|---|---|---|---|---|---|")
        for label, ordered, _ in measures:
            rs = sorted(runs[label], key=lambda r: r["frames_s"])
            r = rs[len(rs) // 2]
            worst_loss = max(x["loss"] for x in rs)
            every = " / ".join(f"{x['frames_s']:.0f}" for x in runs[label])
            order = "-" if ordered is None else ("yes" if all(x["in_order"] for x in rs) else "NO")
            cpu = (f"{1e6 * r['cpu_s'] / r['delivered']:.2f} µs"
                   if "cpu_s" in r and r["delivered"] else "-")
            print(f"| {label} | {r['frames_s']:.0f} | {every} | {worst_loss:.2f} % | {order} | "
                  f"{r['p50']:.2f} ms | {r['p99']:.2f} ms | {cpu} |")
        if instructions:
            print()
            for name, per in instructions.items():
                print(f"{name} --speed max, Rust client: {per:.0f} instructions per delivered "
                      f"frame (callgrind, {max(n // 20, 1000)} frames)")
            for name, per in steady.items():
                print(f"{name} --speed max, Rust client: {per:.0f} instructions per delivered "
                      f"frame without the start (callgrind: {2 * max(n // 20, 1000)} frames "
                      f"against {max(n // 20, 1000)})")
            for name, per in marginal.items():
                print(f"{name} --speed max, Rust client: {per:.0f} instructions per receiver "
                      f"and frame (callgrind: {args.receivers} receivers against 1, "
                      f"{max(n // 20, 1000)} frames)")
        print()
    if latencies:
        print(f"Isolated `123#` frames at real time, one every {ISOLATED_EVERY * 1e3:.0f} ms, "
              f"{args.latency_frames} per run; {args.repeat} runs per row, medians of the runs' "
              f"percentiles; load average {load}{beside}")
        print()
        print("| bit rate | path | latency p50 | latency p99 | p50 over the floor | frame end "
              "to receive, p50 | server CPU per frame | all runs' p50 |")
        print("|---|---|---|---|---|---|---|---|")
        for bitrate in bitrates:
            wire = WIRE_BITS / bitrate * 1e3
            floor = None
            for b, label, _ in latencies:
                if b != bitrate:
                    continue
                rs = lat_runs[(b, label)]
                wire_add = wire if floor is None else 0.0
                p50s = sorted(x[0][0] + wire_add for x in rs)
                p99s = sorted(x[0][1] + wire_add for x in rs)
                p50, p99 = p50s[len(p50s) // 2], p99s[len(p99s) // 2]
                if floor is None:
                    floor = p50
                    over = "-"
                else:
                    over = f"{p50 / floor:.2f}x"
                cpus = sorted(x[1] for x in rs if x[1] is not None)
                cpu = f"{cpus[len(cpus) // 2]:.1f} µs" if cpus else "-"
                every = " / ".join(f"{x[0][0] + wire_add:.3f}" for x in rs)
                ends = sorted(x[0][2] for x in rs)
                end = "-" if over == "-" else f"{ends[len(ends) // 2]:.3f} ms"
                print(f"| {bitrate // 1000} kbit/s | {label} | {p50:.3f} ms | {p99:.3f} ms | "
                      f"{over} | {end} | {cpu} | {every} |")
        print()
        print(f"(the floor's wire time: {WIRE_BITS} bits, "
              + ", ".join(f"{WIRE_BITS / b * 1e3:.3f} ms at {b // 1000} kbit/s" for b in bitrates)
              + ")")


if __name__ == "__main__":
    main()
