"""PyPI can-cannelloni 0.1.0 (python-can's `cannelloni` interface, a TCP client) joins buslab's
`cannelloni+tcp://…?role=server`.

Usage: can_cannelloni_peer.py HOST:PORT COUNT

Prints `ready` once connected; receives COUNT frames (numbered in their data, u32
little-endian, any IDs) and prints `received N in_order 0|1 ext E rtr R`; then sends COUNT
frames of its own (every third extended, ID 0x1ABCDE00 + k, the others 0x200; one remote
frame 0x7FF with DLC 3 last) and prints `sent N`; waits for a `done` line on stdin before it
disconnects (so nothing it sent is cut off).
"""

import sys

import can

# A deadline for frames that normally come within milliseconds (CI machines are loaded).
EVENT = 60


def main():
    channel, count = sys.argv[1], int(sys.argv[2])
    bus = can.Bus(interface="cannelloni", channel=channel, reconnect=False)
    print("ready", flush=True)
    got, last, in_order, ext, rtr = 0, -1, True, 0, 0
    while got < count:
        msg = bus.recv(timeout=EVENT)
        if msg is None:
            sys.exit("no frame within %d s after %d" % (EVENT, got))
        if msg.is_remote_frame:
            rtr += 1
        else:
            number = int.from_bytes(msg.data[:4], "little")
            in_order = in_order and number > last
            last = number
        ext += msg.is_extended_id
        got += 1
    print("received %d in_order %d ext %d rtr %d" % (got, in_order, ext, rtr), flush=True)
    for k in range(count - 1):
        extended = k % 3 == 0
        bus.send(
            can.Message(
                arbitration_id=(0x1ABCDE00 + k % 256) if extended else 0x200,
                data=k.to_bytes(4, "little"),
                is_extended_id=extended,
            )
        )
    bus.send(can.Message(arbitration_id=0x7FF, is_remote_frame=True, dlc=3, is_extended_id=False))
    print("sent %d" % count, flush=True)
    sys.stdin.readline()
    bus.shutdown()


if __name__ == "__main__":
    main()
