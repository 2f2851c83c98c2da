#!/usr/bin/env python3
"""Delivered byte rate of the lab's served serial lines (the PowerPC node's MoniCAN terminal,
the ZELLE cell, the CPU196 board) while a host keeps each line as busy as its protocol lets it,
on an idle machine and with busy loops (`yes > /dev/null`) competing for the CPU.

Usage: python3 bench/served_lines.py [--seconds 10] [--busy 4] [--zelle-ahead 256]
                                     [--cpu196-ahead 16] [--buslab BIN]
       (default BIN: target/release/buslab, built with `cargo build --release -p buslab`)

One `buslab lab -q --no-web --dir DIR` serves the three lines on pseudo-terminals (DIR/monican
19200 8N1, DIR/zelle 9600 8N2, DIR/cpu196 115200 8N1). The client sets each PTY to the
device's settings (raw, same speed and stop bits) and all three are driven at the same time,
one process each (threads would also wait for each other at Python's global lock), first with
no busy loop, then with `--busy` of them, in the same run:

- MoniCAN: a Ctrl-L (full VT100 redraw, ~1360 bytes, 0.7 s of line) every 200 ms, so one is
  always queued. MoniCAN also writes every CAN frame it sees to the screen, so its line is
  near full even without a key. A redraw reaches the PTY whole once its line time is over
  (crates/served/src/ppc.rs), hence reads of ~1360 bytes.
- ZELLE: command 2 (read the data area), the 50 ms set-up pause, then `1` per byte with 256
  requests ahead of the replies (the 30 KiB data area outlasts the window), as `buslab zelle
  dump` does.
- CPU196: PRGFLASH block reads (`F5 0A 00 bank block`, 259-byte reply), sixteen ahead, as
  `buslab cpu196 flash read` does.

The client here is Python and competes with the busy loops too: once it is descheduled for
longer than its requests ahead last on the line (256 ZELLE bytes = 293 ms, sixteen CPU196 blocks =
364 ms), the device idles for want of a request, which is the client's doing. `--zelle-ahead` and
`--cpu196-ahead` deepen the windows to take the client out of the measurement.

Each line is read continuously; the first second is warm-up (the ZELLE set-up pause, the
first redraw). In the window that follows, `bytes` are the bytes received after the window's
first read and `B/s` is bytes / (time of the last read - time of the first read), so the
denominator only spans time in which bytes were flowing; `%` is that over the line rate
(baud / bits per character: 10 for 8N1, 11 for 8N2). A read of N bytes after a silence of S
means the line was idle for S - N character times; `gaps` adds those idle times longer than 50
character times, `longest ms` is the longest, `% busy` the rate over the time outside the gaps
(the rate while the device was sending), and `max read` the biggest single read (a served line
paced to its rate hands over a few characters at a time; a big read is a burst after a stall).
`% window` is every byte read in the window over the whole window: it also charges a stall
still running when the window closes, which first-to-last leaves out. `client s` is the part
of `gaps` ended by a read that brought everything the client had asked for: the device had
answered every request and waited for the next, so that time lies between the device's answer
and the client's next request (the client not running, or the bytes held in the PTY's kernel
side, which a kernel worker moves on); the rest of `gaps` is time the device had requests and
sent nothing (the server's). MoniCAN sends without being asked, so its gaps are not split. A
protocol round trip (MoniCAN's Ctrl-L handling, a reply not yet requested) shows up there, not
in a scheduling delay of the server; with the requests pipelined as above no gap is by design,
so `%` is the figure to judge. `srv wait s` is the time the line's serving thread in the lab
(`zelle-serve`, ...) waited for a CPU while runnable during the window, `cli wait s` the same
for the line's client process (Linux's schedstat): line time lost beyond them was lost neither
to the server's nor to the client's scheduling.
"""

import argparse
import os
import select
import subprocess
import sys
import multiprocessing
import tempfile
import termios
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WARMUP = 1.0
GAP_CHARS = 50

