"""python-can 4.6.1 and CAN FD logs, for buslab's FD round trip (crates/logs/tests/fd_interop.rs).

  can_fd_logs.py write DIR    writes one set of messages (CAN FD frames of every FD length with
                              every BRS/ESI combination, standard and extended IDs, Rx and Tx,
                              two channels, and a few classic data and remote frames) with
                              python-can's writers: DIR/source.blf, DIR/source.asc,
                              DIR/source.log; prints the messages written, as `read` prints them
  can_fd_logs.py read FILE... for each FILE: a line "file NAME", then one line per message
                              python-can reads (or "error TEXT" when it cannot read the file)

A message line: TIME CHANNEL KIND EXT ID DATA DIR BRS ESI
  TIME     repr() of python-can's float seconds
  CHANNEL  the channel as python-can gives it (None when none)
  KIND     F CAN FD (is_fd), f CAN FD marked remote (python-can's ASC reader makes an FD
           line of length 0 one), R remote, E error frame, D data
  EXT      x extended, s standard
  ID       arbitration_id in hex
  DATA     hex, "-" when empty (a remote frame: "r" and its DLC)
  DIR      R or T
  BRS ESI  1 or 0

ASC is read with absolute times (relative_timestamp=False). A `.gz` file is read through
python-can's own decompression, with the same options.
"""

import sys

import can
from can.io.player import _decompress

FD_LENGTHS = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64]
START = 1700000000.0


def messages():
    out = []
    n = 0
    for length in FD_LENGTHS:
        for flags in range(4):
            extended = n % 2 == 1
            ident = (0x1ABC0000 | n) if extended else 0x100 + n
            data = bytes((i * 7 + n) & 0xFF for i in range(length))
            out.append(can.Message(
                timestamp=START + n * 0.0015,
                arbitration_id=ident,
                is_extended_id=extended,
                is_fd=True,
                bitrate_switch=bool(flags & 1),
                error_state_indicator=bool(flags & 2),
                data=data,
                dlc=length,
                channel=n % 2,
                is_rx=n % 3 != 0,
            ))
            n += 1
    for k, (ident, extended, data, remote) in enumerate([
        (0x123, False, b"\x11\x22\x33", False),
        (0x1F334455, True, b"\xde\xad\xbe\xef\x01\x02\x03\x04", False),
        (0x7FF, False, b"", True),
        (0x12345678, True, b"", False),
    ]):
        out.append(can.Message(
            timestamp=START + (n + k) * 0.0015,
            arbitration_id=ident,
            is_extended_id=extended,
            is_remote_frame=remote,
            data=data,
            dlc=3 if remote else len(data),
            channel=k % 2,
            is_rx=k != 1,
        ))
    return out


def fields(msg):
    if msg.is_error_frame:
        kind = "E"
    elif msg.is_fd:
        kind = "f" if msg.is_remote_frame else "F"
    elif msg.is_remote_frame:
        kind = "R"
    else:
        kind = "D"
    if msg.is_remote_frame:
        data = f"r{msg.dlc}"
    else:
        data = bytes(msg.data).hex().upper() or "-"
    return " ".join([
        repr(float(msg.timestamp)),
        str(msg.channel).replace(" ", "_"),
        kind,
        "x" if msg.is_extended_id else "s",
        f"{msg.arbitration_id:X}",
        data,
        "R" if msg.is_rx else "T",
        "1" if msg.bitrate_switch else "0",
        "1" if msg.error_state_indicator else "0",
    ])


def write(directory):
    written = messages()
    for ext in (".blf", ".asc", ".log"):
        with can.Logger(f"{directory}/source{ext}") as logger:
            for msg in written:
                logger.on_message_received(msg)
    for msg in written:
        print(fields(msg))


def read(paths):
    for path in paths:
        print(f"file {path}")
        options = {}
        if path.endswith((".asc", ".asc.gz")):
            options["relative_timestamp"] = False
        try:
            if path.endswith(".gz"):
                reader = _decompress(path, **options)
            else:
                reader = can.LogReader(path, **options)
            lines = [fields(msg) for msg in reader]
        except Exception as e:  # python-can refusing a file is a result, not a crash
            print(f"error {type(e).__name__}: {e}".replace("\n", " "))
            continue
        for line in lines:
            print(line)


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(sys.argv[2])
    elif sys.argv[1] == "read":
        read(sys.argv[2:])
    else:
        sys.exit(__doc__)
