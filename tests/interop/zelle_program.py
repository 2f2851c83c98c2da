"""Loads a user program into a served ZELLE cell and runs it, with pyserial only, byte by byte
as seed 003 describes the protocol (issue 27's acceptance).

Usage: zelle_program.py PTY PROGRAM.ihx VALUE

PROGRAM is examples/zelle/measure.c built by SDCC (--code-loc 0x400): it measures channel 1
sixteen times into 0808h.., stores the count at 0800h, says "D", then waits for a 0. VALUE is
the reading the cell's channel 1 gives (the served cell is fed a constant). Prints what
happened and "ok"; raises on any mismatch.
"""

import sys
import time

import serial

PROGRAM_AREA = 0x0400
AREA_LEN = 0x0400


def image(path):
    """The Intel HEX file's bytes from 0400h (gaps FFh)."""
    data = {}
    with open(path) as hexfile:
        for line in hexfile:
            line = line.strip()
            if not line:
                continue
            assert line.startswith(":"), f"not Intel HEX: {line!r}"
            raw = bytes.fromhex(line[1:])
            length, addr, kind = raw[0], raw[1] << 8 | raw[2], raw[3]
            assert sum(raw) & 0xFF == 0, f"bad checksum: {line}"
            if kind == 1:
                break
            assert kind == 0, f"record type {kind} in {line}"
            for i, byte in enumerate(raw[4 : 4 + length]):
                data[addr + i] = byte
    assert data and min(data) >= PROGRAM_AREA and max(data) < PROGRAM_AREA + AREA_LEN, (
        "the program must lie in 0400h..07FFh"
    )
    end = max(data) + 1
    return bytes(data.get(a, 0xFF) for a in range(PROGRAM_AREA, end))


def main(path, program, value):
    code = image(program)
    # A read returns as soon as its bytes are there; the long time-out only bounds a failure
    # (a loaded machine may be slow to serve the PTY).
    port = serial.Serial(path, 9600, bytesize=8, parity="N", stopbits=2, timeout=30)

    def zeros():
        # The seed's reset: ten zeros, 2 ms apart.
        for _ in range(10):
            time.sleep(0.002)
            port.write(b"\x00")
            port.flush()
        time.sleep(0.01)
        port.reset_input_buffer()

    zeros()
    # Command 5, then 1 ms of set-up; for each byte the cell sends a timing byte, the host
    # answers "1" and the byte; "0" ends the transfer.
    port.write(b"\x05")
    port.flush()
    time.sleep(0.002)
    for byte in code:
        assert len(port.read(1)) == 1, "no timing byte from the cell"
        port.write(bytes([1, byte]))
    assert len(port.read(1)) == 1, "no timing byte before the end"
    port.write(b"\x00")
    port.flush()
    time.sleep(0.01)
    print(f"loaded {len(code)} bytes at 0400h with command 5")

    # Command 6 starts it; it measures for 160 ms, then says "D".
    port.write(b"\x06")
    port.flush()
    heard = port.read(1)
    assert heard == b"D", f"the program said {heard!r}, wanted b'D'"
    print(f"started with command 6, heard {heard!r}")

    # A 0 stops it (it waits outside the OS's serial routines); the OS answers again.
    port.write(b"\x00")
    port.flush()
    time.sleep(0.01)
    port.reset_input_buffer()

    def peek(addr):
        port.write(bytes([18, addr >> 8, addr & 0xFF]))
        reply = port.read(1)
        assert len(reply) == 1, f"no answer to command 18 at {addr:04X}h"
        return reply[0]

    count = peek(0x0800)
    values = [peek(0x0808 + i) for i in range(count)]
    print(f"interrupted with 0; command 18: count {count}, values {values}")
    assert count == 16, f"count {count}, wanted 16"
    assert values == [value] * 16, f"values {values}, wanted 16 x {value}"
    print("ok")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]))
