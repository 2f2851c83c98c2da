//! The PowerPC node's host side, while the node itself runs on a virtual bus server's thread:
//! its VT100 terminal on a pseudo-terminal at 19200 8N1 (MoniCAN's screen, or the running
//! program's serial output), its memory image in a state file, and a control socket that says
//! what the node runs, reads its memory and registers back and resets it ([`serve`] starts
//! what the options ask for).
//!
//! The PTY side is a [`ByteDevice`] paced by `buslab_link`: keys the terminal sends are posted
//! to the bus thread ([`PpcNode::key`]); screen updates are pulled from the node only when the
//! line has room ([`PpcNode::take_screen`] diffs the screen when it is called), so a busy bus
//! never piles up stale updates behind a 19200-baud line. Each update reaches the terminal
//! whole, once the line had the time to carry it: a terminal (or a capture of it) never shows
//! half an update, such as the identifier of a new frame beside the data of the last one.
//!
//! The memory image ([`MemoryStore`]) is an S-record file, read at start and written atomically
//! whenever a load changed it; the node is told once the file is on disk
//! ([`PpcNode::persisted`]) and only then shows the loader's report: a load the terminal
//! reported survives `kill -9`.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_device::{ByteDevice, LineSettings, Nanos, Persistent};
use buslab_link::ControlSocket;
use buslab_link::fs::{read_limited, write_atomic};
use buslab_link::{Serve, Served, ServedError};
use buslab_loader::MemoryImage;
use buslab_ppc::{Activity, BAUD, PpcNode};
use buslab_vbus::{Poster, VirtualBus};

/// The terminal's line: 19200 8N1.
const LINE: LineSettings = LineSettings::n81(BAUD);
/// One character on it.
const BYTE_NS: Nanos = LINE.byte_time();
/// How often the terminal side looks for screen updates while idle.
const POLL_NS: Nanos = Nanos::from_millis(20);
/// How often it looks for the bus thread's answer while one is asked for (it comes within a
/// turn of the bus's loop; the line would stay idle until it is picked up).
const ANSWER_POLL_NS: Nanos = Nanos::from_millis(1);

/// The terminal side of the PowerPC node.
pub struct PpcTerminal {
    /// The node's name on the bus.
    node: String,
    bus: Poster,
    screen: Receiver<Vec<u8>>,
    screen_tx: Sender<Vec<u8>>,
    /// A request for screen bytes is on its way to the bus thread.
    asked: Arc<AtomicBool>,
    /// Screen updates waiting for the line, each whole: the one the line carries, and at most
    /// one behind it (asked for while the first is carried, so the line stays busy with fresh
    /// changes rather than a queue of stale ones).
    updates: VecDeque<Vec<u8>>,
    /// Bytes were lost on the way to the terminal: the next update is the whole screen.
    redraw: bool,
    /// When the line has carried everything handed over so far (line pacing: the next update
    /// leaves once the line had the time for all its bytes after this).
    line_free_at: Nanos,
    now: Nanos,
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
            updates: VecDeque::new(),
            redraw: false,
            line_free_at: Nanos::ZERO,
            now: Nanos::ZERO,
        }
    }

    /// Asks the node for what changed on its screen, if nothing waits behind the update on
    /// the line and no request is pending.
    fn ask(&mut self) {
        if self.updates.len() > 1 || self.asked.swap(true, Ordering::SeqCst) {
            return;
        }
        let node = self.node.clone();
        let tx = self.screen_tx.clone();
        let asked = self.asked.clone();
        let redraw = std::mem::take(&mut self.redraw);
        let posted = self.bus.post(move |bus| {
            let bytes = bus
                .device_mut::<PpcNode>(&node)
                .map(|ppc| {
                    if redraw {
                        ppc.redraw();
                    }
                    ppc.take_screen()
                })
                .unwrap_or_default();
            let _ = tx.send(bytes);
            asked.store(false, Ordering::SeqCst);
        });
        if !posted {
            self.asked.store(false, Ordering::SeqCst);
            self.redraw |= redraw;
        }
    }
}

