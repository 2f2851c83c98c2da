//! What `load`, `sendfile` and `recvfile` share: data sent with the file protocol (SPEC N5,
//! `buslab_can::file`) paced by the bus, with a progress bar on a terminal.
//!
//! The sender hands the frames to its node a batch at a time and waits until the batch is on
//! the wire ([`BusAdmin::flush`](buslab_canbus::BusAdmin::flush)): the progress bar then shows
//! what the bus carried, not what was queued, and a wire that stops carrying (no
//! acknowledgement, errors) only slows it down — the controller retransmits by itself, so the
//! sender keeps waiting and says why, until `stall` (if any) passes without progress.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::bail;
use buslab_backends::{BusUrl, DynBus};
use buslab_can::{Frame, Id};
use buslab_canbus::{BusError, FileReadError};
use indicatif::{ProgressBar, ProgressStyle};

use super::status::shown;
use crate::units::Human;

/// Frames handed to the node before waiting for them to be sent.
const BATCH: usize = 32;
/// How long one wait for a batch lasts before the sender looks at its node's state.
const LOOK: Duration = Duration::from_secs(1);

/// A progress bar of `len` bytes on stderr (drawn only when stderr is a terminal).
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:30}] {bytes}/{total_bytes} {bytes_per_sec} {eta}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Sends `data` on `id` with the file protocol: 8 bytes a frame, the last shorter (empty when
/// the length is a multiple of 8). Returns once every frame was transmitted; an error when the
/// node gave a frame up, when `stall` passed without a frame sent, or on `stop` (Ctrl-C).
pub fn send_data(
    bus: &mut DynBus,
    url: &BusUrl,
    id: Id,
    data: &[u8],
    bar: &ProgressBar,
    stall: Option<Duration>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let frames = buslab_can::file::frames(id, data).map(Ok::<_, FileReadError>);
    send_frames(bus, url, frames, bar, stall, stop)
}

/// [`send_data`] for frames made as they are taken ([`buslab_canbus::FileFrames`] reads a
/// file as it goes): at most one batch of frames is held at a time.
pub fn send_frames(
    bus: &mut DynBus,
    url: &BusUrl,
    mut frames: impl Iterator<Item = Result<Frame, FileReadError>>,
    bar: &ProgressBar,
    stall: Option<Duration>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let mut batch = Vec::with_capacity(BATCH);
    loop {
        batch.clear();
        for frame in frames.by_ref().take(BATCH) {
            batch.push(frame?);
        }
        if batch.is_empty() {
            return Ok(());
        }
        for frame in &batch {
            bus.send(frame)?;
        }
        wait_sent(bus, url, stall, stop)?;
        let bytes: usize = batch.iter().map(|f| f.payload().len()).sum();
        bar.inc(bytes as u64);
    }
}

/// Waits until the frames handed to this client's node are on the wire (a bus without
/// administration, such as SocketCAN, took them into its queue: nothing to wait for).
fn wait_sent(
    bus: &mut DynBus,
    url: &BusUrl,
    stall: Option<Duration>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let Some(admin) = bus.admin() else {
        return Ok(());
    };
    let mut progress_at = Instant::now();
    let mut sent_before = admin.node_status(None)?.counters.sent;
    let mut warned = false;
    loop {
        if stop.load(Ordering::SeqCst) {
            bail!("interrupted");
        }
        match admin.flush(LOOK) {
            Ok(report) if report.failed > 0 => {
                let st = shown(admin.node_status(None)?);
                bail!(
                    "{} frame(s) were given up by this node on {url}; its status:\n{st}",
                    report.failed
                )
            }
            Ok(_) => {
                if warned {
                    tracing::info!("the bus carries frames again");
                }
                return Ok(());
            }
            Err(BusError::Timeout { .. }) => {
                let st = shown(admin.node_status(None)?);
                if st.counters.sent > sent_before {
                    sent_before = st.counters.sent;
                    progress_at = Instant::now();
                    continue;
                }
                if !warned {
                    tracing::warn!(
                        "no frame got through for {} (node {}: {}); the controller keeps retransmitting",
                        Human(LOOK),
                        st.number,
                        st.state
                    );
                    warned = true;
                }
                if let Some(stall) = stall
                    && progress_at.elapsed() >= stall
                {
                    bail!(
                        "no frame got through for {} (no other node acknowledges, or the wire is cut); this node's status:\n{st}",
                        Human(stall)
                    );
                }
            }
            Err(e) => return Err(e.into()),
        }
    }
}
