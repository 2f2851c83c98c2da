//! Small SVG line charts for the pages without JavaScript, on the same scales as the live
//! dashboard's script (`assets/dashboard.js`, `chart`): the x axis is the time window shown
//! (not the age of the server), the y axis fits the values shown and says its scale.

use std::fmt::Write as _;

use crate::html::esc;

/// The plot area in SVG units (the labels go around it).
pub const W: f64 = 600.0;
pub const H: f64 = 160.0;

/// The top of a y axis for values up to `max`: 1, 2 or 5 times a power of ten, at least
/// `floor` (so that a flat 3 % load fills more than a third of the height, and nothing is
/// cut off).
pub fn nice_top(max: f64, floor: f64) -> f64 {
    if !max.is_finite() || max <= floor {
        return floor;
    }
    let power = 10f64.powf(max.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|top| *top >= max)
        .unwrap_or(10.0 * power)
}

/// The top of a TEC/REC axis for values up to `max`: the next power of two above it, from 8
/// to 256 (the warning level 96 shows from 128 on, error-passive 128 from 256 on).
pub fn counter_top(max: f64) -> f64 {
    let mut top = 8.0;
    while top <= max && top < 256.0 {
        top *= 2.0;
    }
    top
}

/// A value as an axis label: no decimals for whole numbers, else up to three.
pub fn label(v: f64) -> String {
    let rounded = (v * 1000.0).round() / 1000.0;
    if rounded.fract() == 0.0 {
        format!("{rounded:.0}")
    } else {
        format!("{rounded}")
    }
}

/// One line of a chart: its CSS class and its pieces (a gap between two pieces stays a gap).
pub struct Series<'a> {
    pub class: &'a str,
    pub pieces: Vec<&'a [(f64, f64)]>,
}

/// A span of x shaded and labelled: a fault on the wire.
pub struct Band {
    pub from: f64,
    pub to: f64,
    /// A few words on the chart.
    pub label: String,
    /// The whole description, as the band's tooltip.
    pub what: String,
}

/// Rows of band labels (further ones start again at the top).
const LABEL_ROWS: usize = 3;
/// The width of a label's character, about, in SVG units (10 px text).
const CHAR_WIDTH: f64 = 5.6;

/// The row of each label starting at `x` with `chars` characters: the first row where it does
/// not run into the label before it.
fn label_rows(labels: &[(f64, usize)]) -> Vec<usize> {
    let mut ends = [f64::NEG_INFINITY; LABEL_ROWS];
    labels
        .iter()
        .enumerate()
        .map(|(i, &(x, chars))| {
            let row = (0..LABEL_ROWS)
                .find(|&r| ends[r] < x)
                .unwrap_or(i % LABEL_ROWS);
            ends[row] = x + chars as f64 * CHAR_WIDTH + 4.0;
            row
        })
        .collect()
}

/// How the x axis is labelled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeAxis {
    /// Seconds before the right edge: `−60 s` … `now` (a window ending now).
    Ago,
    /// Seconds as they are: `0 s` … `5.2 s`.
    Seconds,
}

pub struct Chart<'a> {
    /// The x range shown; points outside are cut off at its edges.
    pub x: (f64, f64),
    pub axis: TimeAxis,
    /// The y axis goes from `bottom` (0 for counts and loads) to `top`.
    pub bottom: f64,
    pub top: f64,
    /// The y values' unit, after each label (`%`, `V`; empty for counts).
    pub unit: &'a str,
    /// Under the chart: what it shows.
    pub caption: String,
    /// Horizontal rules at levels, labelled (drawn only when inside the axis).
    pub rules: Vec<(f64, &'a str)>,
    /// Shaded spans of x, labelled (faults on the wire).
    pub bands: Vec<Band>,
    pub series: Vec<Series<'a>>,
}

