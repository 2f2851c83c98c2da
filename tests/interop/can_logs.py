"""python-can 4.6.1 on log files, for buslab's log interop tests.

  can_logs.py read FILE    prints every message python-can reads from FILE, one per line:
                           SECONDS CHANNEL FRAME DIR, where FRAME is can-utils' syntax
                           (123#1122, 12345678#R3) or ERR for an error frame, DIR R or T
  can_logs.py write FILE   reads candump log lines on stdin and writes them with python-can's
                           writer for FILE's extension (can.Logger)

ASC is read with python-can's default (times relative to the first frame).
"""

import sys

import can


def frame_text(msg):
    if msg.is_error_frame:
        return "ERR"
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    if msg.is_remote_frame:
        return f"{ident}#R{msg.dlc}"
    return f"{ident}#{bytes(msg.data).hex().upper()}"


def read(path):
    for msg in can.LogReader(path):
        print(f"{msg.timestamp:.6f} {msg.channel} {frame_text(msg)} {'R' if msg.is_rx else 'T'}")


def parse(line):
    fields = line.split()
    timestamp = float(fields[0].strip("()"))
    channel = fields[1]
    ident, data = fields[2].split("#", 1)
    is_rx = not (len(fields) > 3 and fields[3] == "T")
    raw = int(ident, 16)
    kwargs = dict(timestamp=timestamp, channel=channel, is_rx=is_rx)
    if len(ident) == 8 and raw & 0x20000000:
        payload = bytes.fromhex(data)
        return can.Message(is_error_frame=True, arbitration_id=raw & 0x1FFFFFFF,
                           is_extended_id=False, data=payload, dlc=len(payload), **kwargs)
    extended = len(ident) == 8
    if data[:1] in ("R", "r"):
        dlc = int(data[1:] or "0")
        return can.Message(arbitration_id=raw, is_extended_id=extended, is_remote_frame=True,
                           dlc=dlc, **kwargs)
    payload = bytes.fromhex(data)
    return can.Message(arbitration_id=raw, is_extended_id=extended, data=payload,
                       dlc=len(payload), **kwargs)


def write(path):
    logger = can.Logger(path)
    for line in sys.stdin:
        if line.strip():
            logger.on_message_received(parse(line))
    logger.stop()


if __name__ == "__main__":
    {"read": read, "write": write}[sys.argv[1]](sys.argv[2])
