#!/usr/bin/env python3
"""`buslab cpu196 monitor` on a line that carries nothing but noise (issue 11, reliability 6):
random bytes at about 11.5 kB/s (115200 8N1) for --seconds; the monitor's resident memory
sampled every 2 s. Before the fix it grew about 1.1 MB/s (every frame error kept as text).

Usage: python3 bench/cpu196_noise.py [BUSLAB] [SECONDS]   (default: target/debug/buslab, 20)
"""

import os
import pty
import subprocess
import sys
import time
import tty

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def rss_kib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target/debug/buslab")
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 20.0
    master, slave = pty.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    monitor = subprocess.Popen(
        [binary, "cpu196", "-p", path, "monitor", "--duration", f"{int(seconds) + 5}s"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(1)
    start = time.monotonic()
    sent = 0
    samples = []
    next_sample = 0.0
    while time.monotonic() - start < seconds and monitor.poll() is None:
        os.write(master, os.urandom(1152))  # 0.1 s of a 115200-baud line
        sent += 1152
        time.sleep(0.1)
        # Whatever the monitor writes (watchdogs) is read and dropped.
        try:
            os.set_blocking(master, False)
            os.read(master, 65536)
        except BlockingIOError:
            pass
        elapsed = time.monotonic() - start
        if elapsed >= next_sample:
            samples.append((elapsed, rss_kib(monitor.pid)))
            next_sample += 2.0
    alive = monitor.poll() is None
    # SIGTERM stops it as Ctrl-C does: it tells how many damaged frames it skipped.
    monitor.terminate()
    _, err = monitor.communicate()
    first, last = samples[0], samples[-1]
    rate = (last[1] - first[1]) / max(last[0] - first[0], 1e-9)
    print(
        f"cpu196 monitor, {sent} bytes of noise over {last[0]:.0f} s: RSS "
        + " ".join(f"{kib / 1024:.1f}" for _, kib in samples)
        + f" MiB (every 2 s), growth {rate:.1f} KiB/s after the first sample; "
        + ("still running" if alive else "had stopped")
    )
    print("monitor's last words: " + err.strip().splitlines()[-1] if err.strip() else "(nothing)")


if __name__ == "__main__":
    main()
