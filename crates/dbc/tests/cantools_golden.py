"""cantools' reading of DBC files, for crates/dbc/tests/golden.rs.

Usage: .venv/bin/python crates/dbc/tests/cantools_golden.py FILE.dbc...

For every file: cantools' model (default strict loading) and the frames this script makes for
each message, each with what cantools decodes from it. The frames are deterministic (seeded by
the file's name and the message's ID): random payloads of the message's length, all zeros, all
ones, for every branch of the multiplexing tree random payloads with the multiplexors on the
path set to the branch's value, and a payload one byte short (decoded with allow_truncated).

One record per line, fields separated by tabs; free text (comments, units, labels, errors) is
UTF-8 in hex, '-' for none:
  file PATH
  refused ERROR                      cantools does not load the file (strict), then
  lenient                            it does with strict=False: the records that follow are that
  refused-lenient ERROR              or it does not either
  message ID EXT NAME LENGTH FD CYCLE_MS COMMENT SENDERS
  signal NAME START LENGTH ORDER SIGNED FLOAT SCALE OFFSET MIN MAX UNIT COMMENT MUX CHOICES INITIAL RECEIVERS
  frame HEX TRUNCATED STATUS         STATUS: ok, or nobranch:MUX=VALUE (cantools refuses the
                                     frame: no branch for that value), or error:ERROR (it cannot
                                     decode the frame at all)
  value NAME RAW PHYSICAL LABEL      RAW: Python repr of the unscaled value; PHYSICAL: repr of
                                     the scaled one as a float
A multiplexor's branch is found by its scaled value, as cantools does; the frames cantools
refuses are decoded here the same way with the unselected branch left out (the `decode_tree`
below follows cantools' Message._decode and is checked against it on every frame cantools
takes).
"""

import random
import sys
import zlib

import cantools
from cantools.database.can.message import DecodeError
from cantools.database.namedsignalvalue import NamedSignalValue
from cantools.database.utils import decode_data

RANDOM_FRAMES = 4
FRAMES_PER_BRANCH = 2
# A message whose tree has more branches than this gets a deterministic sample of them (the
# first, the last and random ones in between); SG_MUL_VAL_ ranges expand to one per value.
MAX_BRANCHES = 256


def text(value):
    if value is None:
        return "-"
    return str(value).encode("utf-8").hex() or "-"


def number(value):
    return "-" if value is None else repr(float(value))


