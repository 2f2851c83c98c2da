//! The PowerPC node's serial port: its VT100 terminal on a pseudo-terminal at 19200 8N1, while
//! the node itself runs on a virtual bus server's thread.
//!
//! The PTY side is a [`ByteDevice`] paced by `buslab_link`: keys the terminal sends are posted
//! to the bus thread ([`PpcNode::key`]); screen updates are pulled from the node only when the
//! line has room ([`PpcNode::take_screen`] diffs the screen when it is called), so a busy bus
//! never piles up stale updates behind a 19200-baud line.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};

use buslab_device::{ByteDevice, LineSettings};
use buslab_link::{Serve, Served, ServedError};
use buslab_ppc::{BAUD, PpcNode};
use buslab_vbus::Poster;

/// 19200 8N1: 10 bit-times per byte.
const BYTE_NS: u64 = 1_000_000_000 * 10 / BAUD as u64;
/// Bytes waiting for the line before more of the screen is asked for.
const LOW_WATER: usize = 256;
/// How often the terminal side looks for screen updates while idle.
const POLL_NS: u64 = 20_000_000;

/// The terminal side of the PowerPC node.
pub struct PpcTerminal {
    /// The node's name on the bus.
    node: String,
    bus: Poster,
    screen: Receiver<Vec<u8>>,
    screen_tx: Sender<Vec<u8>>,
    /// A request for screen bytes is on its way to the bus thread.
    asked: Arc<AtomicBool>,
    out: VecDeque<u8>,
    /// When the next byte may leave (line pacing).
    next_at: u64,
    now: u64,
}

impl PpcTerminal {
    /// The terminal of node `node` on the server behind `bus`.
    pub fn new(node: impl Into<String>, bus: Poster) -> Self {
        let (screen_tx, screen) = mpsc::channel();
        Self {
            node: node.into(),
            bus,
            screen,
            screen_tx,
            asked: Arc::new(AtomicBool::new(false)),
            out: VecDeque::new(),
            next_at: 0,
            now: 0,
        }
    }

    /// Asks the node for what changed on its screen, if the line has room and no request is
    /// pending.
    fn ask(&mut self) {
        if self.out.len() >= LOW_WATER || self.asked.swap(true, Ordering::SeqCst) {
            return;
        }
        let node = self.node.clone();
        let tx = self.screen_tx.clone();
        let asked = self.asked.clone();
        let posted = self.bus.post(move |bus| {
            let bytes = bus
                .device_mut::<PpcNode>(&node)
                .map(PpcNode::take_screen)
                .unwrap_or_default();
            let _ = tx.send(bytes);
            asked.store(false, Ordering::SeqCst);
        });
        if !posted {
            self.asked.store(false, Ordering::SeqCst);
        }
    }
}

impl ByteDevice for PpcTerminal {
    fn receive(&mut self, _now_ns: u64, byte: u8) {
        let node = self.node.clone();
        self.bus.post(move |bus| {
            if let Some(ppc) = bus.device_mut::<PpcNode>(&node) {
                ppc.key(byte);
            }
        });
    }

    fn poll(&mut self, now_ns: u64, out: &mut Vec<u8>) {
        self.now = now_ns;
        while let Ok(bytes) = self.screen.try_recv() {
            self.out.extend(bytes);
        }
        // Bytes leave at the line rate, one after the other.
        self.next_at = self.next_at.max(now_ns.saturating_sub(BYTE_NS));
        while self.next_at + BYTE_NS <= now_ns {
            let Some(b) = self.out.pop_front() else { break };
            out.push(b);
            self.next_at += BYTE_NS;
        }
        self.ask();
    }

    fn next_deadline(&self) -> Option<u64> {
        if self.out.is_empty() {
            Some(self.now + POLL_NS)
        } else {
            Some(self.next_at + BYTE_NS)
        }
    }
}

/// Serves the terminal of PowerPC node `node` on a pseudo-terminal (19200 8N1), linked at
/// `link` if given; the node's screen is redrawn whole first.
pub fn serve_terminal(
    node: &str,
    bus: Poster,
    link: Option<PathBuf>,
) -> Result<Served<PpcTerminal>, ServedError> {
    let name = node.to_string();
    bus.post(move |bus| {
        if let Some(ppc) = bus.device_mut::<PpcNode>(&name) {
            ppc.redraw();
        }
    });
    Serve::new(PpcTerminal::new(node, bus), LineSettings::n81(BAUD))
        .name("monican")
        .link(link)
        .spawn()
}
