//! Drawing a [`Figure`] with plotters' SVG backend.

use plotters::coord::Shift;
use plotters::coord::ranged1d::SegmentValue;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::figure::{Band, Figure, Lane, Panel, Shade, StateLanes};
use crate::{PlotError, TimeUnit, thin};

/// Series colours (Tableau 10), in order.
const PALETTE: [RGBColor; 10] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x7f, 0x7f, 0x7f),
    RGBColor(0xbc, 0xbd, 0x22),
    RGBColor(0x17, 0xbe, 0xcf),
];

const FONT: &str = "sans-serif";
const TITLE_HEIGHT: u32 = 40;
const PANEL_HEIGHT: u32 = 260;
const LANE_HEIGHT: u32 = 24;
/// Caption and time axis of the lanes.
const LANES_EXTRA: u32 = 90;
/// The legend column right of each chart: at least this wide, wider for long names.
const LEGEND_MIN_WIDTH: u32 = 180;
/// Beyond it a name runs out of the picture (it is still in the file).
const LEGEND_MAX_WIDTH: u32 = 800;
/// A generous width of one character of the legend's 14-pixel font (the viewer lays the text
/// out; this only keeps long names inside the picture).
const LEGEND_CHAR_WIDTH: u32 = 8;
/// The least width of a chart.
const CHART_MIN_WIDTH: u32 = 700;
const LEGEND_LINE: i32 = 20;

fn shade_color(shade: Shade) -> RGBAColor {
    match shade {
        Shade::Good => RGBColor(0x2c, 0xa0, 0x2c).mix(0.25),
        Shade::Caution => RGBColor(0xff, 0xd4, 0x2a).mix(0.35),
        Shade::Warning => RGBColor(0xff, 0x8c, 0x1a).mix(0.35),
        Shade::Danger => RGBColor(0xe0, 0x30, 0x30).mix(0.35),
        Shade::Event => RGBColor(0x5a, 0x6f, 0x98).mix(0.25),
    }
}

/// The stronger colour of a lane span.
fn lane_color(shade: Shade) -> RGBAColor {
    let c = shade_color(shade);
    RGBAColor(c.0, c.1, c.2, 0.75)
}

fn draw_error<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> PlotError {
    PlotError::Draw(e.to_string())
}

