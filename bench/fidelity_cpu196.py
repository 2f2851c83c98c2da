#!/usr/bin/env python3
"""Issue 11, fidelity 2, as an outside host sees it: a CPU196 PIC block write (F6 02) against
`buslab cpu196 serve`, sent the way seed 000 implies ("msg_completed tous les 256 octets (16
fois)"): the 4 header bytes and 256 data bytes, then wait for an acknowledgement before the
next 256. Prints what arrives after each 256 bytes and how long it took.

Usage: python3 bench/fidelity_cpu196.py [BUSLAB]   (default: target/debug/buslab)
"""

import os
import subprocess
import sys
import tempfile
import termios
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def raw(fd):
    attrs = termios.tcgetattr(fd)
    attrs[0] = attrs[1] = attrs[3] = 0
    attrs[2] = termios.CS8 | termios.CREAD | termios.CLOCAL
    attrs[4] = attrs[5] = termios.B115200
    attrs[6][termios.VMIN] = 0
    attrs[6][termios.VTIME] = 0
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def read_for(fd, want, timeout):
    got = b""
    deadline = time.monotonic() + timeout
    while len(got) < want and time.monotonic() < deadline:
        try:
            got += os.read(fd, want - len(got))
        except BlockingIOError:
            time.sleep(0.001)
    return got


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target/debug/buslab")
    with tempfile.TemporaryDirectory() as d:
        serve = subprocess.Popen(
            [binary, "-q", "cpu196", "serve", "--baud", "115200", "--image",
             os.path.join(d, "image.toml")],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        pty = serve.stdout.readline().strip()
        fd = os.open(pty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        raw(fd)
        # Whatever the board says at power-on (its start-up message) is not an answer.
        hello = read_for(fd, 256, 0.5)
        print(f"at power-on: {hello.hex(' ') or 'nothing'}")
        data = bytes((i * 7) & 0xFF for i in range(4096))
        os.write(fd, bytes([0xF6, 0x09, 0x02, 0x03]))
        acks = []
        for i in range(16):
            sent = time.monotonic()
            os.write(fd, data[i * 256:(i + 1) * 256])
            # 256 bytes take 22 ms at 115200 8N1; one second is the host's patience.
            got = read_for(fd, 3, 1.0)
            acks.append((got.hex(" "), (time.monotonic() - sent) * 1000))
        extra = read_for(fd, 64, 0.5)
        for i, (ack, ms) in enumerate(acks):
            print(f"256 bytes #{i + 1:2}: reply {ack or 'nothing'} after {ms:.0f} ms")
        print(f"afterwards within 0.5 s: {extra.hex(' ') or 'nothing'}")
        os.close(fd)
        serve.terminate()
        serve.wait()


if __name__ == "__main__":
    main()
