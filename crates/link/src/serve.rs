//! Pacing a sans-IO byte device to the wall clock behind a pseudo-terminal.

use std::collections::VecDeque;
use std::fs::File;
use std::io;
use std::os::fd::AsFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use nix::poll::{PollFd, PollFlags, ppoll};
use nix::sys::time::TimeSpec;

use buslab_device::{ByteDevice, LineSettings, Nanos};
use buslab_pace::{Pacer, Rate, Ticks};

use crate::Pty;

/// Work done on the served device from another thread (press a key, power-cycle, change an
/// input), with the current virtual time.
pub type Control<D> = Box<dyn FnOnce(&mut D, Nanos) + Send>;

/// How long the loop may sleep without looking at `stop` and the control channel.
const MAX_IDLE: Duration = Duration::from_millis(20);

/// The most device time a late turn of the loop catches up at once when the device has work
/// due (its credit, see `buslab_pace`), and the most by which bytes read late are dated back
/// to when the loop was woken for them: a second of the line, 11.5 KB at 115200 baud, well
/// within what a client may have waiting ([`MAX_OUTBOUND`]). A longer stall (the process was
/// stopped) is skipped, not sent in one burst.
const DEVICE_CREDIT: Duration = Duration::from_secs(1);

/// Bytes from the client waiting for their line time. Beyond this the loop stops reading the
/// PTY, so a writer that outruns the line blocks (as on a real port) instead of piling its
/// bytes up in memory.
const MAX_INBOUND: usize = 4096;

/// What Linux's pseudo-terminal hands over in one read at most (its line discipline's buffer,
/// `N_TTY_BUF_SIZE` 4096, keeps one byte free). A read this long found that buffer full: the
/// client wrote more at once, held in the kernel until a kernel worker moves it on after the
/// read, which a loaded host may do hundreds of milliseconds later.
const PTY_READ_MAX: usize = 4095;

/// Bytes for the client that the PTY did not take yet. A client that does not read loses what
/// comes beyond this, as a real port's receive buffer overflows.
const MAX_OUTBOUND: usize = 64 * 1024;

/// Serves `device` on `pty` until `stop` is set.
///
/// Bytes the client writes arrive at the device as over a real UART at `line`: each is
/// delivered when its stop bits end, one character time after the client wrote it and at
/// least one character time after the previous byte, even though a PTY passes a burst at once.
/// Bytes that have arrived are delivered before control work runs. When the client's own
/// settings do not match `line` (other baud rate, data bits or parity) its bytes would be
/// framing errors on a real line: they are dropped, with one warning (`tracing`). A client that
/// writes faster than the line carries is held back (its writes block once 4 KiB wait, as on a
/// real port), and one that does not read loses the device's output beyond 64 KiB waiting (one
/// warning). When serving ends, a summary of what was lost is logged if anything was. The
/// device hears of a client opening the port ([`ByteDevice::port_opened`]) and of a client
/// throwing away what it had not read yet (`tcflush`, as terminal programs do when they start:
/// [`ByteDevice::output_lost`]).
pub fn serve<D: ByteDevice>(
    device: &mut D,
    pty: &Pty,
    line: LineSettings,
    control: &Receiver<Control<D>>,
    stop: &AtomicBool,
) -> io::Result<()> {
    serve_with(
        "the device",
        device,
        pty,
        line,
        control,
        stop,
        &mut |_, _, _| {},
    )
}

/// [`serve`], calling `after_poll(device, now, output)` each time the device has been polled,
/// before the bytes it produced go to the client; `output` says whether it produced any (where
/// an adapter takes snapshots to persist, and syncs its journal before an acknowledgement
/// leaves). `name` names the device in the warnings about lost bytes (`monican`): a process
/// may serve several.
pub(crate) fn serve_with<D: ByteDevice>(
    name: &str,
    device: &mut D,
    pty: &Pty,
    line: LineSettings,
    control: &Receiver<Control<D>>,
    stop: &AtomicBool,
    after_poll: &mut dyn FnMut(&mut D, Nanos, bool),
) -> io::Result<()> {
    let mut losses = Losses {
        device: format!("{name} on {}", pty.path().display()),
        ..Losses::default()
    };
    let result = serve_loop(device, pty, line, control, stop, after_poll, &mut losses);
    for warning in losses.summary(line) {
        tracing::warn!("{warning}");
    }
    result
}

