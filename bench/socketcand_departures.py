#!/usr/bin/env python3
"""Frames a python-can client hands to `buslab bus serve` just before it leaves: how many a
receiver on the bus sees (issue 25). python-can 4.6.1's socketcand interface, run as users run
it, each script its own process, back to back:

- with:     `with can.Bus(interface="socketcand", …) as bus: bus.send(msg)`, RUNS times (one
            frame each, a new process each time);
- shutdown: one process sends FRAMES frames, then `bus.shutdown()`;
- player:   `python -m can.player` on a small candump log (PLAYER frames).

The receiver is `buslab dump -L` on the same bus (a process nobody here changed for this);
each row counts the frames it printed. Optional busy loops (`--busy N`, `yes > /dev/null`)
load the machine as the issue's measurements did. Prints a table:

    row       frames sent   frames seen   lost
    with              100           100      0

Usage: python3 bench/socketcand_departures.py [--buslab BIN] [--python PY] [--runs 100]
       [--frames 200] [--busy 2]
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

WITH = """
import sys, can
host, port, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
with can.Bus(interface="socketcand", host=host, port=port, channel="vcan0") as bus:
    bus.send(can.Message(arbitration_id=0x100 + n % 0x600, data=n.to_bytes(4, "big"),
                         is_extended_id=False))
"""

SHUTDOWN = """
import sys, can
host, port, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
bus = can.Bus(interface="socketcand", host=host, port=port, channel="vcan0")
for n in range(count):
    bus.send(can.Message(arbitration_id=0x200, data=n.to_bytes(4, "big"), is_extended_id=False))
bus.shutdown()
"""


class Receiver:
    """`buslab dump -L` on the bus: counts the frame lines it prints."""

    def __init__(self, buslab, url):
        self.out = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen(
            [buslab, "dump", "-L", "--bus", url], stdout=self.out, stderr=subprocess.DEVNULL
        )

    def seen(self):
        self.out.flush()
        self.out.seek(0)
        return sum(1 for line in self.out if "#" in line)

    def wait_for(self, want, patience):
        """Frames seen once `want` came or nothing more came for `patience` seconds."""
        last, since = -1, time.monotonic()
        while True:
            n = self.seen()
            if n >= want:
                return n
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > patience:
                return n
            time.sleep(0.05)

    def stop(self):
        self.proc.terminate()
        self.proc.wait()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--buslab", default=os.path.join(ROOT, "target/debug/buslab"))
    ap.add_argument("--python", default=os.path.join(ROOT, ".venv/bin/python"))
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--player", type=int, default=20)
    ap.add_argument("--busy", type=int, default=2, help="busy loops (yes > /dev/null)")
    args = ap.parse_args()

    busy = [
        subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(args.busy)
    ]
    server = subprocess.Popen(
        [args.buslab, "bus", "serve", "--listen", "127.0.0.1:0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = server.stdout.readline().strip()
    host, port = url.split("//", 1)[1].split("/", 1)[0].rsplit(":", 1)
    rows = []
    try:
        # with: one frame per process, back to back.
        rx = Receiver(args.buslab, url)
        time.sleep(1)
        for n in range(args.runs):
            subprocess.run([args.python, "-c", WITH, host, port, str(n)], check=True)
        rows.append(("with", args.runs, rx.wait_for(args.runs, 5)))
        rx.stop()

        rx = Receiver(args.buslab, url)
        time.sleep(1)
        subprocess.run([args.python, "-c", SHUTDOWN, host, port, str(args.frames)], check=True)
        rows.append(("shutdown", args.frames, rx.wait_for(args.frames, 5)))
        rx.stop()

        with tempfile.NamedTemporaryFile("w", suffix=".log") as log:
            for n in range(args.player):
                log.write(f"({1700000000 + n * 0.001:.6f}) vcan0 300#{n:08X}\n")
            log.flush()
            rx = Receiver(args.buslab, url)
            time.sleep(1)
            subprocess.run(
                [args.python, "-m", "can.player", "-i", "socketcand", "-c", "vcan0",
                 "--bus-kwargs", f"host={host}", f"port={port}", "--", log.name],
                check=True,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            rows.append(("player", args.player, rx.wait_for(args.player, 5)))
            rx.stop()
    finally:
        server.terminate()
        server.wait()
        for p in busy:
            p.kill()
            p.wait()
    left = [l for l in server.stderr.read().splitlines() if " left: " in l]
    print(f"load: {os.getloadavg()[0]:.1f} (1-min average), {args.busy} busy loops")
    print(f"{'row':<10}{'frames sent':>12}{'frames seen':>13}{'lost':>7}")
    for name, sent, seen in rows:
        print(f"{name:<10}{sent:>12}{seen:>13}{sent - seen:>7}")
    print(f"server: {len(left)} nodes left; the last lines:")
    for line in left[-3:]:
        print("  " + line.split("  ")[-1].strip())
    return 0 if all(sent == seen for _, sent, seen in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