impl Figure {
    /// The figure as an SVG document. Fails with [`PlotError::NoData`] when every series and
    /// lane is empty.
    pub fn to_svg(&self) -> Result<String, PlotError> {
        if self.panels.is_empty() && self.lanes.is_none() {
            return Err(PlotError::NoPanel);
        }
        let (t0, t1) = self.time_span().ok_or_else(|| {
            PlotError::NoData(format!("every series of \"{}\" is empty", self.title))
        })?;
        let unit = TimeUnit::for_span(t1 - t0);
        // Each chart is tall enough for its legend.
        let legend_height = |entries: usize| 50 + LEGEND_LINE as u32 * entries as u32;
        let panel_heights: Vec<u32> = self
            .panels
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let bands = if i == 0 { self.time_bands.len() } else { 0 };
                PANEL_HEIGHT.max(legend_height(p.series.len() + p.bands.len() + bands))
            })
            .collect();
        let lanes_height = self.lanes.as_ref().map_or(0, |l| {
            (LANES_EXTRA + LANE_HEIGHT * l.lanes.len().max(1) as u32)
                .max(legend_height(l.states.len()))
        });
        let height = TITLE_HEIGHT + panel_heights.iter().sum::<u32>() + lanes_height;
        let legend_width = self.legend_width();
        let width = self.width.max(legend_width + CHART_MIN_WIDTH);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
            root.fill(&WHITE).map_err(draw_error)?;
            let root = root
                .titled(&self.title, (FONT, 22).into_font())
                .map_err(draw_error)?;
            let mut breaks: Vec<u32> = panel_heights
                .iter()
                .scan(0, |top, h| {
                    *top += h;
                    Some(*top)
                })
                .collect();
            if self.lanes.is_none() {
                breaks.pop();
            }
            let areas = root.split_by_breakpoints::<u32, u32, _, _>([], breaks);
            let axis = TimeAxis { t0, t1, unit };
            for (i, (panel, area)) in self.panels.iter().zip(&areas).enumerate() {
                self.draw_panel(panel, area, &axis, legend_width, i == 0)?;
            }
            if let (Some(lanes), Some(area)) = (&self.lanes, areas.get(self.panels.len())) {
                self.draw_lanes(lanes, area, &axis, legend_width)?;
            }
            root.present().map_err(draw_error)?;
        }
        Ok(svg)
    }

    /// The legend column's width: room for the longest name.
    fn legend_width(&self) -> u32 {
        let panels = self.panels.iter().flat_map(|p| {
            let series = p
                .series
                .iter()
                .map(|s| s.name().chars().count() + " (no data)".len());
            series.chain(p.bands.iter().map(|b| b.label.chars().count()))
        });
        let bands = self.time_bands.iter().map(|b| b.label.chars().count());
        let states = self
            .lanes
            .iter()
            .flat_map(|l| l.states.iter().map(|s| s.0.chars().count()));
        let longest = panels.chain(bands).chain(states).max().unwrap_or(0);
        let longest = u32::try_from(longest).unwrap_or(u32::MAX);
        (48u32.saturating_add(longest.saturating_mul(LEGEND_CHAR_WIDTH)))
            .clamp(LEGEND_MIN_WIDTH, LEGEND_MAX_WIDTH)
    }

    /// First and last instant shown, in seconds; `None` when there is no data at all.
    fn time_span(&self) -> Option<(f64, f64)> {
        let series = self
            .panels
            .iter()
            .flat_map(|p| &p.series)
            .flat_map(|s| s.points().iter().map(|p| p.0));
        let lanes = self
            .lanes
            .iter()
            .flat_map(|l| &l.lanes)
            .flat_map(|l| l.spans().iter().flat_map(|s| [s.0, s.1]));
        let (lo, hi) = series
            .chain(lanes)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
        if lo > hi {
            return None;
        }
        let (lo, hi) = match self.time_range {
            Some((a, b)) if a.is_finite() && b.is_finite() && a < b => (a, b),
            _ => (lo, hi),
        };
        // A single instant still gets an axis.
        Some(if hi > lo { (lo, hi) } else { (lo, lo + 1.0) })
    }

    fn draw_panel(
        &self,
        panel: &Panel,
        area: &DrawingArea<SVGBackend, Shift>,
        axis: &TimeAxis,
        legend_width: u32,
        first: bool,
    ) -> Result<(), PlotError> {
        let (chart_area, legend_area) =
            area.split_horizontally(area.dim_in_pixel().0 - legend_width);
        let (y0, y1) = value_span(panel);
        let mut chart = ChartBuilder::on(&chart_area)
            .caption(&panel.caption, (FONT, 17).into_font())
            .margin(8)
            .x_label_area_size(42)
            .y_label_area_size(72)
            .build_cartesian_2d(axis.x(axis.t0)..axis.x(axis.t1), y0..y1)
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc(axis.title())
            .y_desc(panel.axis_title())
            .axis_desc_style((FONT, 15))
            .label_style((FONT, 13))
            .x_label_formatter(&tick_label)
            .y_label_formatter(&tick_label)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(draw_error)?;
        let mut legend = Vec::new();
        for band in &panel.bands {
            let (from, to) = (band.from.max(y0), band.to.min(y1));
            if from < to {
                let (x0, x1) = (axis.x(axis.t0), axis.x(axis.t1));
                chart
                    .draw_series([Rectangle::new(
                        [(x0, from), (x1, to)],
                        shade_color(band.shade).filled(),
                    )])
                    .map_err(draw_error)?;
            }
            legend.push(Entry::Band(band));
        }
        for band in &self.time_bands {
            let (from, to) = (band.from.max(axis.t0), band.to.min(axis.t1));
            if from < to {
                chart
                    .draw_series([Rectangle::new(
                        [(axis.x(from), y0), (axis.x(to), y1)],
                        shade_color(band.shade).filled(),
                    )])
                    .map_err(draw_error)?;
            }
            if first {
                legend.push(Entry::Band(band));
            }
        }
        // Drawn with a few points per pixel column at most: a small file, the same picture.
        let columns = chart_area.dim_in_pixel().0 as usize;
        for (i, series) in panel.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let points: Vec<(f64, f64)> = thin::envelope(series.points(), columns)
                .into_iter()
                .map(|(t, v)| (axis.x(t), v))
                .collect();
            if points.len() == 1 {
                chart
                    .draw_series([Circle::new(points[0], 3, color.filled())])
                    .map_err(draw_error)?;
            } else if !points.is_empty() {
                chart
                    .draw_series(LineSeries::new(points, color.stroke_width(2)))
                    .map_err(draw_error)?;
            }
            legend.push(Entry::Line {
                name: series.name(),
                color,
                empty: series.is_empty(),
            });
        }
        draw_legend(&legend_area, &legend)
    }

    fn draw_lanes(
        &self,
        lanes: &StateLanes,
        area: &DrawingArea<SVGBackend, Shift>,
        axis: &TimeAxis,
        legend_width: u32,
    ) -> Result<(), PlotError> {
        let (chart_area, legend_area) =
            area.split_horizontally(area.dim_in_pixel().0 - legend_width);
        let n = lanes.lanes.len().max(1) as i32;
        let names: Vec<&str> = lanes.lanes.iter().map(|l| l.name.as_str()).collect();
        let lane_name = |v: &SegmentValue<i32>| match v {
            // Lane 0 is at the top.
            SegmentValue::CenterOf(i) => usize::try_from(n - 1 - i)
                .ok()
                .and_then(|i| names.get(i))
                .map_or(String::new(), |s| s.to_string()),
            _ => String::new(),
        };
        let mut chart = ChartBuilder::on(&chart_area)
            .caption(&lanes.caption, (FONT, 17).into_font())
            .margin(8)
            .x_label_area_size(42)
            .y_label_area_size(72)
            .build_cartesian_2d(
                axis.x(axis.t0)..axis.x(axis.t1),
                (0..n - 1).into_segmented(),
            )
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc(axis.title())
            .axis_desc_style((FONT, 15))
            .label_style((FONT, 13))
            .x_label_formatter(&tick_label)
            .y_label_formatter(&lane_name)
            .y_labels(n as usize)
            .disable_y_mesh()
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(draw_error)?;
        let columns = chart_area.dim_in_pixel().0 as usize;
        for (i, lane) in lanes.lanes.iter().enumerate() {
            let row = n - 1 - i as i32;
            for (from, to, state) in lane_runs(lane, axis, columns) {
                let Some((_, shade)) = lanes.states.get(state) else {
                    continue;
                };
                chart
                    .draw_series([Rectangle::new(
                        [
                            (axis.x(from), SegmentValue::Exact(row)),
                            (axis.x(to), SegmentValue::Exact(row + 1)),
                        ],
                        lane_color(*shade).filled(),
                    )])
                    .map_err(draw_error)?;
            }
        }
        for band in &self.time_bands {
            let (from, to) = (band.from.max(axis.t0), band.to.min(axis.t1));
            if from < to {
                chart
                    .draw_series([Rectangle::new(
                        [
                            (axis.x(from), SegmentValue::Exact(0)),
                            (axis.x(to), SegmentValue::Exact(n)),
                        ],
                        shade_color(band.shade).filled(),
                    )])
                    .map_err(draw_error)?;
            }
        }
        let legend: Vec<Entry> = lanes
            .states
            .iter()
            .map(|(name, shade)| Entry::State {
                name,
                shade: *shade,
            })
            .collect();
        draw_legend(&legend_area, &legend)
    }
}

