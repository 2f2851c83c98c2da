#!/usr/bin/env python3
"""How fast `buslab bus serve` delivers frames when the bus runs as fast as the CPU allows, with
its client nodes (SJA1000 chips operated by buslab's driver) on the simulator's frame-level
fast path; and python-can's udp_multicast measured the same way in the same run, as the peer.

Usage: .venv/bin/python bench/vbus_speed.py [--frames N] [--receivers 8] [--repeat 3] [--before BINARY]
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
the send call to the receive call. `--before BINARY` adds the rows for another buslab binary
(e.g. one built before the SJA1000 nodes took whole frames).
"""

import argparse
import os
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
        "in_order": in_order,
        # The receivers' own percentiles: the worst receiver's.
        "p50": max(lats_p50) / 1000,
        "p99": max(lats_p99) / 1000,
        "sender": sender.stdout.strip(),
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=50_000)
    ap.add_argument("--receivers", type=int, default=8)
    ap.add_argument("--bitrate", type=int, default=1_000_000)
    ap.add_argument("--before", help="another buslab binary to measure the same way")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per row, in rounds (the median run is shown)")
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
        """One measurement on a fresh bus serve."""
        server, (host, port) = cbs.start_server(bin_, args.bitrate, MAX_SPEED)
        try:
            return measure(host, port)
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

    # Rows in turn, `--repeat` rounds: each row's runs see the same changes of load.
    runs = {label: [] for label, _, _ in measures}
    for _ in range(args.repeat):
        for label, _, measure in measures:
            runs[label].append(measure())

    print(f"1 sender, {args.receivers} receivers, 8-byte frames; {args.bitrate} bit/s bus; "
          f"Rust rows {n} frames, python rows {n // 4}; {args.repeat} runs per row, the median "
          f"run shown; load average {open('/proc/loadavg').read().split()[0]}")
    print()
    print("| transport | frames/s (slowest receiver), median run | all runs | loss (worst run) "
          "| in order | latency p50 | latency p99 |")
    print("|---|---|---|---|---|---|---|")
    for label, ordered, _ in measures:
        rs = sorted(runs[label], key=lambda r: r["frames_s"])
        r = rs[len(rs) // 2]
        worst_loss = max(x["loss"] for x in rs)
        every = " / ".join(f"{x['frames_s']:.0f}" for x in runs[label])
        order = "-" if ordered is None else ("yes" if all(x["in_order"] for x in rs) else "NO")
        print(f"| {label} | {r['frames_s']:.0f} | {every} | {worst_loss:.2f} % | {order} | "
              f"{r['p50']:.2f} ms | {r['p99']:.2f} ms |")

if __name__ == "__main__":
    main()