impl Chart<'_> {
    fn px(&self, x: f64) -> f64 {
        let (x0, x1) = self.x;
        (x - x0) / (x1 - x0).max(1e-9) * W
    }

    fn py(&self, y: f64) -> f64 {
        let span = (self.top - self.bottom).max(1e-12);
        H - ((y - self.bottom) / span).clamp(0.0, 1.0) * H
    }

    /// The chart as an `<svg>` element.
    pub fn render(&self, b: &mut String) {
        let _ = write!(
            b,
            "<svg class=chart viewBox=\"-50 -10 {} {}\" width=650 height=200 role=img \
             aria-label=\"{}\"><rect x=0 y=0 width={W} height={H} class=frame />",
            W + 60.0,
            H + 40.0,
            esc(&self.caption)
        );
        let shown: Vec<(f64, f64, &Band)> = self
            .bands
            .iter()
            .map(|band| (self.px(band.from).max(0.0), self.px(band.to).min(W), band))
            .filter(|(a, z, _)| z > a)
            .collect();
        // A label starts at its band, or further left where it would run out of the chart.
        let starts: Vec<(f64, usize)> = shown
            .iter()
            .map(|(a, _, band)| {
                let chars = band.label.chars().count();
                ((a + 2.0).min(W - chars as f64 * CHAR_WIDTH).max(0.0), chars)
            })
            .collect();
        let rows = label_rows(&starts);
        for (((a, z, band), row), (x, _)) in shown.iter().zip(rows).zip(&starts) {
            let _ = write!(
                b,
                "<rect class=band x={a:.1} y=0 width={:.1} height={H}><title>{}</title></rect>\
                 <text class=bandlabel x={:.1} y={}>{}</text>",
                z - a,
                esc(&band.what),
                x,
                10 + 11 * row,
                esc(&band.label)
            );
        }
        for (y, text) in &self.rules {
            if *y > self.top || *y < self.bottom {
                continue;
            }
            let _ = write!(
                b,
                "<line class=rule x1=0 x2={W} y1={0:.1} y2={0:.1} /><text x=4 y={1:.1}>{2}</text>",
                self.py(*y),
                self.py(*y) - 2.0,
                esc(text)
            );
        }
        for k in 0..=2 {
            let v = self.bottom + (self.top - self.bottom) * f64::from(k) / 2.0;
            let unit = if self.unit.is_empty() { "" } else { " " };
            let _ = write!(
                b,
                "<line class=grid x1=-4 x2=0 y1={0:.1} y2={0:.1} />\
                 <text class=ylabel x=-6 y={1:.1}>{2}{unit}{3}</text>",
                self.py(v),
                self.py(v) + 4.0,
                label(v),
                esc(self.unit)
            );
        }
        for k in 0..=4 {
            let f = f64::from(k) / 4.0;
            let x = self.x.0 + f * (self.x.1 - self.x.0);
            let text = match self.axis {
                TimeAxis::Ago if k == 4 => "now".to_string(),
                TimeAxis::Ago => ago(self.x.1 - x),
                TimeAxis::Seconds => format!("{} s", label((x * 10.0).round() / 10.0)),
            };
            let _ = write!(
                b,
                "<text class=xlabel x={:.1} y={}>{}</text>",
                f * W,
                H + 14.0,
                esc(&text)
            );
        }
        let _ = write!(
            b,
            "<text class=caption x={} y={}>{}</text>",
            W / 2.0,
            H + 28.0,
            esc(&self.caption)
        );
        for s in &self.series {
            for piece in &s.pieces {
                let points = self.clipped(piece);
                if points.is_empty() {
                    continue;
                }
                let mut d = String::new();
                for (x, y) in points {
                    let _ = write!(d, "{:.1},{:.1} ", self.px(x), self.py(y));
                }
                let _ = write!(
                    b,
                    "<polyline class={} points=\"{}\" />",
                    s.class,
                    d.trim_end()
                );
            }
        }
        b.push_str("</svg>");
    }

    /// The points of `piece` inside the x range, the line cut where it crosses an edge.
    fn clipped(&self, piece: &[(f64, f64)]) -> Vec<(f64, f64)> {
        let (x0, x1) = self.x;
        let at = |a: (f64, f64), b: (f64, f64), x: f64| {
            let f = if b.0 > a.0 {
                (x - a.0) / (b.0 - a.0)
            } else {
                0.0
            };
            (x, a.1 + f * (b.1 - a.1))
        };
        let mut out = Vec::with_capacity(piece.len());
        for (i, &p) in piece.iter().enumerate() {
            let prev = i.checked_sub(1).map(|j| piece[j]);
            if p.0 < x0 {
                continue;
            }
            if let Some(q) = prev
                && q.0 < x0
            {
                out.push(at(q, p, x0));
            }
            if p.0 > x1 {
                if let Some(q) = prev
                    && q.0 <= x1
                {
                    out.push(at(q, p, x1));
                }
                break;
            }
            out.push(p);
        }
        out
    }
}