/// What the line lost, for one warning each and a summary at the end.
#[derive(Default)]
struct Losses {
    /// The device and its PTY, as the warnings name them (`monican on /dev/pts/3`).
    device: String,
    /// Bytes from a client at other settings (framing errors), and the last such settings.
    garbled: u64,
    peer: Option<LineSettings>,
    /// Device output beyond what a client that does not read may have waiting.
    overflowed: u64,
    /// Wall time the loop was kept from running beyond the device's credit, skipped.
    skipped: Duration,
}

impl Losses {
    fn garbled(&mut self, n: usize, peer: LineSettings, line: LineSettings) {
        if self.garbled == 0 {
            tracing::warn!(
                "{}: the client's port is set to {peer}, the device expects {line}; its bytes \
                 are lost as framing errors",
                self.device
            );
        }
        self.garbled += n as u64;
        self.peer = Some(peer);
    }

    fn overflowed(&mut self, n: usize) {
        if self.overflowed == 0 {
            tracing::warn!(
                "{}: the client does not read; the device's output beyond {MAX_OUTBOUND} \
                 waiting bytes is lost",
                self.device
            );
        }
        self.overflowed += n as u64;
    }

    fn stalled(&mut self, skipped: Duration) {
        if self.skipped.is_zero() {
            tracing::warn!(
                "{}: serving stalled for more than {} ms; the device skipped {} ms of its time \
                 rather than send it in one burst",
                self.device,
                DEVICE_CREDIT.as_millis(),
                skipped.as_millis()
            );
        }
        self.skipped += skipped;
    }

    /// The warnings when serving ends, one per kind of loss.
    fn summary(&self, line: LineSettings) -> Vec<String> {
        let mut warnings = Vec::new();
        if let Some(peer) = self.peer {
            warnings.push(format!(
                "{}: {} bytes from the client were lost as framing errors (client at {peer}, \
                 device at {line})",
                self.device, self.garbled
            ));
        }
        if self.overflowed > 0 {
            warnings.push(format!(
                "{}: {} bytes of the device's output were lost: the client did not read them",
                self.device, self.overflowed
            ));
        }
        if !self.skipped.is_zero() {
            warnings.push(format!(
                "{}: the device skipped {} ms of its time in stalls of the host",
                self.device,
                self.skipped.as_millis()
            ));
        }
        warnings
    }
}

/// The device time from which bytes read at `wall` were there to read: `late` earlier (how long
/// the woken thread waited for a CPU), at most [`DEVICE_CREDIT`], never before the device's
/// own time `device_now`.
fn readable_since(pacer: &Pacer, wall: Duration, late: Duration, device_now: Nanos) -> Nanos {
    let woken = wall.saturating_sub(late.min(DEVICE_CREDIT));
    nanos(pacer.ticks_at(woken)).max(device_now)
}

/// The device's time on its pacer's clock: the pacer counts the device's nanoseconds
/// ([`Rate::per_second`] of 10⁹), so the two are the same count.
fn ticks(t: Nanos) -> Ticks {
    Ticks(t.get())
}

/// The pacer's ticks as the device's time (see [`ticks`]).
fn nanos(t: Ticks) -> Nanos {
    Nanos::new(t.0)
}

/// How long this thread has waited for a CPU while runnable, in all (Linux's
/// `/proc/thread-self/schedstat`, second field): across a wait, how late the thread ran after
/// it was woken. Zero where the kernel does not tell.
struct RunQueueWait {
    file: Option<File>,
    buf: [u8; 96],
}

impl RunQueueWait {
    /// Opened by the thread it measures.
    fn open() -> Self {
        Self {
            file: File::open("/proc/thread-self/schedstat").ok(),
            buf: [0; 96],
        }
    }

    fn total(&mut self) -> Duration {
        use std::os::unix::fs::FileExt;
        let Some(file) = &self.file else {
            return Duration::ZERO;
        };
        let Ok(n) = file.read_at(&mut self.buf, 0) else {
            return Duration::ZERO;
        };
        run_queue_wait(&self.buf[..n])
    }
}

/// The second field of a `schedstat` line (`on-CPU ns, waiting ns, timeslices`); zero for
/// anything else.
fn run_queue_wait(schedstat: &[u8]) -> Duration {
    std::str::from_utf8(schedstat)
        .ok()
        .and_then(|text| text.split_whitespace().nth(1))
        .and_then(|waited| waited.parse().ok())
        .map_or(Duration::ZERO, Duration::from_nanos)
}

