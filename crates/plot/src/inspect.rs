//! Reading a figure back from its SVG as a person reads it, for tests: a panel by its
//! caption, a series by its legend name (the colour next to the name), values through the
//! axis' tick labels. (Feature `inspect`.)

use std::collections::HashMap;

/// Why an SVG could not be read as a figure.
#[derive(Debug, thiserror::Error)]
pub enum InspectError {
    #[error("not XML: {0}")]
    Xml(#[from] roxmltree::Error),
    #[error("no panel captioned {0:?}; captions: {1:?}")]
    NoPanel(String, Vec<String>),
    #[error("panel {panel:?} has no legend entry {name:?}; entries: {entries:?}")]
    NoEntry {
        panel: String,
        name: String,
        entries: Vec<String>,
    },
    #[error("panel {panel:?} has too few {axis} tick labels to read values")]
    NoTicks { panel: String, axis: &'static str },
}

/// One drawn element, in document order.
#[derive(Clone, Debug)]
enum Shape {
    Text {
        x: f64,
        y: f64,
        anchor: String,
        dy: String,
        size: String,
        rotated: bool,
        text: String,
    },
    Line {
        stroke: String,
        points: Vec<(f64, f64)>,
    },
    Rect {
        fill: String,
        opacity: String,
        x: f64,
        y: f64,
        w: f64,
        h: f64,
    },
    Other,
}

/// An SVG figure, parsed.
#[derive(Debug)]
pub struct Seen {
    shapes: Vec<Shape>,
    height: f64,
}

/// Parses `svg`.
pub fn parse(svg: &str) -> Result<Seen, InspectError> {
    let doc = roxmltree::Document::parse(svg)?;
    let num =
        |n: &roxmltree::Node, a: &str| n.attribute(a).and_then(|v| v.parse().ok()).unwrap_or(0.0);
    let text = |n: &roxmltree::Node, a: &str| n.attribute(a).unwrap_or("").to_owned();
    let root = doc.root_element();
    let height = num(&root, "height");
    let shapes = root
        .children()
        .filter(|n| n.is_element())
        .map(|n| match n.tag_name().name() {
            "text" => Shape::Text {
                x: num(&n, "x"),
                y: num(&n, "y"),
                anchor: text(&n, "text-anchor"),
                dy: text(&n, "dy"),
                size: text(&n, "font-size"),
                rotated: n.attribute("transform").is_some(),
                text: n.text().unwrap_or("").trim().to_owned(),
            },
            "polyline" => Shape::Line {
                stroke: text(&n, "stroke"),
                points: n
                    .attribute("points")
                    .unwrap_or("")
                    .split_whitespace()
                    .filter_map(|p| {
                        let (x, y) = p.split_once(',')?;
                        Some((x.parse().ok()?, y.parse().ok()?))
                    })
                    .collect(),
            },
            "rect" => Shape::Rect {
                fill: text(&n, "fill"),
                opacity: text(&n, "opacity"),
                x: num(&n, "x"),
                y: num(&n, "y"),
                w: num(&n, "width"),
                h: num(&n, "height"),
            },
            _ => Shape::Other,
        })
        .collect();
    Ok(Seen { shapes, height })
}

impl Seen {
    /// Every text of the figure, trimmed, in document order.
    pub fn texts(&self) -> Vec<&str> {
        self.shapes
            .iter()
            .filter_map(|s| match s {
                Shape::Text { text, .. } => Some(text.as_str()),
                _ => None,
            })
            .collect()
    }

    /// The panel (or the lanes) captioned `caption`: from its caption down to the next caption
    /// of the same size.
    pub fn panel(&self, caption: &str) -> Result<SeenPanel<'_>, InspectError> {
        let is_caption = |s: &Shape, size: Option<&str>| match s {
            Shape::Text {
                anchor,
                dy,
                rotated: false,
                size: s,
                ..
            } => anchor == "middle" && dy == "0.76em" && size.is_none_or(|size| s == size),
            _ => false,
        };
        let found = self.shapes.iter().position(|s| {
            matches!(s, Shape::Text { text, .. } if text == caption) && is_caption(s, None)
        });
        let Some(start) = found else {
            let captions = self
                .shapes
                .iter()
                .filter(|s| is_caption(s, None))
                .filter_map(|s| match s {
                    Shape::Text { text, .. } => Some(text.clone()),
                    _ => None,
                })
                .collect();
            return Err(InspectError::NoPanel(caption.to_owned(), captions));
        };
        let Shape::Text { y: top, size, .. } = &self.shapes[start] else {
            unreachable!("found a text")
        };
        let bottom = self.shapes[start + 1..]
            .iter()
            .filter(|s| is_caption(s, Some(size)))
            .filter_map(|s| match s {
                Shape::Text { y, .. } if y > top => Some(*y),
                _ => None,
            })
            .fold(self.height, f64::min);
        Ok(SeenPanel {
            caption: caption.to_owned(),
            shapes: self.shapes[start..]
                .iter()
                .filter(|s| match s {
                    Shape::Text { y, .. } => *y >= *top && *y < bottom,
                    Shape::Line { points, .. } => {
                        points.iter().all(|p| p.1 >= *top && p.1 < bottom)
                    }
                    Shape::Rect { y, h, .. } => *y >= *top && y + h <= bottom,
                    Shape::Other => false,
                })
                .collect(),
        })
    }
}

/// The elements of one panel.
#[derive(Debug)]
pub struct SeenPanel<'a> {
    caption: String,
    shapes: Vec<&'a Shape>,
}

