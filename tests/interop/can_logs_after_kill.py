"""python-can 4.6.1 on a log whose writer was killed, for buslab's durability tests.

  can_logs_after_kill.py FILE   prints every message python-can reads from FILE, one per line:
                                SECONDS FRAME (FRAME in can-utils' syntax, ERR for an error
                                frame); if python-can's reader raises before the end, a last
                                line `# stopped: EXCEPTION` says so (the messages before it
                                are what a script iterating the reader gets).
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


def main(path):
    try:
        for msg in can.LogReader(path):
            print(f"{msg.timestamp:.6f} {frame_text(msg)}")
    except Exception as e:  # the point: show where python-can stops, and why
        print(f"# stopped: {e!r}")


if __name__ == "__main__":
    main(sys.argv[1])
