//! Serving the [`Adapter`] model on a port (the master side of a pseudo-terminal): the thin
//! I/O around the sans-IO model. Bytes from the host and frames from the bus arrive through one
//! channel of [`Input`]s, so the model has a single owner and sees them in order.

use std::io;
use std::os::fd::BorrowedFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender};
use std::time::{Duration, Instant};

use buslab_bus::ErrorFrame;
use buslab_can::{FdFrame, Frame, Nanos};
use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};

use crate::adapter::{Adapter, AdapterEvent};

/// What reaches the served adapter.
#[derive(Debug)]
pub enum Input {
    /// Bytes the host wrote.
    Host(Vec<u8>),
    /// A frame the adapter received from the bus.
    Frame(Frame),
    /// A CAN FD frame the adapter received from the bus (see [`Adapter::deliver_fd`]).
    Fd(FdFrame),
    /// An error frame of the adapter's own controller (see [`Adapter::controller_error`]).
    Error(ErrorFrame),
}

/// How often the loops look at `stop` while nothing happens.
const IDLE: Duration = Duration::from_millis(100);

/// While output waits for room in the port, how soon to try again.
const RETRY: Duration = Duration::from_millis(2);

/// Inputs waiting at most; a reader of the port waits beyond this.
pub const INPUT_QUEUE: usize = 4096;

/// Serves `adapter` on the non-blocking `port` until `stop` is set or every sender of
/// `inputs` is gone: bytes the host writes go to the adapter, and its answers and the frames
/// it receives (`Input::Frame`, sent by whoever watches the bus through `feed`) go back to
/// the host; [`AdapterEvent`]s go to `on_event`. A host that does not read loses frames once
/// the adapter's bounded output is full (see [`Adapter`]).
pub fn serve(
    port: BorrowedFd<'_>,
    adapter: &mut Adapter,
    feed: SyncSender<Input>,
    inputs: Receiver<Input>,
    mut on_event: impl FnMut(AdapterEvent),
    stop: &AtomicBool,
) -> io::Result<()> {
    let epoch = Instant::now();
    std::thread::scope(|scope| {
        let reader = std::thread::Builder::new()
            .name("slcan-port".into())
            .spawn_scoped(scope, move || read_port(port, &feed, stop))?;
        let result = (|| {
            while !stop.load(Ordering::SeqCst) {
                let wait = if adapter.output().is_empty() {
                    IDLE
                } else {
                    RETRY
                };
                match inputs.recv_timeout(wait) {
                    Ok(Input::Host(bytes)) => adapter.receive(&bytes),
                    Ok(Input::Frame(frame)) => {
                        adapter.deliver(&frame, Nanos::from(epoch.elapsed()))
                    }
                    Ok(Input::Fd(frame)) => {
                        adapter.deliver_fd(&frame, Nanos::from(epoch.elapsed()))
                    }
                    Ok(Input::Error(error)) => adapter.controller_error(&error),
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => break,
                }
                while let Some(event) = adapter.poll_event() {
                    on_event(event);
                }
                write_port(port, adapter)?;
            }
            Ok(())
        })();
        // The reader sees `stop` within IDLE.
        stop.store(true, Ordering::SeqCst);
        let read = reader.join().unwrap_or(Ok(()));
        result.and(read)
    })
}

/// Hands what the host writes to the loop.
fn read_port(port: BorrowedFd<'_>, feed: &SyncSender<Input>, stop: &AtomicBool) -> io::Result<()> {
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        let mut fds = [PollFd::new(port, PollFlags::POLLIN)];
        match poll(
            &mut fds,
            PollTimeout::try_from(IDLE).unwrap_or(PollTimeout::MAX),
        ) {
            Ok(0) | Err(Errno::EINTR) => continue,
            Ok(_) => {}
            Err(e) => return Err(e.into()),
        }
        match nix::unistd::read(port, &mut buf) {
            Ok(0) | Err(Errno::EAGAIN | Errno::EINTR) => continue,
            // No client has the port open (a PTY whose slave was closed by everyone).
            Err(Errno::EIO) => std::thread::sleep(IDLE),
            Ok(n) => {
                if feed.send(Input::Host(buf[..n].to_vec())).is_err() {
                    break;
                }
            }
            Err(e) => return Err(e.into()),
        }
    }
    Ok(())
}

/// Writes what the port takes now; the rest waits in the adapter.
fn write_port(port: BorrowedFd<'_>, adapter: &mut Adapter) -> io::Result<()> {
    while !adapter.output().is_empty() {
        match nix::unistd::write(port, adapter.output()) {
            Ok(n) => adapter.consume(n),
            Err(Errno::EAGAIN) => break,
            Err(Errno::EINTR) => {}
            Err(e) => return Err(e.into()),
        }
    }
    Ok(())
}
