#!/usr/bin/env python3
"""A receiver slower than the bus at `--speed max`: does it lose frames?

Usage: .venv/bin/python bench/vbus_slow_reader.py [--frames 20000] [--queues 64,8192]
                                                  [--before BINARY]
(builds buslab with --release first; standard library only)

`buslab bus serve --speed max --client-queue Q`; one raw socketcand receiver that reads 2 KiB
every 5 ms (about 400 kB/s, some 9 000 frames a second: far slower than the bus at `max`),
and one sender that writes all its frames at once. The receiver reads, so by docs/bus.md it
must get every frame: the table shows what it got, what the server counted as dropped for
it, and how long it took. `--before BINARY` adds the same rows for another buslab binary.
"""

import argparse
import os
import socket
import subprocess
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IDLE_TIMEOUT = 12.0


def start(binary, queue):
    p = subprocess.Popen(
        [binary, "bus", "serve", "--listen", "127.0.0.1:0", "--speed", "max",
         "--client-queue", str(queue)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = p.stdout.readline().strip()
    host, port = url[len("socketcand://"):].split("/")[0].rsplit(":", 1)
    return p, (host, int(port))


def connect(addr):
    s = socket.create_connection(addr)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    buf = b""
    for send, want in [(None, b"< hi >"), (b"< open vcan0 >", b"< ok >"),
                       (b"< rawmode >", b"< ok >")]:
        if send:
            s.sendall(send)
        while want not in buf:
            buf += s.recv(4096)
        buf = buf[buf.index(want) + len(want):]
    return s


def run(binary, queue, frames):
    server, addr = start(binary, queue)
    try:
        rx = connect(addr)
        tx = connect(addr)
        data = b"".join(b"< send 123 4 %02X %02X %02X %02X >" % tuple(i.to_bytes(4, "little"))
                        for i in range(frames))
        start_t = time.monotonic()
        threading.Thread(target=tx.sendall, args=(data,), daemon=True).start()
        rx.settimeout(IDLE_TIMEOUT)
        got, tail = 0, b""
        try:
            while got < frames:
                time.sleep(0.005)
                chunk = rx.recv(2048)
                if not chunk:
                    break
                *complete, tail = (tail + chunk).split(b">")
                got += sum(e.lstrip().startswith(b"< frame ") for e in complete)
        except socket.timeout:
            pass
        elapsed = time.monotonic() - start_t
    finally:
        server.terminate()
        _, err = server.communicate(timeout=30)
    lost = 0
    for line in err.splitlines():
        # "node 1 (node1) left: sent 0, received N, lost L"
        if "(node1) left:" in line:
            lost = int(line.rsplit("lost", 1)[1])
    return got, lost, elapsed


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--queues", default="64,8192")
    ap.add_argument("--before", help="another buslab binary to measure the same way")
    args = ap.parse_args()
    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "buslab", "--bin", "buslab"],
                   cwd=ROOT, check=True)
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    binaries = [("bus serve", os.path.join(target, "release", "buslab"))]
    if args.before:
        binaries.append(("bus serve (BEFORE)", args.before))
    print(f"1 sender writing {args.frames} frames at once, 1 receiver reading 2 KiB every 5 ms; "
          f"--speed max; a receiver idle for {IDLE_TIMEOUT:.0f} s stops")
    print()
    print("| binary | --client-queue | frames received | dropped (server's count) | seconds |")
    print("|---|---|---|---|---|")
    for queue in [int(q) for q in args.queues.split(",")]:
        for label, binary in binaries:
            got, lost, elapsed = run(binary, queue, args.frames)
            print(f"| {label} | {queue} | {got} of {args.frames} | {lost} | {elapsed:.2f} |",
                  flush=True)


if __name__ == "__main__":
    main()