impl ByteDevice for PpcTerminal {
    fn receive(&mut self, _now_ns: Nanos, byte: u8) {
        let node = self.node.clone();
        self.bus.post(move |bus| {
            if let Some(ppc) = bus.device_mut::<PpcNode>(&node) {
                ppc.key(byte);
            }
        });
    }

    fn poll(&mut self, now_ns: Nanos, out: &mut Vec<u8>) {
        self.now = now_ns;
        while let Ok(bytes) = self.screen.try_recv() {
            if bytes.is_empty() {
                continue;
            }
            if self.updates.is_empty() {
                // The line was idle: it starts carrying this update now.
                self.line_free_at = self.line_free_at.max(now_ns);
            }
            self.updates.push_back(bytes);
        }
        // Each update leaves whole once the line had the time for it; the line's time is
        // kept however late this thread wakes (a late wake sends what is due at once).
        while let Some(front) = self.updates.front()
            && self.line_free_at + line_time(front.len()) <= now_ns
        {
            let update = self.updates.pop_front().expect("front");
            self.line_free_at += line_time(update.len());
            out.extend_from_slice(&update);
        }
        self.ask();
    }

    fn next_deadline(&self) -> Option<Nanos> {
        let poll = if self.asked.load(Ordering::SeqCst) {
            ANSWER_POLL_NS
        } else {
            POLL_NS
        };
        let release = self.updates.front().map_or(Nanos::MAX, |front| {
            self.line_free_at + line_time(front.len())
        });
        Some(release.min(self.now + poll))
    }

    fn output_lost(&mut self, _now_ns: Nanos) {
        // What the terminal shows is no longer what the node's screen thinks it shows.
        self.redraw = true;
    }

    fn port_opened(&mut self, _now_ns: Nanos) {
        // A terminal opened late has seen nothing of the screen (or only what it threw away
        // on starting): it gets the whole screen, as Ctrl L would draw it.
        self.redraw = true;
    }
}

/// The time `bytes` take on the line.
fn line_time(bytes: usize) -> Nanos {
    BYTE_NS * bytes as u64
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
    Serve::new(PpcTerminal::new(node, bus), LINE)
        .name("monican")
        .link(link)
        .spawn()
}

/// The largest memory image file read (the node's program RAM as S-records is ~4.5 MiB).
pub const MAX_IMAGE_FILE: u64 = 16 * 1024 * 1024;
/// How often the store looks whether a load changed the memory.
const STORE_POLL: Duration = Duration::from_millis(20);
/// How long a request to the bus thread may take before the server is taken for stopped.
const BUS_ANSWER: Duration = Duration::from_secs(10);
/// Bytes one `read` control command returns at most.
pub const MAX_READ: usize = 4096;

