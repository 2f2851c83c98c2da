#!/usr/bin/env python3
"""The ZELLE fidelity points of issue 11 against a served cell, as a pyserial-less outside
client would see them: raw bytes on the PTY at 9600 8N2.

Usage: python3 bench/fidelity_zelle.py [BUSLAB]   (default: target/debug/buslab)

- command 4 sent back to back with its data (seed 003: every command but 1, 2, 3 and 5 may be
  sent at full line speed): `4,1,2,3,4,0`, then `4,1,2,3,0,13`, with channels 1..4 at
  1, 2, 3, 4 V: the replies, byte by byte;
- command 16 on the special function registers, with P1.4/P1.5 pulled low and the START key
  down (control lines `p1 pull 0x30`, `key down`): `buslab zelle reg` for P1, P3, SP, DPL, DPH,
  PSW, ACC, B.
"""

import os
import subprocess
import sys
import tempfile
import termios
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def raw_9600_8n2(fd):
    attrs = termios.tcgetattr(fd)
    attrs[0] = 0  # iflag
    attrs[1] = 0  # oflag
    attrs[2] = termios.CS8 | termios.CSTOPB | termios.CREAD | termios.CLOCAL
    attrs[3] = 0  # lflag
    attrs[4] = attrs[5] = termios.B9600
    attrs[6][termios.VMIN] = 0
    attrs[6][termios.VTIME] = 0
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def exchange(fd, data, wait):
    os.write(fd, bytes(data))
    deadline = time.monotonic() + wait
    got = b""
    while time.monotonic() < deadline:
        try:
            chunk = os.read(fd, 64)
        except BlockingIOError:
            chunk = b""
        got += chunk
        time.sleep(0.005)
    return list(got)


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target/debug/buslab")
    with tempfile.TemporaryDirectory() as d:
        serve = subprocess.Popen(
            [binary, "-q", "zelle", "serve", "--state", os.path.join(d, "state.toml")],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        pty = serve.stdout.readline().strip()
        for ch in range(1, 5):
            serve.stdin.write(f"analog {ch} const:{ch}\n")
            serve.stdin.flush()
            print(serve.stdout.readline().strip())
        fd = os.open(pty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        raw_9600_8n2(fd)
        # Ready state: ten zeros, 2 ms apart (the seed's reset).
        for _ in range(10):
            os.write(fd, b"\0")
            time.sleep(0.002)
        exchange(fd, [], 0.1)
        for data in ([4, 1, 2, 3, 4, 0], [4, 1, 2, 3, 0, 13]):
            got = exchange(fd, data, 0.3)
            print(f"sent {data} back to back: replies {got}")
        os.close(fd)
        # Port 1 pins pulled low from outside (bits 4, 5), the START key held down (INT1, P3.3).
        for line in ("p1 pull 0x30", "key down"):
            serve.stdin.write(line + "\n")
            serve.stdin.flush()
            print(serve.stdout.readline().strip())
        names = [
            ("P1", 0x90),
            ("P3", 0xB0),
            ("SP", 0x81),
            ("DPL", 0x82),
            ("DPH", 0x83),
            ("PSW", 0xD0),
            ("ACC", 0xE0),
            ("B", 0xF0),
        ]
        for name, addr in names:
            out = subprocess.run(
                [binary, "zelle", "-p", pty, "reg", str(addr)],
                capture_output=True,
                text=True,
            )
            print(f"buslab zelle -p PTY reg {addr} ({name}): {(out.stdout + out.stderr).strip()}")
        serve.stdin.close()
        serve.terminate()
        serve.wait()


if __name__ == "__main__":
    main()
