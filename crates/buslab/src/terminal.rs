//! The user's own terminal for the full-screen commands (`monican`, `monitor`): raw mode on
//! the alternate screen, restored however the command ends, and the keys as they come.

use std::io::Read;
use std::sync::mpsc::{self, Receiver};

use anyhow::Context;

/// Raw mode on the alternate screen until dropped.
pub struct RawScreen;

impl RawScreen {
    pub fn enter(cursor: Cursor) -> anyhow::Result<Self> {
        crossterm::terminal::enable_raw_mode().context("cannot put the terminal in raw mode")?;
        // From here on, dropping the guard restores the terminal, even on the errors below.
        let screen = RawScreen;
        crossterm::execute!(std::io::stdout(), crossterm::terminal::EnterAlternateScreen)
            .context("cannot switch to the alternate screen")?;
        if cursor == Cursor::Hidden {
            crossterm::execute!(std::io::stdout(), crossterm::cursor::Hide)
                .context("cannot hide the cursor")?;
        }
        Ok(screen)
    }
}

impl Drop for RawScreen {
    fn drop(&mut self) {
        let _ = crossterm::execute!(
            std::io::stdout(),
            crossterm::cursor::Show,
            crossterm::terminal::LeaveAlternateScreen
        );
        let _ = crossterm::terminal::disable_raw_mode();
    }
}

/// Whether the terminal's own cursor shows while the command runs.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Cursor {
    /// The application draws where the cursor is (MoniCAN's VT100 screen).
    Shown,
    /// The application draws its own widgets (ratatui).
    Hidden,
}

/// Bytes from the terminal as they come (a thread blocked in `read`; it ends with the
/// process or when the receiver is dropped and the next key arrives).
pub fn read_keys() -> Receiver<Vec<u8>> {
    let (tx, rx) = mpsc::sync_channel(64);
    std::thread::spawn(move || {
        let mut stdin = std::io::stdin();
        let mut buf = [0u8; 256];
        while let Ok(n) = stdin.read(&mut buf) {
            if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                break;
            }
        }
    });
    rx
}