/// The time axis: seconds in, the chosen unit out.
struct TimeAxis {
    t0: f64,
    t1: f64,
    unit: TimeUnit,
}

impl TimeAxis {
    fn x(&self, seconds: f64) -> f64 {
        seconds * self.unit.per_second()
    }

    fn title(&self) -> String {
        format!("time ({})", self.unit.symbol())
    }
}

/// A tick value as short as it can be: `250`, `0.25`, `1e-7` (the axis' steps are round, so
/// six decimals are plenty; the float noise of `0.30000000000000004` goes).
fn tick_label(v: &f64) -> String {
    let v = if v.abs() < 1e-12 { 0.0 } else { *v };
    if v != 0.0 && v.abs() < 1e-4 {
        return format!("{v:e}");
    }
    let fixed = format!("{v:.6}");
    fixed.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// The value axis: every point and `covers`, with a margin of 5 % beyond the points (none at
/// an end that `covers` reaches: a 0 V baseline stays at the axis).
fn value_span(panel: &Panel) -> (f64, f64) {
    let (lo, hi) = panel
        .series
        .iter()
        .flat_map(|s| s.points().iter().map(|p| p.1))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let covers = panel
        .covers
        .filter(|(a, b)| a.is_finite() && b.is_finite() && a <= b);
    let (lo, hi) = match (lo <= hi, covers) {
        (false, None) => return (0.0, 1.0),
        (false, Some(c)) => c,
        (true, None) => (lo, hi),
        (true, Some((a, b))) => (lo.min(a), hi.max(b)),
    };
    if lo == hi {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        return (lo - pad, hi + pad);
    }
    let margin = (hi - lo) * 0.05;
    let pinned = |end: f64| covers.is_some_and(|(a, b)| end == a || end == b);
    (
        if pinned(lo) { lo } else { lo - margin },
        if pinned(hi) { hi } else { hi + margin },
    )
}

/// The spans of a lane as drawn: as they are when they fit the pixels; otherwise one run per
/// pixel column, in the column's worst (highest-numbered) state.
fn lane_runs(lane: &Lane, axis: &TimeAxis, columns: usize) -> Vec<(f64, f64, usize)> {
    let spans = lane.spans();
    if spans.len() <= 2 * columns.max(1) {
        return spans.to_vec();
    }
    let width = (axis.t1 - axis.t0) / columns as f64;
    let mut worst = vec![None::<usize>; columns];
    for &(from, to, state) in spans {
        let col = |t: f64| (((t - axis.t0) / width).max(0.0) as usize).min(columns - 1);
        for w in &mut worst[col(from)..=col(to)] {
            *w = Some(w.map_or(state, |s| s.max(state)));
        }
    }
    let mut runs: Vec<(f64, f64, usize)> = Vec::new();
    for (c, state) in worst.into_iter().enumerate() {
        let Some(state) = state else { continue };
        let (from, to) = (axis.t0 + c as f64 * width, axis.t0 + (c + 1) as f64 * width);
        match runs.last_mut() {
            Some(last) if last.2 == state && last.1 >= from => last.1 = to,
            _ => runs.push((from, to, state)),
        }
    }
    runs
}

enum Entry<'a> {
    Line {
        name: &'a str,
        color: RGBColor,
        empty: bool,
    },
    Band(&'a Band),
    State {
        name: &'a str,
        shade: Shade,
    },
}

/// The legend column: per entry its mark (a line or a filled square), then its name, in that
/// order in the document.
fn draw_legend(area: &DrawingArea<SVGBackend, Shift>, entries: &[Entry]) -> Result<(), PlotError> {
    let style = TextStyle::from((FONT, 14).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    for (i, entry) in entries.iter().enumerate() {
        let y = 40 + i as i32 * LEGEND_LINE;
        let (x, text) = (8, 36);
        let label = match entry {
            Entry::Line { name, color, empty } => {
                area.draw(&PathElement::new(
                    vec![(x, y), (x + 22, y)],
                    color.stroke_width(2),
                ))
                .map_err(draw_error)?;
                if *empty {
                    format!("{name} (no data)")
                } else {
                    name.to_string()
                }
            }
            Entry::Band(band) => {
                area.draw(&Rectangle::new(
                    [(x, y - 6), (x + 22, y + 6)],
                    shade_color(band.shade).filled(),
                ))
                .map_err(draw_error)?;
                band.label.clone()
            }
            Entry::State { name, shade } => {
                area.draw(&Rectangle::new(
                    [(x, y - 6), (x + 22, y + 6)],
                    lane_color(*shade).filled(),
                ))
                .map_err(draw_error)?;
                name.to_string()
            }
        };
        area.draw(&Text::new(label, (text, y), style.clone()))
            .map_err(draw_error)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(&250.0), "250");
        assert_eq!(tick_label(&0.30000000000000004), "0.3");
        assert_eq!(tick_label(&-2.5), "-2.5");
        assert_eq!(tick_label(&1e-15), "0");
        assert_eq!(tick_label(&2e-7), "2e-7");
        assert_eq!(tick_label(&1e9), "1000000000");
    }
}
