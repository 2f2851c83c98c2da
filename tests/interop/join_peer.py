"""python-can 4.6.1 on one of two buses joined across "machines" (`bus serve --join`), through
its socketcand interface: the sender or the receiver of numbered frames.

Usage:
  join_peer.py send PORT FIRST COUNT [PAUSE_AT[,PAUSE_AT…]]
  join_peer.py recv PORT

send: COUNT frames, ID 0x123, data = the frame's number (u32, little-endian) and 4 zero bytes,
numbered from FIRST; at each PAUSE_AT (frames sent so far) it prints `paused N` and waits for
a `go` line on stdin before the rest. Prints `sent N` at the end.

recv: prints `ready` once connected, then receives until it has as many frames as the last
`stop N` line on stdin says (read at any time), and prints `received N in_order 0|1`: in_order
says each frame's number was greater than the one before (gaps allowed: frames lost on the
way are counted by buslab, not here).
"""

import sys
import threading

import can


def connect(port):
    return can.Bus(interface="socketcand", host="127.0.0.1", port=port, channel="vcan0")


def send(port, first, count, pauses):
    bus = connect(port)
    for k in range(first, first + count):
        if k - first in pauses:
            print("paused %d" % (k - first), flush=True)
            if sys.stdin.readline().strip() != "go":
                sys.exit("expected go")
        data = k.to_bytes(4, "little") + bytes(4)
        bus.send(can.Message(arbitration_id=0x123, data=data, is_extended_id=False))
    print("sent %d" % count, flush=True)
    bus.shutdown()


def recv(port):
    bus = connect(port)
    target = [None]

    def read_stdin():
        for line in sys.stdin:
            word, _, n = line.strip().partition(" ")
            if word == "stop":
                target[0] = int(n)

    threading.Thread(target=read_stdin, daemon=True).start()
    print("ready", flush=True)
    got = 0
    last = -1
    in_order = True
    while target[0] is None or got < target[0]:
        msg = bus.recv(timeout=0.1)
        if msg is None:
            continue
        number = int.from_bytes(msg.data[:4], "little")
        if number <= last:
            in_order = False
        last = number
        got += 1
    print("received %d in_order %d" % (got, in_order), flush=True)
    bus.shutdown()


def main():
    mode, port = sys.argv[1], int(sys.argv[2])
    if mode == "send":
        pauses = {int(p) for p in sys.argv[5].split(",")} if len(sys.argv) > 5 else set()
        send(port, int(sys.argv[3]), int(sys.argv[4]), pauses)
    else:
        recv(port)


if __name__ == "__main__":
    main()