SPEEDS = {9600: termios.B9600, 19200: termios.B19200, 115200: termios.B115200}


def open_line(path, baud, stop_bits):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    attrs = termios.tcgetattr(fd)
    iflag, oflag, cflag, lflag, _, _, cc = attrs
    iflag = 0
    oflag = 0
    lflag = 0
    cflag = termios.CS8 | termios.CREAD | termios.CLOCAL
    if stop_bits == 2:
        cflag |= termios.CSTOPB
    cc[termios.VMIN] = 1
    cc[termios.VTIME] = 0
    speed = SPEEDS[baud]
    termios.tcsetattr(fd, termios.TCSANOW, [iflag, oflag, cflag, lflag, speed, speed, cc])
    termios.tcflush(fd, termios.TCIOFLUSH)
    return fd


def write_all(fd, data):
    while data:
        try:
            n = os.write(fd, data)
            data = data[n:]
        except BlockingIOError:
            select.select([], [fd], [], 0.1)


def drain_quiet(fd, quiet, limit=2.0):
    """Reads until the line has been quiet for `quiet` seconds (at most `limit` seconds)."""
    n = 0
    end = time.monotonic() + limit
    while time.monotonic() < end:
        r, _, _ = select.select([fd], [], [], quiet)
        if not r:
            return n
        try:
            n += len(os.read(fd, 65536))
        except BlockingIOError:
            pass
    return n


class MoniCan:
    name, baud, stop_bits = "MoniCAN terminal", 19200, 1
    EVERY = 0.2

    def start(self, fd):
        self.asked = 0
        self.last_ask = 0.0
        self.ask(fd)

    def ask(self, fd):
        now = time.monotonic()
        if now - self.last_ask >= self.EVERY:
            write_all(fd, b"\x0c")
            self.asked += 1
            self.last_ask = now

    def got(self, fd, n):
        self.ask(fd)

    def quiet(self, fd, seconds):
        self.ask(fd)
        return False

    def outstanding(self):
        return None  # a redraw's size is the screen's

    def detail(self):
        return f"{self.asked} Ctrl-L sent, one every {1000 * self.EVERY:.0f} ms"


class Zelle:
    name, baud, stop_bits = "ZELLE cell", 9600, 2
    AHEAD = 256  # buslab_zelle::client::WINDOW
    DATA_AREA = 0x8000 - 0x0800

    def start(self, fd):
        drain_quiet(fd, 0.2)
        write_all(fd, b"\x02")
        time.sleep(0.05)  # the cell's set-up pause after command 2 (docs/zelle.md)
        self.asked = 0
        self.received = 0
        self.ask(fd)

    def ask(self, fd):
        more = min(self.AHEAD - (self.asked - self.received), self.DATA_AREA - self.asked)
        if more > 0:
            write_all(fd, b"\x01" * more)
            self.asked += more

    def got(self, fd, n):
        self.received += n
        self.ask(fd)

    def quiet(self, fd, seconds):
        return False

    def stop(self, fd):
        write_all(fd, b"\x00")

    def outstanding(self):
        return self.asked - self.received

    def detail(self):
        return f"{self.received} of {self.DATA_AREA} data bytes read, {self.AHEAD} requests ahead"


class Cpu196:
    name, baud, stop_bits = "CPU196 board", 115200, 1
    AHEAD = 16  # buslab_cpu196::host::FLASH_READ_AHEAD
    REPLY = 259

    def start(self, fd):
        drain_quiet(fd, 0.2)
        self.block = 0
        self.owed = 0
        self.ask(fd)

    def ask(self, fd):
        while self.owed < self.AHEAD * self.REPLY:
            write_all(fd, bytes([0xF5, 0x0A, 0x00, 0, self.block]))
            self.block = (self.block + 1) % 256
            self.owed += self.REPLY

    def got(self, fd, n):
        self.owed -= n
        self.ask(fd)

    def quiet(self, fd, seconds):
        return False

    def outstanding(self):
        return self.owed

    def detail(self):
        return f"flash bank 0 block reads, {self.AHEAD} ahead"


