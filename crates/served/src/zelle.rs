//! The ZELLE cell served on a pseudo-terminal at 9600 8N2.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

pub use crate::analog::load_source;
use buslab_device::Nanos;
use buslab_link::fs::read_text_limited;
use buslab_link::{Handle, LineHandler, Serve, Served, ServedError};
use buslab_zelle::analog::{Source, SourceSpec};
use buslab_zelle::control::{self, ControlCommand};
use buslab_zelle::timing::LINE;
use buslab_zelle::{BatteryRam, Cell, SetupRule, TraceEvent};

use crate::ServeError;

/// How often the state file is looked at (and written if the RAM changed).
pub const SAVE_EVERY: Duration = Duration::from_secs(1);

/// The largest state file read (the RAM as hex is about 70 KB).
const MAX_STATE_FILE: u64 = 1 << 20;

/// What to serve.
#[derive(Clone, Debug, Default)]
pub struct CellOptions {
    /// The battery-backed RAM: read at start (missing = a fresh cell), written back at once,
    /// when it changes, at `power off`, `save` and stop.
    pub state: Option<PathBuf>,
    /// A symlink to the PTY.
    pub link: Option<PathBuf>,
    /// `(channel, source)` pairs.
    pub analog: Vec<(u8, Source)>,
    /// Trace at most this many instructions a second of the cell's time
    /// ([`ServedCell::take_trace`]).
    pub trace: Option<u32>,
}

/// A cell served on a PTY by a background thread; stopped (and its state saved) when dropped.
pub struct ServedCell {
    served: Served<Cell>,
}

/// What a served cell does with a byte sent within the 1 ms set-up after commands 1, 2, 3 and
/// 5 unless told otherwise: it keeps it (and counts it). A pseudo-terminal does not carry the
/// line's timing: a client's drain returns before its byte has crossed the emulated line, and
/// a server late on a loaded host reads a command and the byte sent after the pause together,
/// so the cell's rule would lose bytes of clients that keep the pause.
pub const SERVED_SETUP_RULE: SetupRule = SetupRule::Keep;

impl ServedCell {
    /// Reads the state file, feeds the inputs, and serves the cell on a new PTY, keeping bytes
    /// sent within a set-up ([`SERVED_SETUP_RULE`]).
    pub fn spawn(options: CellOptions) -> Result<Self, ServeError> {
        Self::spawn_with_setup_rule(options, SERVED_SETUP_RULE)
    }

    /// [`spawn`](Self::spawn), with `rule` for bytes sent within a set-up
    /// ([`SetupRule::Lose`]: as the cell does, for clients that pause far beyond 1 ms after
    /// their drain on a host that reads the PTY promptly).
    pub fn spawn_with_setup_rule(
        options: CellOptions,
        rule: SetupRule,
    ) -> Result<Self, ServeError> {
        let ram = match &options.state {
            Some(path) => {
                let mut ram = load_state(path)?;
                crate::replay_journals::<Cell>(path, &mut ram)?;
                ram
            }
            None => BatteryRam::default(),
        };
        let mut cell = Cell::new(ram);
        cell.set_setup_rule(rule);
        for (channel, source) in &options.analog {
            cell.set_analog(*channel, source.clone())?;
        }
        cell.set_trace(options.trace);
        let served = Serve::new(cell, LINE)
            .name("zelle")
            .link(options.link)
            .persist(options.state, "state file", SAVE_EVERY)
            .spawn()?;
        Ok(Self { served })
    }

    /// The PTY path clients open.
    pub fn path(&self) -> &Path {
        self.served.path()
    }

    /// Runs `work` on the cell in its serve thread at the current virtual time.
    pub fn with<T: Send + 'static>(
        &self,
        work: impl FnOnce(&mut Cell, Nanos) -> T + Send + 'static,
    ) -> Result<T, ServedError> {
        self.served.with(work)
    }

    /// The trace lines of the programs run since the last call (none unless
    /// [`CellOptions::trace`] was given).
    pub fn take_trace(&self) -> Result<Vec<TraceEvent>, ServedError> {
        self.served.with(|cell, _| {
            let mut lines = Vec::new();
            cell.take_trace(&mut lines);
            lines
        })
    }

    /// The control lines of this cell, for stdin and a control socket.
    pub fn control(&self) -> CellControl {
        CellControl {
            handle: self.served.handle(),
        }
    }

    /// Stops serving, saves the state file, waits for the thread.
    pub fn stop(self) -> Result<(), ServedError> {
        self.served.stop()
    }
}

/// Takes control lines for a served cell (see [`buslab_zelle::control`]); cheap to clone.
#[derive(Clone)]
pub struct CellControl {
    handle: Handle<Cell>,
}

impl CellControl {
    /// Handles one control line: CSV replays are read here, `save` and `power off` write the
    /// state file. Returns the reply line (`ok …` or `error: …`); `None` for blank lines and
    /// comments.
    pub fn line(&self, line: &str) -> Option<String> {
        let cmd = match ControlCommand::parse(line) {
            Ok(None) => return None,
            Ok(Some(cmd)) => cmd,
            Err(e) => return Some(format!("error: {e}")),
        };
        let cmd = match cmd {
            ControlCommand::Analog { channel, source } => match load_source(source) {
                Ok(s) => ControlCommand::Analog {
                    channel,
                    source: SourceSpec::Ready(s),
                },
                Err(e) => return Some(format!("error: {e}")),
            },
            other => other,
        };
        let save = matches!(cmd, ControlCommand::Save | ControlCommand::PowerOff);
        let mut reply = match self
            .handle
            .with(move |cell, now| control::apply(cell, now, &cmd))
        {
            Ok(reply) => reply,
            Err(e) => return Some(format!("error: {e}")),
        };
        if save {
            match self.handle.save() {
                Ok(Some(path)) => reply.push_str(&format!("; saved {}", path.display())),
                Ok(None) => {}
                Err(e) => reply.push_str(&format!("; error: {e}")),
            }
        }
        Some(if reply.starts_with("error") {
            reply
        } else {
            format!("ok {reply}")
        })
    }

    /// [`line`](Self::line) as a handler for [`buslab_link::ControlSocket`].
    pub fn handler(&self) -> Arc<LineHandler> {
        let control = self.clone();
        Arc::new(move |line: &str| control.line(line))
    }
}

/// The battery-backed RAM in `path`; a missing file is a fresh cell.
pub fn load_state(path: &Path) -> Result<BatteryRam, ServeError> {
    match read_text_limited(path, MAX_STATE_FILE) {
        Ok(text) => BatteryRam::from_state_file(&text).map_err(|source| ServeError::State {
            path: path.to_path_buf(),
            source,
        }),
        Err(e) if e.is_not_found() => Ok(BatteryRam::default()),
        Err(e) => Err(e.into()),
    }
}

/// `CH=SOURCE` as `serve --analog` takes it, with its CSV replay file read.
pub fn analog_input(arg: &str) -> Result<(u8, Source), ServeError> {
    crate::analog::channel_input(arg, buslab_zelle::analog::CHANNELS)
}