/// Why the PowerPC node's host side could not start.
#[derive(Debug, thiserror::Error)]
pub enum PpcServeError {
    #[error(transparent)]
    Served(#[from] ServedError),
    #[error(transparent)]
    Read(#[from] buslab_link::fs::ReadError),
    #[error(transparent)]
    Write(#[from] buslab_link::fs::WriteError),
    #[error("memory image {}: {errors}", path.display())]
    Image {
        path: PathBuf,
        errors: buslab_loader::SrecErrors,
    },
    #[error("cannot listen on the control socket {}: {source}", path.display())]
    Control {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("the bus server has stopped (no node {0} to serve)")]
    NoNode(String),
}

/// Runs `job` on node `node` in the bus thread and waits for its result (`None`: no such node,
/// or the server stopped).
fn on_node<R: Send + 'static>(
    bus: &Poster,
    node: &str,
    job: impl FnOnce(&mut PpcNode) -> R + Send + 'static,
) -> Option<R> {
    let (tx, rx) = mpsc::channel();
    let name = node.to_string();
    let posted = bus.post(move |bus: &mut VirtualBus| {
        let result = bus.device_mut::<PpcNode>(&name).map(job);
        let _ = tx.send(result);
    });
    if !posted {
        return None;
    }
    rx.recv_timeout(BUS_ANSWER).ok().flatten()
}

/// Reads a memory image file: an S-record file whose data lies in the node's program RAM.
pub fn read_image(path: &Path) -> Result<Option<MemoryImage>, PpcServeError> {
    let bytes = match read_limited(path, MAX_IMAGE_FILE) {
        Ok(b) => b,
        Err(e) if e.is_not_found() => return Ok(None),
        Err(e) => return Err(e.into()),
    };
    let image_error = |errors| PpcServeError::Image {
        path: path.to_path_buf(),
        errors,
    };
    let program = buslab_loader::srec::parse(&bytes).map_err(image_error)?;
    let errors = buslab_loader::MemoryMap::ppc403().check_program(&program);
    if !errors.is_empty() {
        return Err(image_error(errors));
    }
    Ok(Some(MemoryImage::from_program(&program)))
}

/// Keeps the node's memory image in a file: read at start, written whenever a load changed
/// it (the node waits for that before it reports), and once more when dropped.
pub struct MemoryStore {
    path: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// One look at the node: its image if it changed since `saved`, written, and the node told.
fn save_if_changed(bus: &Poster, node: &str, path: &Path, saved: &mut u64) -> bool {
    let known = *saved;
    let Some(changed) = on_node(bus, node, move |ppc| {
        let generation = ppc.state_generation();
        (generation > known).then(|| (generation, ppc.snapshot()))
    }) else {
        return false;
    };
    if let Some((generation, image)) = changed {
        match write_atomic(path, &PpcNode::file_bytes(&image)) {
            Ok(()) => {
                *saved = generation;
                let name = node.to_string();
                bus.post(move |bus: &mut VirtualBus| {
                    if let Some(ppc) = bus.device_mut::<PpcNode>(&name) {
                        ppc.persisted(generation);
                    }
                });
                tracing::debug!(
                    "memory image {} saved (generation {generation})",
                    path.display()
                );
            }
            Err(e) => tracing::warn!("{e}; the loader's report waits until it can be written"),
        }
    }
    true
}

impl MemoryStore {
    /// Restores node `node`'s memory from `path` if the file exists, writes it once (a file
    /// that cannot be written is an error now, not a lost load later), then keeps it.
    pub fn spawn(node: &str, bus: Poster, path: PathBuf) -> Result<Self, PpcServeError> {
        let image = read_image(&path)?;
        let restored = image.is_some();
        let snapshot = on_node(&bus, node, move |ppc| {
            if let Some(image) = image {
                ppc.restore_memory(image);
            }
            ppc.set_durable(true);
            (ppc.state_generation(), ppc.snapshot())
        })
        .ok_or_else(|| PpcServeError::NoNode(node.to_string()))?;
        let (generation, image) = snapshot;
        write_atomic(&path, &PpcNode::file_bytes(&image))?;
        on_node(&bus, node, move |ppc| ppc.persisted(generation));
        if restored {
            tracing::info!(
                "PowerPC memory restored from {}: {} bytes in {} ranges",
                path.display(),
                image.len(),
                image.ranges().len()
            );
        }
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            let node = node.to_string();
            let path = path.clone();
            std::thread::Builder::new()
                .name("ppc-memory".into())
                .spawn(move || {
                    let mut saved = generation;
                    while !stop.load(Ordering::SeqCst) {
                        if !save_if_changed(&bus, &node, &path, &mut saved) {
                            break;
                        }
                        std::thread::sleep(STORE_POLL);
                    }
                    // A load that finished meanwhile is not lost.
                    save_if_changed(&bus, &node, &path, &mut saved);
                })
                .map_err(|e| PpcServeError::Served(ServedError::Serve(e)))?
        };
        Ok(Self {
            path,
            stop,
            thread: Some(thread),
        })
    }

    /// The image file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for MemoryStore {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A control line, parsed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ControlCommand {
    Help,
    /// What the CPU runs.
    State,
    /// The last transfer the loader finished.
    Load,
    /// The ranges the memory holds.
    Ranges,
    Entry,
    Read {
        address: u32,
        len: usize,
    },
    /// The running program's RAM.
    Ram {
        address: u32,
        len: usize,
    },
    /// The registers of the running program (or of the last one).
    Regs,
    /// A power cycle: the resident firmware and MoniCAN.
    Reset,
}

/// What the control socket understands.
pub const CONTROL_HELP: &str = "commands: state | load | ranges | entry | read ADDR LEN (the loaded image; hex address, LEN 1..=4096) | ram ADDR LEN (the running program's RAM) | regs | reset | help";

fn hex_u32(text: &str) -> Option<u32> {
    let t = text
        .strip_prefix("0x")
        .or_else(|| text.strip_prefix("0X"))
        .unwrap_or(text);
    u32::from_str_radix(t, 16).ok()
}

impl ControlCommand {
    pub fn parse(line: &str) -> Result<Self, String> {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["help"] => Ok(Self::Help),
            ["state"] => Ok(Self::State),
            ["load"] => Ok(Self::Load),
            ["ranges"] => Ok(Self::Ranges),
            ["entry"] => Ok(Self::Entry),
            ["regs"] => Ok(Self::Regs),
            ["reset"] => Ok(Self::Reset),
            [command @ ("read" | "ram"), address, len] => {
                let address = hex_u32(address)
                    .ok_or_else(|| format!("address {address:?} is not a 32-bit hex number"))?;
                let len = len
                    .parse::<usize>()
                    .ok()
                    .filter(|l| (1..=MAX_READ).contains(l))
                    .ok_or_else(|| format!("length {len:?} is out of range 1..={MAX_READ}"))?;
                if u64::from(address) + len as u64 > 1 << 32 {
                    return Err(format!(
                        "0x{address:08X} + {len} runs past the end of the address space"
                    ));
                }
                Ok(if *command == "read" {
                    Self::Read { address, len }
                } else {
                    Self::Ram { address, len }
                })
            }
            _ => Err(format!("unknown command {line:?}; {CONTROL_HELP}")),
        }
    }
}

fn ranges_text(ranges: &[(u32, u32)]) -> String {
    if ranges.is_empty() {
        return "none".to_string();
    }
    ranges
        .iter()
        .map(|(a, b)| format!("{a:08X}-{b:08X}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// The reply to `command` from `node` (one line).
pub fn answer(node: &mut PpcNode, command: &ControlCommand) -> String {
    match command {
        ControlCommand::Help => CONTROL_HELP.to_string(),
        ControlCommand::State => match node.activity() {
            Activity::MoniCan => "monican".to_string(),
            Activity::Loading { received } => format!("loading {received}"),
            Activity::Saving => "saving".to_string(),
            Activity::Running { pc } => format!("running pc={pc:08X}"),
            Activity::Stopped { reason, pc } => format!("stopped: {reason} at {pc:08X}"),
            Activity::Exited { status } => format!("exited {status}"),
        },
        ControlCommand::Regs => node
            .registers()
            .map_or("none".to_string(), |r| buslab_ppc::registers_line(&r)),
        ControlCommand::Reset => {
            node.reset();
            "reset: MoniCAN started".to_string()
        }
        ControlCommand::Ram { address, len } => match node.ram(*address, *len) {
            Some(bytes) => hex(&bytes),
            None if node.running().is_none() => "error: no program runs".to_string(),
            None => format!(
                "error: {address:08X} + {len} is outside the RAM (0..{:08X})",
                buslab_ppc::board::RAM_SIZE
            ),
        },
        ControlCommand::Load => match node.last_load() {
            None => "none".to_string(),
            Some(l) if l.loaded => format!(
                "load {} ok ranges={} entry={}",
                l.number,
                ranges_text(&l.ranges).replace(' ', ","),
                l.entry.map_or("none".to_string(), |e| format!("{e:08X}"))
            ),
            Some(l) => {
                let (headline, details) = l
                    .report
                    .split_first()
                    .map_or(("", &[][..]), |(h, d)| (h.as_str(), d));
                let details: String = details
                    .iter()
                    .map(|s| s.trim())
                    .collect::<Vec<_>>()
                    .join("; ")
                    .chars()
                    .take(1000)
                    .collect();
                format!("load {} refused ({}): {details}", l.number, headline.trim())
            }
        },
        ControlCommand::Ranges => ranges_text(&node.memory().ranges()),
        ControlCommand::Entry => node
            .memory()
            .entry()
            .map_or("none".to_string(), |e| format!("{e:08X}")),
        ControlCommand::Read { address, len } => hex(&node.memory().read(*address, *len)),
    }
}

/// Serves node `node`'s control socket at `path`: one command a line, one reply line each
/// (`error: …` for what it cannot do).
pub fn serve_control(node: &str, bus: Poster, path: &Path) -> Result<ControlSocket, PpcServeError> {
    let node = node.to_string();
    let handler = move |line: &str| -> Option<String> {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            return None;
        }
        Some(match ControlCommand::parse(line) {
            Err(e) => format!("error: {e}"),
            Ok(command) => on_node(&bus, &node, move |ppc| answer(ppc, &command))
                .unwrap_or_else(|| "error: the bus server does not answer".to_string()),
        })
    };
    ControlSocket::bind(path, Arc::new(handler)).map_err(|source| PpcServeError::Control {
        path: path.to_path_buf(),
        source,
    })
}

/// What to serve besides the node.
#[derive(Clone, Debug, Default)]
pub struct PpcOptions {
    /// A link to the terminal's PTY.
    pub link: Option<PathBuf>,
    /// The memory image file (S-records).
    pub memory: Option<PathBuf>,
    /// The control socket.
    pub control: Option<PathBuf>,
}

/// The node's terminal, memory image and control socket while served.
pub struct ServedPpc {
    terminal: Served<PpcTerminal>,
    // Dropped after the terminal: the last save still reaches the node.
    store: Option<MemoryStore>,
    control: Option<ControlSocket>,
}

impl ServedPpc {
    /// The terminal's PTY.
    pub fn path(&self) -> &Path {
        self.terminal.path()
    }

    pub fn memory_file(&self) -> Option<&Path> {
        self.store.as_ref().map(MemoryStore::path)
    }

    pub fn control_socket(&self) -> Option<&Path> {
        self.control.as_ref().map(ControlSocket::path)
    }
}

/// Serves PowerPC node `node` on the server behind `bus`: its terminal, and what `options`
/// ask for.
pub fn serve(node: &str, bus: Poster, options: PpcOptions) -> Result<ServedPpc, PpcServeError> {
    let store = match options.memory {
        Some(path) => Some(MemoryStore::spawn(node, bus.clone(), path)?),
        None => None,
    };
    let control = match &options.control {
        Some(path) => Some(serve_control(node, bus.clone(), path)?),
        None => None,
    };
    let terminal = serve_terminal(node, bus, options.link)?;
    Ok(ServedPpc {
        terminal,
        store,
        control,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bus server with a PowerPC node alone on it, and its terminal side.
    fn terminal() -> (buslab_vbus::server::ServerHandle, PpcTerminal) {
        let mut config =
            buslab_vbus::server::ServerConfig::new("127.0.0.1:0".parse().unwrap(), 125_000);
        let node = PpcNode::new(buslab_monican::Config::default()).unwrap();
        config.devices.push(("ppc".into(), Box::new(node)));
        let server = buslab_vbus::server::spawn(config).unwrap();
        let terminal = PpcTerminal::new("ppc", server.poster());
        (server, terminal)
    }

    /// Polls at virtual times a second apart (the line has all the time it needs) until the
    /// terminal hands over bytes; each poll's bytes, as the pseudo-terminal gets them.
    fn next_bytes(t: &mut PpcTerminal, now: &mut Nanos) -> Vec<u8> {
        let start = std::time::Instant::now();
        loop {
            *now += Nanos::from_secs(1);
            let mut out = Vec::new();
            t.poll(*now, &mut out);
            if !out.is_empty() {
                return out;
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "the node's screen never came"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Issue 26 (10): screen updates went to the pseudo-terminal 8 bytes at a time, so a
    /// terminal read between two pieces showed half an update. Now each leaves whole, at the
    /// line's pace: none before the line had the time for all its bytes.
    #[test]
    fn screen_updates_leave_whole_at_the_lines_pace() {
        let (_server, mut t) = terminal();
        let mut now = Nanos::ZERO;
        let first = next_bytes(&mut t, &mut now);
        assert!(
            first.starts_with(b"\x1b[0m\x1b[H\x1b[2J"),
            "the whole screen"
        );
        assert!(first.ends_with(b"H"), "it ends with the cursor's place");
        // A key changes the command line: that update leaves once its bytes had their line
        // time.
        t.receive(now, b'3');
        let start = std::time::Instant::now();
        let mut out = Vec::new();
        while t.updates.is_empty() {
            assert!(start.elapsed() < Duration::from_secs(60));
            t.poll(now, &mut out);
            std::thread::sleep(Duration::from_millis(1));
        }
        let len = t.updates[0].len();
        t.poll(now + line_time(len) - Nanos::new(1), &mut out);
        assert!(out.is_empty(), "not before its last byte's time");
        t.poll(now + line_time(len), &mut out);
        assert_eq!(out.len(), len, "all of it at once");
    }

    /// Bytes the pseudo-terminal lost (nobody read it) leave the terminal showing something
    /// else than the node's screen thinks: the next update is the whole screen again.
    #[test]
    fn after_lost_output_the_whole_screen_is_sent_again() {
        let (_server, mut t) = terminal();
        let mut now = Nanos::ZERO;
        next_bytes(&mut t, &mut now);
        t.output_lost(now);
        let mut again = next_bytes(&mut t, &mut now);
        while !again.windows(4).any(|w| w == b"\x1b[2J") {
            // An update asked for before the loss may come first.
            again = next_bytes(&mut t, &mut now);
        }
        assert!(again.starts_with(b"\x1b[0m\x1b[H\x1b[2J"), "{again:?}");
    }

    #[test]
    fn control_lines_are_parsed_and_answered() {
        assert_eq!(
            ControlCommand::parse("read 0x32000 16"),
            Ok(ControlCommand::Read {
                address: 0x32000,
                len: 16
            })
        );
        assert!(
            ControlCommand::parse("read 32000 5000")
                .unwrap_err()
                .contains("1..=4096")
        );
        assert!(
            ControlCommand::parse("read FFFFFFFF 2")
                .unwrap_err()
                .contains("past the end")
        );
        assert!(
            ControlCommand::parse("peek")
                .unwrap_err()
                .starts_with("unknown command")
        );
        let mut node = PpcNode::new(buslab_monican::Config::default()).unwrap();
        assert_eq!(answer(&mut node, &ControlCommand::State), "monican");
        assert_eq!(answer(&mut node, &ControlCommand::Load), "none");
        assert_eq!(answer(&mut node, &ControlCommand::Ranges), "none");
        assert_eq!(answer(&mut node, &ControlCommand::Regs), "none");
        assert_eq!(
            answer(
                &mut node,
                &ControlCommand::Ram {
                    address: 0x32000,
                    len: 4
                }
            ),
            "error: no program runs"
        );
        assert_eq!(
            ControlCommand::parse("ram 32000 4096").unwrap(),
            ControlCommand::Ram {
                address: 0x32000,
                len: 4096
            }
        );
        assert_eq!(ControlCommand::parse("reset"), Ok(ControlCommand::Reset));
        let mut image = MemoryImage::new();
        image.write(0x32000, &[0xAB, 0xCD]);
        node.restore_memory(image);
        assert_eq!(
            answer(&mut node, &ControlCommand::Ranges),
            "00032000-00032001"
        );
        assert_eq!(
            answer(
                &mut node,
                &ControlCommand::Read {
                    address: 0x31FFF,
                    len: 4
                }
            ),
            "00ABCD00"
        );
    }

    #[test]
    fn a_bad_image_file_names_its_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ppc.s37");
        assert!(read_image(&path).unwrap().is_none());
        std::fs::write(&path, "S00600004844521B\nS1030000FD\n").unwrap();
        let e = read_image(&path).unwrap_err().to_string();
        assert!(e.contains("line 2: checksum"), "{e}");
        let flash = buslab_loader::srec::write(b"", [(0xFFFE_0000, &[1u8][..])], None);
        std::fs::write(&path, flash).unwrap();
        assert!(read_image(&path).unwrap_err().to_string().contains("flash"));
    }
}
