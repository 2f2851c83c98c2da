//! Ending a bus's wait for frames from another thread ([`buslab_bus::CanBus::recv_waker`]): a
//! socket pair whose reading end the wait polls beside the bus's own descriptor (a TCP
//! connection, a CAN socket, a serial port). Shared by the socketcand client, the SLCAN bus
//! and the SocketCAN bus of `buslab-backends`.

use std::io::{self, Read, Write};
use std::os::fd::{AsFd, BorrowedFd};
use std::os::unix::net::UnixStream;
use std::sync::Arc;
use std::time::Duration;

use nix::poll::{PollFd, PollFlags, PollTimeout};

use buslab_bus::RecvWaker;

/// The waiting side: readable while a wake is pending.
#[derive(Debug)]
pub struct WakeLine {
    pending: UnixStream,
    waker: Arc<Waker>,
}

/// The waking side, shared with other threads.
#[derive(Debug)]
struct Waker(UnixStream);

impl RecvWaker for Waker {
    fn wake(&self) {
        // A full socket (WouldBlock) means wakes are pending already: nothing to add.
        let _ = (&self.0).write(&[1]);
    }
}

impl WakeLine {
    pub fn new() -> io::Result<Self> {
        let (pending, waking) = UnixStream::pair()?;
        pending.set_nonblocking(true)?;
        waking.set_nonblocking(true)?;
        Ok(Self {
            pending,
            waker: Arc::new(Waker(waking)),
        })
    }

    pub fn waker(&self) -> Arc<dyn RecvWaker> {
        self.waker.clone()
    }

    /// The waker of `line`, opened the first time it is asked for ([`CanBus::recv_waker`]
    /// of `bus`); `None` when no line can be opened (the bus is then not woken).
    ///
    /// [`CanBus::recv_waker`]: buslab_bus::CanBus::recv_waker
    pub fn opened_waker(line: &mut Option<WakeLine>, bus: &str) -> Option<Arc<dyn RecvWaker>> {
        if line.is_none() {
            match WakeLine::new() {
                Ok(opened) => *line = Some(opened),
                Err(e) => {
                    tracing::debug!("no wake line for {bus}: {e}");
                    return None;
                }
            }
        }
        line.as_ref().map(WakeLine::waker)
    }

    /// Takes the pending wakes: one wait ends for all of them. One read takes all there are
    /// unless the buffer fills (a stream socket hands out everything it holds).
    fn clear(&self) {
        let mut buf = [0u8; 64];
        while matches!((&self.pending).read(&mut buf), Ok(n) if n == buf.len()) {}
    }
}

/// Waits until `fd` is readable (`true`); `false` after `timeout` (`None`: no limit) or when
/// `wake` was woken. poll(2), not a read timeout: the kernel counts SO_RCVTIMEO in whole
/// scheduler ticks (a 2 ms wait took at least 4 ms at HZ=250). A signal is an
/// [`io::ErrorKind::Interrupted`] error: the caller waits again until its deadline.
pub fn wait_readable(
    fd: BorrowedFd<'_>,
    wake: Option<&WakeLine>,
    timeout: Option<Duration>,
) -> io::Result<bool> {
    let timeout = match timeout {
        None => PollTimeout::NONE,
        // Whole milliseconds, rounded up: a wait never ends before its deadline.
        Some(t) => PollTimeout::try_from(t.as_micros().div_ceil(1000)).unwrap_or(PollTimeout::MAX),
    };
    let watched = PollFd::new(fd, PollFlags::POLLIN);
    let mut fds = [watched.clone(), watched];
    let polled = match wake {
        Some(w) => {
            fds[1] = PollFd::new(w.pending.as_fd(), PollFlags::POLLIN);
            &mut fds[..]
        }
        None => &mut fds[..1],
    };
    if nix::poll::poll(polled, timeout)? == 0 {
        return Ok(false);
    }
    // The descriptor first; the wake stays pending until a poll finds it idle (it ends the
    // wait then), so it is not lost while what was read turns out to be no frame.
    if fds[0].any().unwrap_or(true) {
        return Ok(true);
    }
    if let Some(w) = wake {
        w.clear();
    }
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wake_ends_one_wait_and_bytes_come_before_it() {
        let (mut peer, watched) = UnixStream::pair().unwrap();
        let line = WakeLine::new().unwrap();
        let forever = None;
        line.waker().wake();
        line.waker().wake();
        peer.write_all(&[7]).unwrap();
        assert!(wait_readable(watched.as_fd(), Some(&line), forever).unwrap());
        (&watched).read_exact(&mut [0]).unwrap();
        assert!(!wait_readable(watched.as_fd(), Some(&line), forever).unwrap());
        // Both wakes were taken by that one wait.
        let no_wait = Some(Duration::ZERO);
        assert!(!wait_readable(watched.as_fd(), Some(&line), no_wait).unwrap());
    }
}