/// A signal's values as steps: each `(t, value)` holds until the next, the last until `until`;
/// a value that is no number breaks the line (pieces of a chart's series).
pub fn steps(points: &[(f64, f64)], until: f64) -> Vec<Vec<(f64, f64)>> {
    let mut pieces = Vec::new();
    let mut piece: Vec<(f64, f64)> = Vec::new();
    for &(t, v) in points {
        if !v.is_finite() {
            if !piece.is_empty() {
                pieces.push(std::mem::take(&mut piece));
            }
            continue;
        }
        if let Some(&(_, last)) = piece.last() {
            piece.push((t, last));
        }
        piece.push((t, v));
    }
    if let Some(&(t, last)) = piece.last()
        && until > t
    {
        piece.push((until, last));
    }
    if !piece.is_empty() {
        pieces.push(piece);
    }
    pieces
}

/// The y axis for values from `min` to `max`: from 0 (or the nice bottom below a negative
/// minimum) to the nice top above the maximum (or 0); never empty.
pub fn signal_axis(min: f64, max: f64) -> (f64, f64) {
    let top = if max > 0.0 { nice_top(max, 0.0) } else { 0.0 };
    let bottom = if min < 0.0 { -nice_top(-min, 0.0) } else { 0.0 };
    if top > bottom {
        (bottom, top)
    } else {
        (bottom, bottom + 1.0)
    }
}

/// A chart's window in words: `60 s`, `5 min`.
pub fn window_words(window: std::time::Duration) -> String {
    let s = window.as_secs();
    if s >= 120 && s.is_multiple_of(60) {
        format!("{} min", s / 60)
    } else {
        format!("{} s", label(window.as_secs_f64()))
    }
}

