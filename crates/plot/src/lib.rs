//! Time series as SVG figures, for the pictures `buslab` draws (`sim --plot`,
//! `zelle measure --plot`, `cpu196 record --plot`, `log info --plot`).
//!
//! A [`Figure`] is a stack of [`Panel`]s sharing one time axis (x in seconds; the axis shows
//! s, ms or µs, whichever suits the span), optionally with [`StateLanes`] below them (one lane
//! per node, coloured by state). A panel holds named [`Series`] (one colour each, named in the
//! panel's legend), horizontal [`Band`]s (value regions such as "error-passive") and the
//! figure's time bands (intervals such as "wire cut"). Axis titles carry their unit.
//!
//! [`Figure::to_svg`] draws it with `plotters`' SVG backend: text is emitted as SVG `<text>`
//! and laid out by the viewer, so no font file or system library is needed. Series keep a
//! bounded number of points (see [`Series::push`]) and are drawn with at most a few points per
//! pixel column, keeping each extreme, so a long run still gives a small file with the same
//! shape.
//!
//! Nothing here does I/O: the caller writes the string where it wants.

mod figure;
#[cfg(feature = "inspect")]
pub mod inspect;
mod render;
mod thin;
mod time_unit;

pub use figure::{Band, Figure, Lane, MAX_POINTS, Panel, Series, Shade, StateLanes};
pub use time_unit::TimeUnit;

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Every series (and lane) of the figure is empty: there is nothing to draw.
    #[error("no data to plot: {0}")]
    NoData(String),
    /// The figure has no panel and no lanes.
    #[error("the figure has no panel")]
    NoPanel,
    /// plotters refused to draw (an internal error: every value is checked before).
    #[error("drawing the figure: {0}")]
    Draw(String),
}
