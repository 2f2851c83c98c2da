#!/usr/bin/env python3
"""How fast buslab decodes CAN frames with a DBC file, against cantools in the same run, on
the same frames and the same DBC.

Usage: .venv/bin/python bench/dbc_speed.py [--frames 100000] [--seconds 3] [DBC...]
(cantools in .venv and opendbc's DBC files under target/ come from scripts/setup-test-deps.sh;
builds the example crates/dbc/examples/dbc_speed.rs with --release first.)

For each DBC (default: opendbc's vw_mlb.dbc, 145 classic messages and 1442 signals, and
ford_lincoln_base_pt.dbc, 368 messages of which 31 CAN FD), a deterministic log of random
frames: each frame a random message of the file with random payload bytes of its length (a
multiplexed message's payload is drawn again until cantools finds a branch for it, so that
both decode every frame). The log is written as `ID#HEX` lines under target/dbc-speed/.

cantools: `Database.decode_message(frame_id, data)` on every frame (its defaults: value-table
labels and scaling), in whole passes over the log for at least SECONDS. buslab: the release
example looks each frame's message up by ID and decodes every signal's raw and physical value
into a reused buffer (`Message::decode_into`), in whole passes for at least SECONDS. The table
gives frames per second and the ratio.
"""

import argparse
import os
import random
import subprocess
import sys
import time

import cantools
from cantools.database.errors import DecodeError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OPENDBC = os.path.join(ROOT, "target/opendbc-wheel/opendbc/dbc")
DEFAULT_DBCS = [os.path.join(OPENDBC, "vw_mlb.dbc"),
                os.path.join(OPENDBC, "ford_lincoln_base_pt.dbc")]
EXAMPLE = os.path.join(ROOT, "target/release/examples/dbc_speed")


def make_log(db, count, seed):
    """(frame_id, data) pairs cantools decodes, and their `ID#HEX` lines."""
    rng = random.Random(seed)
    messages = db.messages
    frames, lines = [], []
    while len(frames) < count:
        message = rng.choice(messages)
        data = rng.randbytes(message.length)
        try:
            message.decode(data)
        except DecodeError:
            continue  # a multiplexor value without a branch: draw again
        frames.append((message.frame_id, data))
        width = 8 if message.is_extended_frame else 3
        lines.append(f"{message.frame_id:0{width}X}#{data.hex().upper()}")
    return frames, lines


def cantools_rate(db, frames, seconds):
    decode = db.decode_message
    done = 0
    start = time.perf_counter()
    while True:
        for frame_id, data in frames:
            decode(frame_id, data)
        done += len(frames)
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return done / elapsed


def buslab_rate(dbc, log, seconds):
    out = subprocess.run([EXAMPLE, dbc, log, str(seconds)], check=True, text=True,
                         stdout=subprocess.PIPE).stdout.split()
    fields = dict(zip(out[::2], out[1::2]))
    return int(fields["frames"]) / float(fields["seconds"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=100_000)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("dbc", nargs="*", default=DEFAULT_DBCS)
    args = ap.parse_args()
    subprocess.run(["cargo", "build", "--quiet", "--release", "-p", "buslab-dbc", "--example",
                    "dbc_speed"], cwd=ROOT, check=True)
    os.makedirs(os.path.join(ROOT, "target/dbc-speed"), exist_ok=True)
    rows = []
    for dbc in args.dbc:
        name = os.path.basename(dbc)
        db = cantools.database.load_file(dbc)
        frames, lines = make_log(db, args.frames, seed=name)
        log = os.path.join(ROOT, "target/dbc-speed", name + ".frames")
        with open(log, "w") as f:
            f.write("\n".join(lines) + "\n")
        theirs = cantools_rate(db, frames, args.seconds)
        ours = buslab_rate(dbc, log, args.seconds)
        rows.append((name, len(db.messages), len(frames), theirs, ours))
    print(f"cantools {cantools.__version__}, Python {sys.version.split()[0]}; "
          f"{args.frames} frames per log, >= {args.seconds} s per measurement")
    print()
    print("| DBC | messages | frames in log | cantools frames/s | buslab frames/s | buslab / cantools |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, messages, count, theirs, ours in rows:
        print(f"| {name} | {messages} | {count} | {theirs:,.0f} | {ours:,.0f} | {ours / theirs:.1f}x |")


if __name__ == "__main__":
    main()
