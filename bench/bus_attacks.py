#!/usr/bin/env python3
"""The bus server's attacks of issue 11, against a real `buslab bus serve` process, with the
numbers docs/reliability.md quotes.

Usage: python3 bench/bus_attacks.py [BUSLAB]   (default: target/release/buslab)

Rows:
- amplification: 1 MiB of `>` then `< echo >` on one connection: bytes of replies before the
  echo, and the server's CPU time (/proc/PID/task/*/schedstat) and wall time for it;
- idle connections: a server with `--client-queue 1048576`, 256 connections that read the
  greeting and never open the bus; the server's resident memory before and after, then two
  real clients open the bus and one frame goes from one to the other;
- zombie: a client process with the wrong bit timing (`< buslab_btr 07 4D >`) queues 4 MB of
  sends and is killed with SIGKILL once it has disturbed the bus; how long its node stays in
  `< buslab_nodes >` after the kill, and whether a client joining then receives anything.

Plain sockets, no python-can. Each row starts its own server.
"""

import os
import signal
import socket
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cpu_seconds(pid):
    """CPU time of every thread of the process, in seconds (schedstat: nanoseconds)."""
    total = 0
    for tid in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{tid}/schedstat") as f:
            total += int(f.read().split()[0])
    return total / 1e9


def rss_mib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")


class Server:
    def __init__(self, binary, *args):
        self.proc = subprocess.Popen(
            [binary, "-q", "bus", "serve", "--listen", "127.0.0.1:0", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        url = self.proc.stdout.readline().strip()
        host, port = url.split("//", 1)[1].split("/", 1)[0].rsplit(":", 1)
        self.addr = (host, int(port))

    def stop(self):
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait()


class Conn:
    def __init__(self, addr):
        self.s = socket.create_connection(addr)
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""

    def expect(self, text, timeout=60):
        self.s.settimeout(timeout)
        while text not in self.buf:
            chunk = self.s.recv(65536)
            if not chunk:
                raise RuntimeError(f"server closed before {text!r}: {self.buf[-200:]!r}")
            self.buf += chunk
        got, self.buf = self.buf.split(text, 1)
        return got + text

    def request(self, text, answer):
        self.s.sendall(text)
        return self.expect(answer)

    def open(self, name=None):
        self.expect(b"< hi >")
        self.request(b"< open vcan0 >< rawmode >", b"< ok >< ok >")
        if name:
            self.request(f"< buslab_name {name} >".encode(), b"< ok >")
        return self


def amplification(binary):
    server = Server(binary)
    c = Conn(server.addr)
    c.expect(b"< hi >")
    cpu_before = cpu_seconds(server.proc.pid)
    started = time.monotonic()
    import threading

    writer = threading.Thread(target=lambda: c.s.sendall(b">" * (1 << 20) + b"< echo >"))
    writer.start()
    replies = c.expect(b"< echo >")
    wall = time.monotonic() - started
    writer.join()
    cpu = cpu_seconds(server.proc.pid) - cpu_before
    server.stop()
    errors = replies.count(b"< error")
    print(
        f"amplification: 1 MiB of '>': {len(replies)} bytes of replies ({errors} error), "
        f"server CPU {cpu * 1000:.0f} ms, echo after {wall * 1000:.0f} ms"
    )


def idle_connections(binary):
    server = Server(binary, "--client-queue", "1048576")
    pid = server.proc.pid
    before = rss_mib(pid)
    idle = []
    for _ in range(256):
        c = Conn(server.addr)
        c.expect(b"< hi >")
        idle.append(c)
    after = rss_mib(pid)
    started = time.monotonic()
    a = Conn(server.addr).open()
    b = Conn(server.addr).open()
    a.s.sendall(b"< send 123 1 42 >")
    b.expect(b"< frame 123 ")
    b.expect(b" 42 >")
    took = time.monotonic() - started
    server.stop()
    print(
        f"idle connections: 256 bare connections with --client-queue 1048576: server RSS "
        f"{before:.1f} -> {after:.1f} MiB; then two real clients opened the bus and passed a "
        f"frame in {took * 1000:.0f} ms"
    )


ZOMBIE = r"""
import socket, sys, time
s = socket.create_connection((sys.argv[1], int(sys.argv[2])))
s.sendall(b"< open vcan0 >< rawmode >< buslab_name zombie >< buslab_btr 07 4D >< buslab_errors 1 >")
buf = b""
while buf.count(b"< ok >") < 5:
    buf += s.recv(4096)
s.setblocking(False)
sends = b"< send 123 8 01 02 03 04 05 06 07 08 >" * (4 * 1024 * 1024 // 38)
written = 0
while written < len(sends):
    try:
        written += s.send(sends[written:])
    except BlockingIOError:
        break
print(written, flush=True)
time.sleep(3600)
"""


def zombie(binary):
    server = Server(binary)
    watcher = Conn(server.addr).open("watcher")
    proc = subprocess.Popen(
        [sys.executable, "-c", ZOMBIE, server.addr[0], str(server.addr[1])],
        stdout=subprocess.PIPE,
        text=True,
    )
    written = int(proc.stdout.readline())
    # It is on the bus and failing.
    while True:
        status = watcher.request(b"< buslab_status zombie >", b">")
        errors = int(status.split(b"bus_errors=", 1)[1].split()[0])
        if errors > 0:
            break
        time.sleep(0.01)
    proc.kill()
    killed = time.monotonic()
    proc.wait()
    polls = 0
    while b":zombie" in watcher.request(b"< buslab_nodes >", b">"):
        polls += 1
        time.sleep(0.001)
    gone = time.monotonic() - killed
    late = Conn(server.addr).open("late")
    late.s.settimeout(0.5)
    try:
        stale = late.s.recv(65536)
    except socket.timeout:
        stale = b""
    server.stop()
    print(
        f"zombie: {written} bytes of sends queued, {errors} bus errors, SIGKILL; its node left "
        f"the bus {gone * 1000:.0f} ms after the kill; a client joining then got "
        f"{len(stale)} bytes in 0.5 s"
    )


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target/release/buslab")
    amplification(binary)
    idle_connections(binary)
    zombie(binary)


if __name__ == "__main__":
    main()
