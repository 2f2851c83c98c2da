//! `--plot FILE.svg` of `sim`, `zelle measure` and `cpu196 record`: the path is
//! checked before the work starts (a measurement is not thrown away for a typo), the figure is
//! drawn by `buslab-plot` and written atomically.

use std::path::Path;

use anyhow::{Context, bail};
use buslab_link::fs::write_atomic;
use buslab_plot::Figure;

/// Refuses a `--plot` path that cannot be written: not ending in `.svg`, a folder, in a folder
/// that does not exist or cannot be written to.
pub fn check_target(path: &Path) -> anyhow::Result<()> {
    let shown = path.display();
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        bail!("--plot {shown}: the figure is SVG; give a file name ending in .svg");
    }
    if path.is_dir() {
        bail!("--plot {shown} is a folder; give a file name such as {shown}/plot.svg");
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!("--plot {shown}: folder {} does not exist", dir.display());
    }
    // The figure is written to a temporary file there and renamed: try that now.
    tempfile::Builder::new()
        .prefix(".buslab-plot-check.")
        .tempfile_in(dir)
        .with_context(|| format!("--plot {shown}: cannot write in {}", dir.display()))?;
    Ok(())
}

/// Draws `figure` and writes it to `path` atomically.
pub fn write(figure: &Figure, path: &Path) -> anyhow::Result<()> {
    let svg = figure
        .to_svg()
        .with_context(|| format!("--plot {}: nothing written", path.display()))?;
    write_atomic(path, svg.as_bytes())?;
    tracing::info!("figure written to {}", path.display());
    Ok(())
}