class Result:
    pass


def run_queue_wait(path):
    """Seconds the thread `path` (a `/proc/.../schedstat`) has waited for a CPU while runnable
    (Linux's schedstat, second field); None where the kernel does not tell."""
    try:
        with open(path) as f:
            return int(f.read().split()[1]) / 1e9
    except (OSError, IndexError, ValueError):
        return None


def waited(before, after):
    return None if before is None or after is None else after - before


def drive(device, path, seconds, server, out):
    out.put(measure(device, path, seconds, server))


def measure(device, path, seconds, server=None):
    fd = open_line(path, device.baud, device.stop_bits)
    try:
        device.start(fd)
        char = (10 if device.stop_bits == 1 else 11) / device.baud
        gap_limit = GAP_CHARS * char
        t0 = time.monotonic()
        window_start = t0 + WARMUP
        end = window_start + seconds
        first = last = None
        nbytes = 0
        gaps = 0.0
        longest = 0.0
        biggest = 0
        in_window = 0
        me = "/proc/thread-self/schedstat"
        waits = None
        client_gaps = 0.0
        prev = t0
        while True:
            now = time.monotonic()
            if now >= end:
                break
            r, _, _ = select.select([fd], [], [], min(0.05, end - now))
            now = time.monotonic()
            if not r:
                device.quiet(fd, now - prev)
                continue
            owed = device.outstanding()
            try:
                data = os.read(fd, 65536)
            except BlockingIOError:
                continue
            device.got(fd, len(data))
            if now >= window_start:
                if waits is None:
                    waits = (run_queue_wait(me), server and run_queue_wait(server))
                in_window += len(data)
                if first is None:
                    first = now
                else:
                    nbytes += len(data)
                    # The line was idle for the silence less the time this chunk took on it.
                    idle = (now - last) - len(data) * char
                    longest = max(longest, idle)
                    biggest = max(biggest, len(data))
                    if idle > gap_limit:
                        gaps += idle
                        # Everything asked had come: the device waited for the client.
                        if owed is not None and len(data) >= owed:
                            client_gaps += idle
                last = now
            prev = now
        if hasattr(device, "stop"):
            device.stop(fd)
        res = Result()
        res.device = device
        res.bytes = nbytes
        res.span = (last - first) if first is not None and last is not None else 0.0
        res.gaps = gaps
        res.longest = longest
        res.biggest = biggest
        res.in_window = in_window
        res.client_gaps = client_gaps
        res.window = seconds
        res.client_wait = waited(waits and waits[0], run_queue_wait(me))
        res.server_wait = waited(waits and waits[1], server and run_queue_wait(server))
        return res
    finally:
        os.close(fd)


def serving_thread(lab, name):
    """The schedstat of the lab's thread that serves `name` (`zelle-serve`), if any."""
    tasks = f"/proc/{lab}/task"
    for tid in os.listdir(tasks):
        try:
            with open(f"{tasks}/{tid}/comm") as f:
                if f.read().strip() == f"{name}-serve":
                    return f"{tasks}/{tid}/schedstat"
        except OSError:
            pass
    return None


def phase(d, seconds, zelle_ahead, cpu196_ahead, lab):
    out = multiprocessing.Queue()
    zelle, cpu196 = Zelle(), Cpu196()
    zelle.AHEAD, cpu196.AHEAD = zelle_ahead, cpu196_ahead
    # One process per line: threads would wait for each other's turn at Python's lock on top
    # of the busy loops, and that delay would be counted against the served line.
    clients = [
        multiprocessing.Process(
            target=drive,
            args=(dev, os.path.join(d, link), seconds, serving_thread(lab, link), out),
        )
        for dev, link in ((MoniCan(), "monican"), (zelle, "zelle"), (cpu196, "cpu196"))
    ]
    for c in clients:
        c.start()
    results = [out.get() for _ in clients]
    for c in clients:
        c.join()
    with open("/proc/loadavg") as f:
        load = f.read().split()[0]
    order = {"MoniCAN terminal": 0, "ZELLE cell": 1, "CPU196 board": 2}
    results.sort(key=lambda r: order[r.device.name])
    return results, load


