"""python-can 4.6.1 opens `buslab slcan serve` at the wrong bit rate, then at the right one.

Usage: can_slcan_wrong_rate.py PTY_PATH WRONG_BITRATE RIGHT_BITRATE

Talks on stdout, one line per step, so the Rust test can check the other side:
  sent           a frame was sent at the wrong rate (python-can does not wait for an answer)
  flags XX       what `F` answers once the adapter is bus-off
  refused        a frame was answered with BEL
  reopened       after shutdown and a new Bus at the right rate, one frame (0x456, AA) sent

python-can has no call for `F` and ignores the answers to frames: the script reads them with
the bus's own `_write`/`_read`, as its `get_version` does.
"""

import sys
import time

import can

# A deadline for answers that normally come within milliseconds (CI machines are loaded).
EVENT = 60


def answer(bus, first):
    """The next answer starting with one of `first` (others, such as `z`, are skipped)."""
    deadline = time.monotonic() + EVENT
    while time.monotonic() < deadline:
        text = bus._read(EVENT)
        if text and text[0] in first:
            return text
    raise SystemExit("no answer starting with %r" % (first,))


def opened(path, bitrate):
    """A Bus at `bitrate`, past the answers to its opening (python-can's second `O` gets BEL;
    `get_version` reads up to the version line)."""
    bus = can.Bus(interface="slcan", channel=path, bitrate=bitrate, sleep_after_open=0)
    if bus.get_version(EVENT) == (None, None):
        raise SystemExit("no answer to V")
    return bus


def main():
    path, wrong, right = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    frame = can.Message(arbitration_id=0x123, is_extended_id=False, data=[])
    bus = opened(path, wrong)
    try:
        bus.send(frame)
        print("sent", flush=True)
        deadline = time.monotonic() + EVENT
        while True:
            if time.monotonic() > deadline:
                print("never bus-off", flush=True)
                return 1
            bus._write("F")
            flags = answer(bus, "F")
            if flags == "FA4\r":
                # Error passive with a bus error, or bus-off: a frame tells them apart.
                bus.send(frame)
                if answer(bus, "z\a") == "\a":
                    break
            time.sleep(0.02)
        print("flags " + flags[1:3], flush=True)
        print("refused", flush=True)
    finally:
        bus.shutdown()
    bus = opened(path, right)
    try:
        bus.send(can.Message(arbitration_id=0x456, is_extended_id=False, data=[0xAA]))
        if answer(bus, "z\a") != "z\r":
            print("refused at the right rate", flush=True)
            return 1
        print("reopened", flush=True)
    finally:
        bus.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
