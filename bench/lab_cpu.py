#!/usr/bin/env python3
"""CPU of `buslab lab` (the whole bench: its bus with the simulated nodes, three SLIO demo
boards and the PowerPC node running MoniCAN at 125 kbit/s, the ZELLE cell and the CPU196
board), with its own traffic only ("quiet": about 17 % bus load) and with a client saturating
the bus (`buslab gen -g 0s`, 100 % load).

Usage: python3 bench/lab_cpu.py [--seconds 10] [BUSLAB]
       (default BUSLAB: target/release/buslab, built with `cargo build --release -p buslab`)

CPU time of the lab process (utime + stime from /proc) over the wall time, in per cent of one
core; the saturating client's own CPU is not counted. The machine is shared: compare rows of
the same run.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def measure(pid, seconds):
    c0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    c1, t1 = cpu_seconds(pid), time.monotonic()
    return 100.0 * (c1 - c0) / (t1 - t0)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("buslab", nargs="?", default=os.path.join(ROOT, "target/release/buslab"))
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        lab = subprocess.Popen(
            [args.buslab, "lab", "-q", "--listen", "127.0.0.1:0", "--dir", d],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        url = None
        for line in lab.stderr:
            if "socketcand://" in line:
                url = line.split("socketcand://", 1)[1].split()[0].rstrip(",")
                url = "socketcand://" + url
                break
        subprocess.Popen(["cat"], stdin=lab.stderr, stdout=subprocess.DEVNULL)
        time.sleep(2)  # start-up: calibration, sign-ons
        quiet = measure(lab.pid, args.seconds)
        gen = subprocess.Popen(
            [args.buslab, "gen", "--bus", url, "-g", "0s", "-n", "100000000", "-L", "8"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        time.sleep(1)
        saturated = measure(lab.pid, args.seconds)
        gen.terminate()
        gen.wait()
        lab.terminate()
        lab.wait()
    print()
    print(f"buslab lab at 125 kbit/s (3 SLIO boards, PowerPC node, ZELLE, CPU196), {args.seconds:.0f} s each")
    print(f"{'bus':<32} {'lab CPU':>10} {'budget':>8}")
    print(f"{'quiet (its own traffic, ~17 %)':<32} {quiet:>8.1f} % {'< 15 %':>8}")
    print(f"{'saturated (gen -g 0s)':<32} {saturated:>8.1f} % {'< 40 %':>8}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