def seconds(value):
    return "-" if value is None else f"{value:.3f}"


def print_table(title, results, load):
    print()
    print(f"{title} (load average 1 min at the end: {load})")
    head = (
        f"{'device':<17} {'line':<13} {'line B/s':>9} {'bytes':>7} {'s':>6} {'B/s':>8} "
        f"{'%':>7} {'gaps s':>7} {'longest ms':>10} {'% busy':>7} {'max read':>8} {'% window':>8} {'client s':>8}"
        f" {'srv wait s':>10} {'cli wait s':>10}"
    )
    print(head)
    for r in results:
        dev = r.device
        bits = 10 if dev.stop_bits == 1 else 11
        line_rate = dev.baud / bits
        settings = f"{dev.baud} 8N{dev.stop_bits}"
        rate = r.bytes / r.span if r.span > 0 else 0.0
        busy_span = r.span - r.gaps
        busy = r.bytes / busy_span if busy_span > 0 else 0.0
        print(
            f"{dev.name:<17} {settings:<13} {line_rate:>9.1f} {r.bytes:>7} {r.span:>6.2f} "
            f"{rate:>8.1f} {100 * rate / line_rate:>6.1f}% {r.gaps:>7.2f} "
            f"{1000 * r.longest:>10.1f} {100 * busy / line_rate:>6.1f}% {r.biggest:>8} {100 * r.in_window / r.window / line_rate:>7.1f}% {r.client_gaps:>8.2f}"
            f" {seconds(r.server_wait):>10} {seconds(r.client_wait):>10}"
        )
    for r in results:
        print(f"  {r.device.name}: {r.device.detail()}")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=10.0, help="measured window per phase")
    p.add_argument("--busy", type=int, default=4, help="busy loops in the loaded phase")
    p.add_argument("--zelle-ahead", type=int, default=Zelle.AHEAD, help="ZELLE requests ahead")
    p.add_argument("--cpu196-ahead", type=int, default=Cpu196.AHEAD, help="CPU196 reads ahead")
    p.add_argument("--buslab", default=os.path.join(ROOT, "target/release/buslab"))
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        lab = subprocess.Popen(
            [args.buslab, "lab", "-q", "--no-web", "--listen", "127.0.0.1:0", "--dir", d],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        busy = []
        try:
            deadline = time.monotonic() + 30
            while not os.path.exists(os.path.join(d, "bus")):
                if lab.poll() is not None or time.monotonic() > deadline:
                    print("buslab lab did not come up (no DIR/bus)", file=sys.stderr)
                    return 1
                time.sleep(0.1)
            time.sleep(2)  # MoniCAN's start-up: calibration of the SLIO boards, sign-on
            idle, idle_load = phase(d, args.seconds, args.zelle_ahead, args.cpu196_ahead, lab.pid)
            busy = [
                subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(args.busy)
            ]
            time.sleep(1)
            loaded, loaded_load = phase(d, args.seconds, args.zelle_ahead, args.cpu196_ahead, lab.pid)
        finally:
            for b in busy:
                b.terminate()
                b.wait()
            lab.terminate()
            lab.wait()
    cores = os.cpu_count()
    print(f"\nbuslab lab, three served lines driven at once, {args.seconds:.0f} s window each, "
          f"{cores} cores")
    print_table("0 busy loops", idle, idle_load)
    print_table(f"{args.busy} busy loops (yes > /dev/null)", loaded, loaded_load)
    return 0


if __name__ == "__main__":
    sys.exit(main())
