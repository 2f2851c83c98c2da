"""python-can 4.6.1 reading log files, every field of every message, for buslab's test that
reads the same files (crates/buslab/tests/log_python_can_data.rs).

  can_log_fields.py FILE...   for each FILE: a line "file NAME", then one line per message:
                              TIME CHANNEL KIND EXT ID DLC DATA DIR
                              TIME   repr() of python-can's float seconds
                              CHANNEL the channel as python-can gives it (None when none)
                              KIND   D data, R remote, E error, F CAN FD (is_fd)
                              EXT    x extended, s standard
                              ID     arbitration_id in hex
                              DLC    decimal; DATA hex ("-" when empty); DIR R or T
                              or, when python-can cannot read the file, "error TEXT"

ASC is read with absolute times (relative_timestamp=False), as buslab reads it. python-can's
LogReader drops its options for a .gz file; its own decompressing path is called with them.

  can_log_fields.py --write-examples DIR
                              writes python-can's example messages (its test/data/example_data.py,
                              on the path) with python-can's writer of each format it writes
                              (DIR/examples.log .asc .blf .trc .csv .db) and prints the paths
"""

import sys

import can
from can.io.player import _decompress


def fields(msg):
    if msg.is_error_frame:
        kind = "E"
    elif msg.is_fd:
        kind = "F"
    elif msg.is_remote_frame:
        kind = "R"
    else:
        kind = "D"
    data = bytes(msg.data).hex().upper() or "-"
    return " ".join([
        repr(float(msg.timestamp)),
        str(msg.channel).replace(" ", "_"),
        kind,
        "x" if msg.is_extended_id else "s",
        f"{msg.arbitration_id:X}",
        str(msg.dlc),
        data,
        "R" if msg.is_rx else "T",
    ])


def main(paths):
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


def write_examples(directory):
    import example_data

    messages = example_data.sort_messages(
        example_data.TEST_MESSAGES_BASE
        + example_data.TEST_MESSAGES_REMOTE_FRAMES
        + example_data.TEST_MESSAGES_ERROR_FRAMES
    )
    for ext in (".log", ".asc", ".blf", ".trc", ".csv", ".db"):
        path = f"{directory}/examples{ext}"
        with can.Logger(path) as logger:
            for msg in messages:
                logger.on_message_received(msg)
        print(path)


if __name__ == "__main__":
    if sys.argv[1] == "--write-examples":
        write_examples(sys.argv[2])
    else:
        main(sys.argv[1:])
