"""python-can 4.6.1 joins `buslab bus serve` through its socketcand interface.

Usage: can_socketcand_peer.py HOST PORT

Talks on stdout, one line per step, so the Rust test can drive the other side:
  ready                      connected (handshake done)
  rx ID EXT REMOTE DLC DATA  each of the first 3 frames received (ID hex, DATA hex or -)
  sent                       after sending 3 frames (standard, extended, remote)
  order ID ID ID             the first 3 frames received whose ID is not 0x001
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
    host, port = sys.argv[1], int(sys.argv[2])
    bus = can.Bus(interface="socketcand", channel="vcan0", host=host, port=port)
    try:
        print("ready", flush=True)
        for _ in range(3):
            msg = bus.recv(timeout=EVENT)
            if msg is None:
                print("timeout waiting for a frame", flush=True)
                return 1
            print("rx " + describe(msg), flush=True)
        bus.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=[1, 2]))
        bus.send(can.Message(arbitration_id=0x1ABCDEF0, is_extended_id=True, data=[0xDE, 0xAD]))
        bus.send(can.Message(arbitration_id=0x321, is_extended_id=False, is_remote_frame=True, dlc=3))
        print("sent", flush=True)
        order = []
        while len(order) < 3:
            msg = bus.recv(timeout=EVENT)
            if msg is None:
                print("timeout waiting for contenders", flush=True)
                return 1
            if msg.arbitration_id != 0x001:
                order.append("%X" % msg.arbitration_id)
        print("order " + " ".join(order), flush=True)
    finally:
        bus.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