/// A legend entry: its name and the mark before it.
struct Mark<'a> {
    index: usize,
    shape: &'a Shape,
}

impl<'a> SeenPanel<'a> {
    /// The legend's names, in order.
    pub fn legend(&self) -> Vec<String> {
        let mut names: Vec<(usize, String)> = self
            .marks()
            .into_iter()
            .map(|(name, mark)| (mark.index, name))
            .collect();
        names.sort();
        names.into_iter().map(|(_, name)| name).collect()
    }

    /// Legend texts (anchored at their start) with the mark drawn just before each.
    fn marks(&self) -> HashMap<String, Mark<'a>> {
        let mut marks = HashMap::new();
        for (i, s) in self.shapes.iter().enumerate().skip(1) {
            if let Shape::Text {
                anchor,
                text,
                rotated: false,
                ..
            } = s
                && anchor == "start"
                && matches!(self.shapes[i - 1], Shape::Line { .. } | Shape::Rect { .. })
            {
                marks.insert(
                    text.clone(),
                    Mark {
                        index: i - 1,
                        shape: self.shapes[i - 1],
                    },
                );
            }
        }
        marks
    }

    /// The value axis' title (the rotated text), e.g. `voltage (V)`.
    pub fn value_title(&self) -> Option<&str> {
        self.shapes.iter().find_map(|s| match s {
            Shape::Text {
                rotated: true,
                text,
                ..
            } => Some(text.as_str()),
            _ => None,
        })
    }

    /// The time axis' title, e.g. `time (ms)`.
    pub fn time_title(&self) -> Option<&str> {
        self.shapes.iter().find_map(|s| match s {
            Shape::Text {
                anchor,
                dy,
                rotated: false,
                text,
                ..
            } if anchor == "middle" && dy == "-0.5ex" => Some(text.as_str()),
            _ => None,
        })
    }

    /// Tick labels of one axis that read as numbers: (pixel, value).
    fn ticks(&self, value_axis: bool) -> Vec<(f64, f64)> {
        self.shapes
            .iter()
            .filter_map(|s| match s {
                Shape::Text {
                    anchor,
                    dy,
                    rotated: false,
                    text,
                    x,
                    y,
                    ..
                } => {
                    let value: f64 = text.parse().ok()?;
                    if value_axis && anchor == "end" {
                        Some((*y, value))
                    } else if !value_axis && anchor == "middle" && dy == "0.76em" {
                        Some((*x, value))
                    } else {
                        None
                    }
                }
                _ => None,
            })
            .collect()
    }

    /// Pixel → value of one axis, from its outermost tick labels.
    fn scale(&self, value_axis: bool) -> Result<impl Fn(f64) -> f64, InspectError> {
        let mut ticks = self.ticks(value_axis);
        ticks.sort_by(|a, b| a.0.total_cmp(&b.0));
        ticks.dedup_by(|a, b| a.0 == b.0);
        let (Some(&(p0, v0)), Some(&(p1, v1))) = (ticks.first(), ticks.last()) else {
            return Err(self.no_ticks(value_axis));
        };
        if p0 == p1 {
            return Err(self.no_ticks(value_axis));
        }
        Ok(move |p: f64| v0 + (p - p0) * (v1 - v0) / (p1 - p0))
    }

    fn no_ticks(&self, value_axis: bool) -> InspectError {
        InspectError::NoTicks {
            panel: self.caption.clone(),
            axis: if value_axis { "value" } else { "time" },
        }
    }

    fn mark(&self, name: &str) -> Result<Mark<'a>, InspectError> {
        let mut marks = self.marks();
        marks.remove(name).ok_or_else(|| InspectError::NoEntry {
            panel: self.caption.clone(),
            name: name.to_owned(),
            entries: self.legend(),
        })
    }

    /// The points of the series named `name` in the legend, as (time in the axis' unit,
    /// value), read through the tick labels (so exact to a pixel).
    pub fn series(&self, name: &str) -> Result<Vec<(f64, f64)>, InspectError> {
        let mark = self.mark(name)?;
        let Shape::Line { stroke: color, .. } = mark.shape else {
            return Ok(Vec::new());
        };
        let (x, y) = (self.scale(false)?, self.scale(true)?);
        Ok(self
            .shapes
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != mark.index)
            .filter_map(|(_, s)| match s {
                Shape::Line { stroke, points } if stroke == color => Some(points),
                _ => None,
            })
            .flatten()
            .map(|&(px, py)| (x(px), y(py)))
            .collect())
    }

    /// The rectangles filled like the legend mark `name` (a band or a lane state), as (time
    /// from, time to, value from, value to); for lanes the values are pixel rows (see
    /// [`lane_row`](Self::lane_row)).
    pub fn areas(&self, name: &str) -> Result<Vec<(f64, f64, f64, f64)>, InspectError> {
        let mark = self.mark(name)?;
        let Shape::Rect {
            fill: color,
            opacity: alpha,
            ..
        } = mark.shape
        else {
            return Ok(Vec::new());
        };
        let x = self.scale(false)?;
        let y = self.scale(true);
        Ok(self
            .shapes
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != mark.index)
            .filter_map(|(_, s)| match s {
                Shape::Rect {
                    fill,
                    opacity,
                    x: rx,
                    y: ry,
                    w,
                    h,
                } if fill == color && opacity == alpha => {
                    let (v0, v1) = match &y {
                        Ok(y) => (y(ry + h), y(*ry)),
                        Err(_) => (*ry, ry + h),
                    };
                    Some((x(*rx), x(rx + w), v0, v1))
                }
                _ => None,
            })
            .collect())
    }

    /// The pixel row of lane `name` (its label's height).
    pub fn lane_row(&self, name: &str) -> Option<f64> {
        self.shapes.iter().find_map(|s| match s {
            Shape::Text {
                anchor,
                text,
                y,
                rotated: false,
                ..
            } if anchor == "end" && text == name => Some(*y),
            _ => None,
        })
    }

    /// The time spans lane `lane` is drawn in state `state` (a legend name).
    pub fn lane_spans(&self, lane: &str, state: &str) -> Result<Vec<(f64, f64)>, InspectError> {
        let Some(row) = self.lane_row(lane) else {
            return Ok(Vec::new());
        };
        Ok(self
            .areas(state)?
            .into_iter()
            .filter(|a| a.2 <= row && row <= a.3)
            .map(|a| (a.0, a.1))
            .collect())
    }
}
