//! `--plot FILE.svg` of `sim`, `zelle measure`, `cpu196 record` and `log info`, and `buslab
//! plot` (DBC signals of a log, [`signals`]): the path is checked before the work starts (a
//! measurement is not thrown away for a typo), the figure is drawn by `buslab-plot` and
//! written atomically.

mod signals;

pub use signals::{Args, run};

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use anyhow::{Context, bail};
use buslab_link::fs::write_atomic;
use buslab_logs::Timestamp;
use buslab_plot::{Figure, Panel, Series};

use crate::units::Human;

/// Refuses a `--plot` path that cannot be written: not ending in `.svg`, a folder, in a folder
/// that does not exist or cannot be written to.
pub fn check_target(path: &Path) -> anyhow::Result<()> {
    check_option_target("--plot", path)
}

/// [`check_target`] for the figure of `option` (named in the errors).
pub fn check_option_target(option: &str, path: &Path) -> anyhow::Result<()> {
    let shown = path.display();
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        bail!("{option} {shown}: the figure is SVG; give a file name ending in .svg");
    }
    if path.is_dir() {
        bail!("{option} {shown} is a folder; give a file name such as {shown}/plot.svg");
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!("{option} {shown}: folder {} does not exist", dir.display());
    }
    // The figure is written to a temporary file there and renamed: try that now.
    tempfile::Builder::new()
        .prefix(".buslab-plot-check.")
        .tempfile_in(dir)
        .with_context(|| format!("{option} {shown}: cannot write in {}", dir.display()))?;
    Ok(())
}

/// Draws `figure` and writes it to `path` atomically.
pub fn write(figure: &Figure, path: &Path) -> anyhow::Result<()> {
    write_option(figure, "--plot", path)
}

/// [`write`] for the figure of `option` (named in the errors).
pub fn write_option(figure: &Figure, option: &str, path: &Path) -> anyhow::Result<()> {
    let svg = figure
        .to_svg()
        .with_context(|| format!("{option} {}: nothing written", path.display()))?;
    write_atomic(path, svg.as_bytes())?;
    tracing::info!("figure written to {}", path.display());
    Ok(())
}

/// Bus load over time per interface, for `log info --plot`: the bits of each frame added to
/// the time window it falls in. Windows start at 1 ms and double (neighbours merged) whenever
/// the log is longer than [`LoadWindows::MAX_WINDOWS`] of them, so memory stays bounded for
/// any log length.
pub struct LoadWindows {
    origin: Option<Timestamp>,
    width: Duration,
    bits: BTreeMap<String, Vec<u64>>,
    end: Duration,
}

impl LoadWindows {
    /// At most this many windows: several frames each on a busy bus, a few pixels each.
    const MAX_WINDOWS: usize = 250;

    pub fn new() -> Self {
        LoadWindows {
            origin: None,
            width: Duration::from_millis(1),
            bits: BTreeMap::new(),
            end: Duration::ZERO,
        }
    }

    /// A frame of `bits` bits on the wire (stuffing and intermission included) at `at` on
    /// `interface`. The first entry of the log starts the time axis; an entry stamped before
    /// it (a log out of order) counts in the first window.
    pub fn add(&mut self, interface: &str, at: Timestamp, bits: u64) {
        let origin = *self.origin.get_or_insert(at);
        let since = at.saturating_since(origin);
        self.end = self.end.max(since);
        while self.window_of(since) >= Self::MAX_WINDOWS {
            self.width *= 2;
            for windows in self.bits.values_mut() {
                *windows = windows.chunks(2).map(|pair| pair.iter().sum()).collect();
            }
        }
        let index = self.window_of(since);
        let windows = match self.bits.get_mut(interface) {
            Some(w) => w,
            None => self.bits.entry(interface.to_owned()).or_default(),
        };
        if windows.len() <= index {
            windows.resize(index + 1, 0);
        }
        windows[index] += bits;
    }

    fn window_of(&self, since: Duration) -> usize {
        usize::try_from(since.as_nanos() / self.width.as_nanos()).unwrap_or(usize::MAX)
    }

    /// The figure: one line per interface, the load of each window in percent of `bitrate`,
    /// drawn at the window's middle (time from the log's first entry).
    pub fn figure(&self, title: String, bitrate: u32) -> Figure {
        let width_s = self.width.as_secs_f64();
        let capacity = width_s * f64::from(bitrate.max(1));
        let windows = self.window_of(self.end) + 1;
        let mut panel = Panel::new(
            format!("bus load per {} window", Human(self.width)),
            "load",
            Some("%"),
        );
        panel.covers = Some((0.0, 100.0));
        panel.series = self
            .bits
            .iter()
            .map(|(name, bits)| {
                let load = |i: usize| bits.get(i).map_or(0.0, |&b| 100.0 * b as f64 / capacity);
                Series::from_points(
                    name.as_str(),
                    (0..windows).map(|i| ((i as f64 + 0.5) * width_s, load(i))),
                )
            })
            .collect();
        Figure {
            panels: vec![panel],
            ..Figure::new(title)
        }
    }
}

impl Default for LoadWindows {
    fn default() -> Self {
        Self::new()
    }
}