/// `−45 s`, `−7.5 min`: how long before the right edge.
fn ago(seconds: f64) -> String {
    if seconds >= 120.0 {
        format!("−{} min", label(seconds / 60.0))
    } else {
        format!("−{} s", label(seconds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_load_axis_fits_the_load_shown() {
        assert_eq!(nice_top(3.1, 1.0), 5.0);
        assert_eq!(nice_top(17.1, 1.0), 20.0);
        assert_eq!(nice_top(20.0, 1.0), 20.0);
        assert_eq!(nice_top(20.5, 1.0), 25.0);
        assert_eq!(nice_top(51.0, 1.0), 100.0);
        assert_eq!(nice_top(0.0, 1.0), 1.0);
        assert_eq!(nice_top(0.3, 0.5), 0.5);
        assert_eq!(nice_top(1234.0, 1.0), 2000.0);
        // Whatever the load, the highest point is at half the height or above.
        for tenth in 1..1000 {
            let v = f64::from(tenth) / 10.0;
            let top = nice_top(v, 1.0);
            assert!(v <= top && (v < 1.0 || v / top >= 0.5), "{v} on {top}");
        }
    }

    #[test]
    fn a_counter_axis_is_a_power_of_two_that_shows_the_levels_reached() {
        assert_eq!(counter_top(0.0), 8.0);
        assert_eq!(counter_top(8.0), 16.0);
        assert_eq!(counter_top(100.0), 128.0);
        assert_eq!(counter_top(128.0), 256.0);
        assert_eq!(counter_top(255.0), 256.0);
    }

    #[test]
    fn lines_are_cut_at_the_window_and_pieces_stay_apart() {
        let old = [(0.0, 0.0), (50.0, 100.0), (70.0, 100.0)];
        let new = [(80.0, 0.0), (90.0, 8.0)];
        let chart = Chart {
            x: (60.0, 120.0),
            axis: TimeAxis::Ago,
            bottom: 0.0,
            top: 128.0,
            unit: "",
            caption: "TEC".into(),
            rules: vec![(96.0, "warning 96"), (128.0, "passive 128")],
            bands: vec![
                Band {
                    from: 55.0,
                    to: 65.0,
                    label: "cut at engine".into(),
                    what: "the wire cut".into(),
                },
                Band {
                    from: 66.0,
                    to: 67.0,
                    label: "noise 1 %".into(),
                    what: "noise".into(),
                },
            ],
            series: vec![Series {
                class: "tec",
                pieces: vec![&old, &new],
            }],
        };
        let mut svg = String::new();
        chart.render(&mut svg);
        // Entering at the left edge (x = 60 s: 100), then the piece after the gap alone.
        assert!(svg.contains("points=\"0.0,35.0 100.0,35.0\""), "{svg}");
        assert!(svg.contains("points=\"200.0,160.0 300.0,150.0\""), "{svg}");
        assert!(svg.contains(">−60 s<") && svg.contains(">now<"), "{svg}");
        assert!(svg.contains(">128<") && svg.contains(">64<"), "{svg}");
        assert!(svg.contains("warning 96") && svg.contains("passive 128"));
        // The band is cut at the left edge: 5 s of 60 on 600 units.
        assert!(svg.contains("class=band x=0.0 y=0 width=50.0"), "{svg}");
        // A label that would run into the one before goes a row down.
        assert!(svg.contains("x=2.0 y=10>cut at engine<"), "{svg}");
        assert!(svg.contains("x=62.0 y=21>noise 1 %<"), "{svg}");
    }

    #[test]
    fn a_signal_is_drawn_as_steps_on_an_axis_that_fits_negative_values() {
        let pieces = steps(&[(1.0, 5.0), (2.0, -3.0), (3.0, f64::NAN), (4.0, 1.0)], 6.0);
        assert_eq!(
            pieces,
            [
                vec![(1.0, 5.0), (2.0, 5.0), (2.0, -3.0)],
                vec![(4.0, 1.0), (6.0, 1.0)]
            ]
        );
        assert_eq!(signal_axis(-3.0, 5.0), (-5.0, 5.0));
        assert_eq!(signal_axis(0.0, 4000.0), (0.0, 5000.0));
        assert_eq!(signal_axis(-0.3, -0.1), (-0.5, 0.0));
        assert_eq!(signal_axis(0.0, 0.0), (0.0, 1.0));
        let chart = Chart {
            x: (0.0, 10.0),
            axis: TimeAxis::Seconds,
            bottom: -5.0,
            top: 5.0,
            unit: "V",
            caption: "a signal".into(),
            rules: vec![],
            bands: vec![],
            series: vec![],
        };
        let mut svg = String::new();
        chart.render(&mut svg);
        assert!(
            svg.contains(">-5 V<") && svg.contains(">0 V<") && svg.contains(">5 V<"),
            "{svg}"
        );
        // 0 V half-way up.
        assert_eq!(chart.py(0.0), H / 2.0);
    }

    #[test]
    fn a_label_of_a_band_at_the_right_edge_stays_inside_the_chart() {
        let chart = Chart {
            x: (60.0, 120.0),
            axis: TimeAxis::Ago,
            bottom: 0.0,
            top: 8.0,
            unit: "",
            caption: "TEC".into(),
            rules: vec![],
            bands: vec![Band {
                from: 118.0,
                to: 121.0,
                label: "cut at engine".into(),
                what: "the wire cut".into(),
            }],
            series: vec![],
        };
        let mut svg = String::new();
        chart.render(&mut svg);
        // The band starts 2 s before now (580 of 600); its 13 characters end at the edge.
        assert!(svg.contains("class=band x=580.0 y=0 width=20.0"), "{svg}");
        assert!(svg.contains("x=527.2 y=10>cut at engine<"), "{svg}");
    }
}
