//! Ending a client's wait for frames from another thread: a socket pair whose reading end the
//! wait polls beside the connection ([`buslab_bus::CanBus::recv_waker`]).

use std::io::{self, Read, Write};
use std::os::fd::{AsFd, BorrowedFd};
use std::os::unix::net::UnixStream;
use std::sync::Arc;

use buslab_bus::RecvWaker;

/// The waiting side: readable while a wake is pending.
#[derive(Debug)]
pub(super) struct WakeLine {
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
    pub(super) fn new() -> io::Result<Self> {
        let (pending, waking) = UnixStream::pair()?;
        pending.set_nonblocking(true)?;
        waking.set_nonblocking(true)?;
        Ok(Self {
            pending,
            waker: Arc::new(Waker(waking)),
        })
    }

    pub(super) fn waker(&self) -> Arc<dyn RecvWaker> {
        self.waker.clone()
    }

    /// Takes the pending wakes: one wait ends for all of them. One read takes all there are
    /// unless the buffer fills (a stream socket hands out everything it holds).
    pub(super) fn clear(&self) {
        let mut buf = [0u8; 64];
        while matches!((&self.pending).read(&mut buf), Ok(n) if n == buf.len()) {}
    }

    pub(super) fn fd(&self) -> BorrowedFd<'_> {
        self.pending.as_fd()
    }
}