def set_bits(data, signal, raw):
    """The payload with `signal`'s bits set to `raw` (an unsigned integer)."""
    width = 8 * len(data)
    mask = (1 << signal.length) - 1
    raw &= mask
    if signal.byte_order == "little_endian":
        word = int.from_bytes(data, "little")
        shift = signal.start
        word = (word & ~(mask << shift)) | (raw << shift)
        return word.to_bytes(len(data), "little")
    word = int.from_bytes(data, "big")
    msb = 8 * (signal.start // 8) + 7 - signal.start % 8
    shift = width - (msb + signal.length)
    word = (word & ~(mask << shift)) | (raw << shift)
    return word.to_bytes(len(data), "big")


def assignments(tree):
    """Multiplexor settings (name -> value) that together reach every branch of the tree."""
    result = [{}]
    for node in tree:
        if not isinstance(node, dict):
            continue
        for mux, branches in node.items():
            options = []
            for value, sub in sorted(branches.items()):
                for deeper in assignments(sub):
                    options.append({mux: value, **deeper})
            # Several multiplexors side by side: pair them up rather than multiply.
            count = max(len(result), len(options))
            result = [{**result[i % len(result)], **options[i % len(options)]} for i in range(count)]
    return result


def raw_selector(message, name, value):
    """The raw bits that make cantools see `value` for multiplexor `name` (its scaled value)."""
    signal = message.get_signal_by_name(name)
    raw = (value - signal.offset) / signal.scale if signal.conversion.choices is None else value
    raw = int(round(raw))
    return raw & ((1 << signal.length) - 1)


def decode_tree(message, node, data, decode_choices, scaling, truncated, unselected):
    decoded = decode_data(data, message.length, node["signals"], node["formats"],
                          decode_choices, scaling, truncated, True)
    for mux in node["multiplexers"]:
        if truncated and mux not in decoded:
            continue
        value = message._get_mux_number(decoded, mux)
        branch = node["multiplexers"][mux].get(value)
        if branch is None:
            unselected.append(f"{mux}={value}")
            continue
        decoded.update(decode_tree(message, branch, data, decode_choices, scaling, truncated,
                                   unselected))
    return decoded


def decode(message, data, truncated):
    """(status, {name: (raw, physical, label)}) as cantools decodes `data`."""
    results = {}
    for choices, scaling in ((False, False), (False, True), (True, True)):
        unselected = []
        results[(choices, scaling)] = decode_tree(message, message._codecs, data, choices,
                                                  scaling, truncated, unselected)
        try:
            real = message.decode(data, decode_choices=choices, scaling=scaling,
                                  allow_truncated=truncated)
        except DecodeError:
            real = None
        if real is None and not unselected:
            raise AssertionError(f"{message.name}: cantools refuses {data.hex()}")
        # repr: NaN is not equal to itself
        if real is not None and repr(real) != repr(results[(choices, scaling)]):
            raise AssertionError(f"{message.name}: decode_tree differs from cantools on {data.hex()}")
    status = "ok" if not unselected else "nobranch:" + ",".join(unselected)
    values = {}
    for name, raw in results[(False, False)].items():
        physical = results[(False, True)][name]
        label = results[(True, True)][name]
        label = label.name if isinstance(label, NamedSignalValue) else None
        values[name] = (raw, physical, label)
    return status, values


def frames(message, seed):
    rng = random.Random(seed)
    length = message.length
    out = [(bytes(length), False), (bytes([0xFF]) * length, False)]
    out += [(rng.randbytes(length), False) for _ in range(RANDOM_FRAMES)]
    settings = [a for a in assignments(message.signal_tree) if a]
    if len(settings) > MAX_BRANCHES:
        middle = rng.sample(settings[1:-1], MAX_BRANCHES - 2)
        settings = [settings[0], *middle, settings[-1]]
    for setting in settings:
        for _ in range(FRAMES_PER_BRANCH):
            data = rng.randbytes(length)
            for name, value in setting.items():
                data = set_bits(data, message.get_signal_by_name(name),
                                raw_selector(message, name, value))
            out.append((data, False))
    if length > 1:
        out.append((rng.randbytes(length - 1), True))
    return out


def mux_field(signal):
    parts = []
    if signal.is_multiplexer:
        parts.append("M")
    if signal.multiplexer_signal is not None:
        ids = ",".join(str(i) for i in sorted(signal.multiplexer_ids or []))
        parts.append(f"{signal.multiplexer_signal}:{ids}")
    return ";".join(parts) or "-"


def choices_field(signal):
    if not signal.conversion.choices:
        return "-"
    return ",".join(f"{k}={text(str(v))}" for k, v in sorted(signal.conversion.choices.items()))


def dump(path, out):
    out.write(f"file\t{path}\n")
    try:
        db = cantools.database.load_file(path)
    except Exception as e:  # noqa: BLE001 - any refusal is a result to report
        out.write(f"refused\t{text(f'{type(e).__name__}: {e}')}\n")
        # What it makes of the file when told not to check the layout (strict=False).
        try:
            db = cantools.database.load_file(path, strict=False)
        except Exception as e:  # noqa: BLE001
            out.write(f"refused-lenient\t{text(f'{type(e).__name__}: {e}')}\n")
            return
        out.write("lenient\n")
    name = path.rsplit("/", 1)[-1]
    for message in db.messages:
        cycle = "-" if message.cycle_time is None else str(message.cycle_time)
        out.write("\t".join(["message", str(message.frame_id), str(int(message.is_extended_frame)),
                             message.name, str(message.length), str(int(message.is_fd)), cycle,
                             text(message.comment), ",".join(message.senders) or "-"]) + "\n")
        for s in message.signals:
            out.write("\t".join([
                "signal", s.name, str(s.start), str(s.length),
                "le" if s.byte_order == "little_endian" else "be",
                str(int(s.is_signed)), str(int(s.is_float)),
                number(s.scale), number(s.offset), number(s.minimum), number(s.maximum),
                text(s.unit), text(s.comment), mux_field(s), choices_field(s),
                number(s.raw_initial), ",".join(s.receivers) or "-",
            ]) + "\n")
        seed = zlib.crc32(f"{name}/{message.frame_id}/{message.name}".encode())
        for data, truncated in frames(message, seed):
            try:
                status, values = decode(message, data, truncated)
            except DecodeError as e:
                # A layout strict loading refuses (a signal past the message's end).
                status, values = f"error:{text(str(e))}", {}
            out.write(f"frame\t{data.hex() or '-'}\t{int(truncated)}\t{status}\n")
            for signal_name, (raw, physical, label) in values.items():
                out.write(f"value\t{signal_name}\t{raw!r}\t{number(physical)}\t{text(label)}\n")


def main():
    out = sys.stdout
    for path in sys.argv[1:]:
        dump(path, out)


if __name__ == "__main__":
    main()
