"""python-can 4.6.1 uses `buslab slcan serve` as a USB SLCAN adapter (interface='slcan').

Usage: can_slcan_peer.py PTY_PATH

Talks on stdout, one line per step, so the Rust test can drive the other side:
  ready VERSION SERIAL       the adapter is open (python-can's get_version and serial number)
  sent                       after sending 3 frames (standard, extended, remote)
  rx ID EXT REMOTE DLC DATA  each of the next 3 frames received (ID hex, DATA hex or -)
"""

import sys

import can

# A deadline for frames that normally come within milliseconds (CI machines are loaded).
EVENT = 60


def describe(msg):
    data = msg.data.hex().upper() or "-"
    return "%X %d %d %d %s" % (
        msg.arbitration_id,
        msg.is_extended_id,
        msg.is_remote_frame,
        msg.dlc,
        data,
    )


def main():
    path = sys.argv[1]
    # As an adapter is opened: the bus's bit rate (S6), no 2 s sleep after opening the port.
    bus = can.Bus(interface="slcan", channel=path, bitrate=500000, sleep_after_open=0)
    try:
        hw, sw = bus.get_version(EVENT)
        serial = bus.get_serial_number(EVENT)
        print("ready %s.%s %s" % (hw, sw, serial), flush=True)
        bus.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=[1, 2, 3]))
        bus.send(can.Message(arbitration_id=0x1ABCDEF0, is_extended_id=True, data=[0xDE, 0xAD]))
        bus.send(can.Message(arbitration_id=0x7FF, is_extended_id=False, is_remote_frame=True, dlc=2))
        print("sent", flush=True)
        for _ in range(3):
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
