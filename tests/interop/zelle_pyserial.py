"""Drives a served ZELLE cell with pyserial only, as any serial program would.

Usage: zelle_pyserial.py PTY
Exits 0 and prints "ok" when every check passed; raises otherwise.
"""

import sys
import time

import serial


def main(path):
    # A read returns as soon as its bytes are there; the long time-out only bounds a failure
    # (a loaded machine may be slow to serve the PTY).
    port = serial.Serial(path, 9600, bytesize=8, parity="N", stopbits=2, timeout=30)

    def ask(data, n):
        port.write(bytes(data))
        reply = port.read(n)
        assert len(reply) == n, f"sent {list(data)}, wanted {n} bytes, got {list(reply)}"
        return reply

    # The seed's reset: ten zeros, 2 ms apart.
    for _ in range(10):
        time.sleep(0.002)
        port.write(b"\x00")
        port.flush()
    time.sleep(0.01)
    port.reset_input_buffer()

    # 13: START key not pressed.
    assert ask([13], 1) == b"\x01"
    # 19 / 18: write and read back a RAM byte.
    port.write(bytes([19, 0x12, 0x34, 0x5A]))
    assert ask([18, 0x12, 0x34], 1) == b"\x5a"
    # 7: one analog reading; channel 1 is fed 2.5 V by the test.
    assert ask([7, 1], 1) == bytes([128])
    # 3: write two bytes to 0800h, waiting for each timing byte as the seed describes.
    port.write(bytes([3]))
    port.flush()
    time.sleep(0.001)  # the seed's 1 ms set-up pause, after the command has left
    for value in (0xC0, 0xDE):
        ask([], 1)  # timing byte
        port.write(bytes([1, value]))
    ask([], 1)
    port.write(bytes([0]))
    # 2: read them back, one "1" per byte, "0" ends.
    port.write(bytes([2]))
    port.flush()
    time.sleep(0.001)
    assert ask([1, 1], 2) == bytes([0xC0, 0xDE])
    port.write(bytes([0]))
    # 12: port 1 is all high after power-on.
    assert ask([12], 1) == b"\xff"
    port.close()
    print("ok")


if __name__ == "__main__":
    main(sys.argv[1])