fn serve_loop<D: ByteDevice>(
    device: &mut D,
    pty: &Pty,
    line: LineSettings,
    control: &Receiver<Control<D>>,
    stop: &AtomicBool,
    after_poll: &mut dyn FnMut(&mut D, Nanos, bool),
    losses: &mut Losses,
) -> io::Result<()> {
    pty.report_flushes()?;
    let epoch = Instant::now();
    let wall = || epoch.elapsed();
    // The device's nanoseconds, paced to the wall clock.
    let mut pacer = Pacer::new(Rate::per_second(1_000_000_000), DEVICE_CREDIT);
    let mut run_queue = RunQueueWait::open();
    let mut inbound = Inbound {
        queue: VecDeque::new(),
        arrivals: Arrivals::new(line.byte_time()),
        buf: vec![0; MAX_INBOUND],
    };
    let mut outbound: VecDeque<u8> = VecDeque::new();
    let mut produced = Vec::new();
    let mut controls_open = true;
    let mut now = Nanos::ZERO;

    while !stop.load(Ordering::Relaxed) {
        let turn = wall();
        let due = [device.next_deadline(), inbound.next_arrival()]
            .into_iter()
            .flatten()
            .min();
        let plan = pacer.plan(turn, ticks(now), due.map(ticks));
        if !plan.skipped.is_zero() {
            losses.stalled(plan.skipped);
        }
        now = nanos(plan.run_to);
        // Bytes that have finished arriving go first, so control work sees them. Bytes the
        // client wrote while it was held back go in before the device's time moves past them.
        loop {
            inbound.deliver(device, now);
            if !inbound.arrivals.held_back || inbound.queue.len() >= MAX_INBOUND {
                break;
            }
            let read_at = nanos(pacer.ticks_at(wall())).max(now);
            inbound.read(pty, line, read_at, losses)?;
        }
        // A client that arrived or threw away what it had not read yet: before the device's
        // poll, so its answer (a whole screen) leaves in this turn.
        if pty.take_opened() {
            tracing::debug!("{}: a client opened the port", losses.device);
            device.port_opened(now);
        }
        if pty.take_flushed() {
            tracing::debug!("{}: the client flushed what it had not read", losses.device);
            device.output_lost(now);
        }
        while controls_open {
            match control.try_recv() {
                Ok(work) => work(device, now),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => controls_open = false,
            }
        }
        device.poll(now, &mut produced);
        after_poll(device, now, !produced.is_empty());
        let room = MAX_OUTBOUND.saturating_sub(outbound.len());
        if produced.len() > room {
            losses.overflowed(produced.len() - room);
            device.output_lost(now);
        }
        outbound.extend(produced.drain(..).take(room));
        flush(pty, &mut outbound)?;

        let due = [device.next_deadline(), inbound.next_arrival()]
            .into_iter()
            .flatten()
            .min();
        let sleep = match pacer.wake_at(turn, due.map(ticks)) {
            Some(at) => at.saturating_sub(turn).min(MAX_IDLE),
            None => MAX_IDLE,
        };
        let mut events = PollFlags::empty();
        if inbound.queue.len() < MAX_INBOUND {
            events |= PollFlags::POLLIN;
        }
        if !outbound.is_empty() {
            events |= PollFlags::POLLOUT;
        }
        // Where opens cannot be watched, the master again with no events: one array always.
        let (opens, open_events) = match pty.opens_fd() {
            Some(opens) => (opens, PollFlags::POLLIN),
            None => (pty.as_fd(), PollFlags::empty()),
        };
        let mut fds = [
            PollFd::new(pty.as_fd(), events),
            PollFd::new(opens, open_events),
        ];
        // ppoll, not poll: poll's whole milliseconds would round a wait under 1 ms (a byte at
        // 115200 baud is 87 µs) down to 0 and spin the loop.
        let waited_before = run_queue.total();
        match ppoll(&mut fds, Some(TimeSpec::from_duration(sleep)), None) {
            Ok(_) | Err(nix::errno::Errno::EINTR) => {}
            Err(e) => return Err(e.into()),
        }
        // Woken, this thread may wait for a CPU a long time on a loaded machine: what the
        // client wrote was there that much earlier, and it is dated so (bounded), or every
        // late turn would be line time lost for good (a request-reply protocol such as the
        // ZELLE cell's idles its line for it).
        let late = run_queue.total().saturating_sub(waited_before);
        let read_at = readable_since(&pacer, wall(), late, now);
        inbound.read(pty, line, read_at, losses)?;
    }
    flush(pty, &mut outbound)
}

/// Bytes from the client waiting for their line time. `None`: a character the device cannot
/// decode (the client's settings differ); it still takes its time on the line.
struct Inbound {
    queue: VecDeque<(Nanos, Option<u8>)>,
    arrivals: Arrivals,
    buf: Vec<u8>,
}

