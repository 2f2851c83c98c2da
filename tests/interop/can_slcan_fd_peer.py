"""python-can 4.6.1 uses `buslab slcan serve` as a CAN FD SLCAN adapter (CANable 2.0 style:
its `slcan` interface with a BitTimingFd, which sends S6 and Y2, and FD messages as d/D/b/B).

Usage: can_slcan_fd_peer.py PTY_PATH COUNT

Talks on stdout, one line per step, so the Rust test can drive the other side:
  sent                             after sending 4 messages: FD 12 bytes, FD with BRS and an
                                   extended ID 64 bytes, FD 0 bytes, and a classic frame
  rx ID EXT FD BRS LEN DATA        each of the next COUNT messages received (hex, DATA or -)
"""

import sys

import can

# A deadline for frames that normally come within milliseconds (CI machines are loaded).
EVENT = 60


def describe(msg):
    data = msg.data.hex().upper() or "-"
    return "%X %d %d %d %d %s" % (
        msg.arbitration_id,
        msg.is_extended_id,
        msg.is_fd,
        msg.bitrate_switch,
        len(msg.data),
        data,
    )


def main():
    path, count = sys.argv[1], int(sys.argv[2])
    timing = can.BitTimingFd.from_sample_point(
        f_clock=80_000_000,
        nom_bitrate=500_000,
        nom_sample_point=80.0,
        data_bitrate=2_000_000,
        data_sample_point=80.0,
    )
    bus = can.Bus(interface="slcan", channel=path, timing=timing, sleep_after_open=0)
    try:
        # python-can's IDs are extended unless told otherwise.
        bus.send(
            can.Message(
                arbitration_id=0x123, is_extended_id=False, is_fd=True, data=bytes(range(12))
            )
        )
        bus.send(
            can.Message(
                arbitration_id=0x1ABCDEF0,
                is_extended_id=True,
                is_fd=True,
                bitrate_switch=True,
                data=bytes(range(64)),
            )
        )
        bus.send(can.Message(arbitration_id=0x7FF, is_extended_id=False, is_fd=True, data=b""))
        bus.send(can.Message(arbitration_id=0x100, is_extended_id=False, data=[0xAA]))
        print("sent", flush=True)
        for _ in range(count):
            msg = bus.recv(timeout=EVENT)
            if msg is None:
                print("timeout waiting for a frame", flush=True)
                return 1
            print("rx " + describe(msg), flush=True)
    finally:
        bus.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
