"""python-can 4.6.1 keeps the SLIOs on a buslab bus calibrated, as any host could.

Usage: slio_calibrator.py HOST PORT PERIOD_S

Sends the calibration frame 0AA#AA04 every PERIOD_S seconds until stdin closes. Prints
`ready` once connected and `sent N` after the first few frames, so the Rust test can wait for
the event instead of guessing a time.
"""

import select
import sys
import time

import can


def main():
    host, port, period = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    bus = can.Bus(interface="socketcand", channel="vcan0", host=host, port=port, tcp_tune=True)
    frame = can.Message(arbitration_id=0x0AA, is_extended_id=False, data=[0xAA, 0x04])
    try:
        print("ready", flush=True)
        sent = 0
        while True:
            bus.send(frame)
            sent += 1
            if sent == 4:
                print("sent 4", flush=True)
            # Stop when the test closes our stdin.
            ready, _, _ = select.select([sys.stdin], [], [], period)
            if ready and not sys.stdin.read(1):
                return 0
    finally:
        bus.shutdown()


if __name__ == "__main__":
    sys.exit(main())
