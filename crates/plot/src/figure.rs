//! What a figure shows: panels of series over time, bands, state lanes.

use crate::thin;

/// A stack of panels over one time axis, with optional state lanes below.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// The line at the top.
    pub title: String,
    pub panels: Vec<Panel>,
    /// One lane per node, coloured by state, below the panels.
    pub lanes: Option<StateLanes>,
    /// Time intervals shaded across every panel and the lanes (e.g. a fault), in seconds.
    pub time_bands: Vec<Band>,
    /// The time axis, in seconds; `None`: from the first to the last point.
    pub time_range: Option<(f64, f64)>,
    /// Width in pixels (the height follows from the panels and lanes).
    pub width: u32,
}

impl Figure {
    /// An empty figure 1000 pixels wide.
    pub fn new(title: impl Into<String>) -> Self {
        Figure {
            title: title.into(),
            panels: Vec::new(),
            lanes: None,
            time_bands: Vec::new(),
            time_range: None,
            width: 1000,
        }
    }
}

/// One chart: series sharing a value axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// The line above the chart, e.g. `transmit error counter (TEC)`.
    pub caption: String,
    /// What the value axis shows, e.g. `voltage`; the axis reads `voltage (V)`.
    pub quantity: String,
    /// The unit of the values, e.g. `V`, `%`, `frames/s`; `None` for plain counts.
    pub unit: Option<String>,
    pub series: Vec<Series>,
    /// Value regions shaded across the chart (e.g. TEC 128..256 "error-passive").
    pub bands: Vec<Band>,
    /// The value axis covers at least this range (and always every point).
    pub covers: Option<(f64, f64)>,
}

impl Panel {
    pub fn new(
        caption: impl Into<String>,
        quantity: impl Into<String>,
        unit: Option<&str>,
    ) -> Self {
        Panel {
            caption: caption.into(),
            quantity: quantity.into(),
            unit: unit.map(str::to_owned),
            series: Vec::new(),
            bands: Vec::new(),
            covers: None,
        }
    }

    /// The value axis title: `quantity (unit)`.
    pub fn axis_title(&self) -> String {
        match &self.unit {
            Some(unit) => format!("{} ({unit})", self.quantity),
            None => self.quantity.clone(),
        }
    }
}

/// A named line: points `(time in seconds, value)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    name: String,
    points: Vec<(f64, f64)>,
    /// Non-finite points given (not drawn).
    skipped: u64,
}

/// The most points a series keeps; beyond it, it keeps each stretch's extremes (see
/// [`Series::push`]).
pub const MAX_POINTS: usize = 100_000;

impl Series {
    pub fn new(name: impl Into<String>) -> Self {
        Series {
            name: name.into(),
            points: Vec::new(),
            skipped: 0,
        }
    }

    /// A series of these points (see [`push`](Self::push)).
    pub fn from_points(
        name: impl Into<String>,
        points: impl IntoIterator<Item = (f64, f64)>,
    ) -> Self {
        let mut s = Series::new(name);
        for (x, y) in points {
            s.push(x, y);
        }
        s
    }

    /// Adds a point. A point with a non-finite coordinate cannot be drawn: it is counted in
    /// [`skipped`](Self::skipped) and left out. When the series holds [`MAX_POINTS`], it is
    /// thinned to the first, lowest, highest and last point of each of `MAX_POINTS / 8` equal
    /// time slices, so memory stays bounded and every peak stays visible.
    pub fn push(&mut self, x: f64, y: f64) {
        if !(x.is_finite() && y.is_finite()) {
            self.skipped += 1;
            return;
        }
        if self.points.len() >= MAX_POINTS {
            self.points = thin::envelope(&self.points, MAX_POINTS / 8);
        }
        self.points.push((x, y));
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// How many points were left out because a coordinate was not finite.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }
}

/// An interval shaded across a chart: of time (seconds) in [`Figure::time_bands`], of values
/// in [`Panel::bands`]. `to` may be infinite (up to the axis' end).
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    pub from: f64,
    pub to: f64,
    /// Named in the legend.
    pub label: String,
    pub shade: Shade,
}

impl Band {
    pub fn new(from: f64, to: f64, label: impl Into<String>, shade: Shade) -> Self {
        Band {
            from,
            to,
            label: label.into(),
            shade,
        }
    }
}

/// The fill colours of bands and lanes, by meaning.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shade {
    /// All well (green).
    Good,
    /// Worth a look (yellow).
    Caution,
    /// Degraded (orange).
    Warning,
    /// Failed (red).
    Danger,
    /// Something done to the system, e.g. a fault injected (blue-grey).
    Event,
}

/// One lane per node, coloured by the node's state over time.
#[derive(Clone, Debug, PartialEq)]
pub struct StateLanes {
    /// The line above the lanes, e.g. `fault-confinement state`.
    pub caption: String,
    /// The states a span may be in, with their colour; named in the legend.
    pub states: Vec<(String, Shade)>,
    pub lanes: Vec<Lane>,
}

/// One node's states: spans `(from, to, state)` in seconds, `state` an index into
/// [`StateLanes::states`].
#[derive(Clone, Debug, PartialEq)]
pub struct Lane {
    pub name: String,
    spans: Vec<(f64, f64, usize)>,
}

impl Lane {
    pub fn new(name: impl Into<String>) -> Self {
        Lane {
            name: name.into(),
            spans: Vec::new(),
        }
    }

    /// The node is in `state` from `at` on (until the next call or `end`): extends the last
    /// span when the state is the same.
    pub fn enter(&mut self, at: f64, state: usize) {
        if !at.is_finite() {
            return;
        }
        if let Some(last) = self.spans.last_mut() {
            last.1 = last.1.max(at);
            if last.2 == state {
                return;
            }
        }
        self.spans.push((at, at, state));
    }

    /// The last span lasts until `end`.
    pub fn end(&mut self, end: f64) {
        if let Some(last) = self.spans.last_mut()
            && end.is_finite()
        {
            last.1 = last.1.max(end);
        }
    }

    pub fn spans(&self) -> &[(f64, f64, usize)] {
        &self.spans
    }
}