impl Inbound {
    /// Hands the device every byte that has fully arrived by `now`.
    fn deliver<D: ByteDevice>(&mut self, device: &mut D, now: Nanos) {
        while let Some(&(at, byte)) = self.queue.front() {
            if at > now {
                break;
            }
            if let Some(byte) = byte {
                device.receive(at, byte);
            }
            self.queue.pop_front();
        }
    }

    fn next_arrival(&self) -> Option<Nanos> {
        self.queue.front().map(|&(at, _)| at)
    }

    /// Reads what the client wrote, as far as the queue has room; notes whether the client is
    /// being held back.
    /// `read_at`: the device time from which what is read now could have been on the line.
    fn read(
        &mut self,
        pty: &Pty,
        line: LineSettings,
        read_at: Nanos,
        losses: &mut Losses,
    ) -> io::Result<()> {
        loop {
            if self.queue.len() >= MAX_INBOUND {
                // What the client writes meanwhile waits in the PTY, on the line already.
                self.arrivals.held_back = true;
                return Ok(());
            }
            let room = MAX_INBOUND - self.queue.len();
            match pty.read(&mut self.buf[..room]) {
                Ok(0) => {
                    self.arrivals.held_back = false;
                    return Ok(());
                }
                Ok(n) => {
                    let peer = pty.peer_settings()?;
                    let understood = line.understands(&peer);
                    if !understood {
                        losses.garbled(n, peer, line);
                    }
                    // Bytes sent at other settings occupy the line too (a writer cannot
                    // outrun it), but the device never gets them.
                    let stamps = self.arrivals.stamp(read_at, n);
                    // The kernel's buffer was full: what it still holds follows these bytes
                    // without a gap, however late it comes.
                    self.arrivals.kernel_held_back = n >= PTY_READ_MAX;
                    for (&byte, at) in self.buf[..n].iter().zip(stamps) {
                        self.queue.push_back((at, understood.then_some(byte)));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    // Nothing was waiting: the next bytes are written from now on.
                    self.arrivals.held_back = false;
                    return Ok(());
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // EIO: no client at the moment (cannot happen while we hold the slave open).
                Err(e) if e.raw_os_error() == Some(libc::EIO) => {
                    self.arrivals.held_back = false;
                    return Ok(());
                }
                Err(e) => return Err(e),
            }
        }
    }
}

/// When the bytes read from the PTY finish arriving at the device. A PTY passes a burst at
/// once and says nothing of when each byte was written: a byte read at `read_at` has fully
/// arrived one character time later, and no sooner than one character after the previous one.
/// Bytes that waited in the PTY because the server held the client back (its queue was full)
/// were on the line already: they follow the previous ones without a gap, however late the
/// server got to read them (a gap would be a pause inside a frame, which a device may time
/// out). The same holds for bytes the kernel held back: a read that found its buffer full
/// ([`PTY_READ_MAX`]) is followed without a gap by the next bytes read.
#[derive(Debug)]
struct Arrivals {
    byte_ns: Nanos,
    last: Nanos,
    held_back: bool,
    kernel_held_back: bool,
}

impl Arrivals {
    fn new(byte_ns: Nanos) -> Self {
        Self {
            byte_ns,
            last: Nanos::ZERO,
            held_back: false,
            kernel_held_back: false,
        }
    }

    /// Arrival times of `n` bytes read at `read_at`.
    fn stamp(&mut self, read_at: Nanos, n: usize) -> impl Iterator<Item = Nanos> + use<> {
        let start = if self.held_back || self.kernel_held_back {
            self.last
        } else {
            read_at.max(self.last)
        };
        let byte_ns = self.byte_ns;
        self.last = start + byte_ns * n as u64;
        (1..=n as u64).map(move |k| start + byte_ns * k)
    }
}

/// Writes as much of `outbound` as the PTY takes now, in one write when it takes it all (what
/// a device produced at once reaches the client at once: a screen update is not split where
/// the queue's buffer wraps).
fn flush(pty: &Pty, outbound: &mut VecDeque<u8>) -> io::Result<()> {
    while !outbound.is_empty() {
        let front = &*outbound.make_contiguous();
        match pty.write(front) {
            Ok(n) => {
                outbound.drain(..n);
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{
        Arrivals, DEVICE_CREDIT, Duration, LineSettings, Losses, Nanos, Pacer, Rate,
        readable_since, run_queue_wait,
    };

    fn ns(counts: &[u64]) -> Vec<Nanos> {
        counts.iter().copied().map(Nanos::new).collect()
    }

    #[test]
    fn a_request_read_late_is_dated_from_when_the_loop_was_woken_for_it() {
        // The ZELLE cell answers each `1` with a byte: a request stamped at the moment a late
        // serving thread got the CPU was that much line time lost for good. It is dated from
        // when the thread was woken (read 30 ms after that: 30 ms earlier).
        let pacer = Pacer::new(Rate::per_second(1_000_000_000), DEVICE_CREDIT);
        let ms = Nanos::from_millis;
        let wall = Duration::from_millis(1_000);
        assert_eq!(
            readable_since(&pacer, wall, Duration::from_millis(30), ms(900)),
            ms(970)
        );
        // On time: the read time.
        assert_eq!(
            readable_since(&pacer, wall, Duration::ZERO, ms(900)),
            ms(1_000)
        );
        // Never before the device's own time (it has run past it already).
        assert_eq!(
            readable_since(&pacer, wall, Duration::from_millis(300), ms(900)),
            ms(900)
        );
        // At most the device's credit back, however long the thread waited.
        let wall = Duration::from_secs(10);
        assert_eq!(
            readable_since(&pacer, wall, Duration::from_secs(5), Nanos::ZERO),
            ms(10_000) - Nanos::from(DEVICE_CREDIT)
        );
    }

    #[test]
    fn the_run_queue_wait_is_the_second_schedstat_field() {
        assert_eq!(
            run_queue_wait(b"2061532418 36270051 1431\n"),
            Duration::from_nanos(36_270_051)
        );
        for garbage in [&b""[..], b"12", b"1 x 3", b"\xff\xfe 1 2", b"1 -5 2"] {
            assert_eq!(run_queue_wait(garbage), Duration::ZERO, "{garbage:?}");
        }
    }

    #[test]
    fn the_warnings_about_lost_bytes_name_the_device() {
        // `WARN 8264 bytes of the device's output were lost` did not say which device: the
        // lab serves three.
        let mut losses = Losses {
            device: "monican on /dev/pts/3".into(),
            ..Losses::default()
        };
        losses.overflowed(8264);
        losses.garbled(5, LineSettings::n81(9600), LineSettings::n81(19_200));
        let warnings = losses.summary(LineSettings::n81(19_200));
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[0].starts_with("monican on /dev/pts/3: 5 bytes from the client were lost"),
            "{}",
            warnings[0]
        );
        assert!(
            warnings[1]
                .starts_with("monican on /dev/pts/3: 8264 bytes of the device's output were lost"),
            "{}",
            warnings[1]
        );
    }

    #[test]
    fn bytes_follow_each_other_at_line_rate_from_when_they_were_read() {
        let mut a = Arrivals::new(Nanos::new(10));
        assert_eq!(
            a.stamp(Nanos::new(100), 3).collect::<Vec<_>>(),
            ns(&[110, 120, 130])
        );
        // Read before the line is free: they queue behind the previous ones.
        assert_eq!(
            a.stamp(Nanos::new(105), 2).collect::<Vec<_>>(),
            ns(&[140, 150])
        );
        // Read later: they start then.
        assert_eq!(
            a.stamp(Nanos::new(1000), 1).collect::<Vec<_>>(),
            ns(&[1010])
        );
    }

    #[test]
    fn bytes_the_server_held_back_follow_without_a_gap_however_late_it_reads_them() {
        let mut a = Arrivals::new(Nanos::new(10));
        assert_eq!(a.stamp(Nanos::ZERO, 2).collect::<Vec<_>>(), ns(&[10, 20]));
        a.held_back = true;
        // The server was away for a long time (a loaded machine): no pause inside the frame.
        assert_eq!(
            a.stamp(Nanos::new(500_000_000), 2).collect::<Vec<_>>(),
            ns(&[30, 40])
        );
        // Once nothing waits any more, read times count again.
        a.held_back = false;
        assert_eq!(
            a.stamp(Nanos::new(500_000_000), 1).collect::<Vec<_>>(),
            ns(&[500_000_010])
        );
    }

    #[test]
    fn bytes_the_kernel_held_back_follow_without_a_gap_however_late_they_come() {
        let mut a = Arrivals::new(Nanos::new(10));
        assert_eq!(a.stamp(Nanos::ZERO, 2).collect::<Vec<_>>(), ns(&[10, 20]));
        // The read found the kernel's buffer full; the rest came much later.
        a.kernel_held_back = true;
        assert_eq!(
            a.stamp(Nanos::new(400_000_000), 2).collect::<Vec<_>>(),
            ns(&[30, 40])
        );
        a.kernel_held_back = false;
        assert_eq!(
            a.stamp(Nanos::new(400_000_000), 1).collect::<Vec<_>>(),
            ns(&[400_000_010])
        );
    }
}
