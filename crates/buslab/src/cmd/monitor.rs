//! `buslab monitor --bus URL`: the bus in the terminal (ratatui): the per-ID table with the
//! bytes that changed highlighted (cansniffer, SavvyCAN), a frame log, a load sparkline, and
//! the nodes' error state with the STATUS, ALC and ECC registers of one in words (JerryCAN's
//! viewers). The model is `buslab_view::BusView`, as for `buslab web`; this adapter owns the
//! terminal (raw mode and the alternate screen, restored on every way out), the keys and the
//! bus.
//!
//! With `--dbc FILE`, the left panel shows the database's messages as signals instead (`d`
//! switches between the two): each message seen with its count and period, each of its signals
//! with its latest value (the value table's label, or the number and its unit); a value that
//! changed within the last second is highlighted as a changed byte is, and a multiplexed
//! branch the last frame did not carry is dimmed, showing what it last said.
//!
//! No backend hands a client its own frames (socketcand, SocketCAN without
//! `CAN_RAW_RECV_OWN_MSGS`, SLCAN), so the frames the monitor sends (`s`) go into the view
//! when the bus takes them, marked `TX` in the log as `candump -x` marks the host's own.

use std::collections::VecDeque;
use std::io::{IsTerminal, Stdout};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_backends::DynBus;
use buslab_can::Frame;
use buslab_canbus::{NodeRef, NodeStatus, Record, Timestamp, wall_clock};
use buslab_view::{BusView, LogFilter, MessageRow, ViewConfig};
use ratatui::Terminal;
use ratatui::backend::CrosstermBackend;
use ratatui::layout::{Constraint, Layout};
use ratatui::style::{Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph, Row, Sparkline, Table};

use super::busopt::{BusOpt, open};
use crate::dbc::DbcArg;
use crate::terminal::{self, RawScreen, read_keys};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The bus's bit rate, to estimate the load on buses that do not report it.
    #[arg(long, value_name = "BIT/S", value_parser = clap::value_parser!(u32).range(1_000..=1_000_000))]
    pub bitrate: Option<u32>,
    #[command(flatten)]
    pub dbc: DbcArg,
}

const CTRL_C: u8 = 3;
const ESC: u8 = 0x1B;
/// The screen is drawn this often at most.
const REDRAW: Duration = Duration::from_millis(100);
/// Node statuses are asked for this often.
const STATUS_EVERY: Duration = Duration::from_millis(250);
/// Frames the log shows at most (the newest).
const LOG_LINES: usize = 200;

pub fn run(args: Args) -> anyhow::Result<()> {
    if !std::io::stdin().is_terminal() || !std::io::stdout().is_terminal() {
        bail!(
            "buslab monitor needs a terminal (its keys and its screen); buslab dump prints frames anywhere"
        );
    }
    let url = args.bus.bus.to_string();
    // The database before the bus: a bad file is named before anything else happens.
    let dbc = args.dbc.load()?;
    let mut bus = open(&args.bus.bus)?;
    let own = bus.admin().and_then(|a| {
        let _ = a.set_name("monitor");
        a.node_status(None).ok().map(|s| s.number)
    });
    let quit = super::interrupted()?;
    let guard = RawScreen::enter(terminal::Cursor::Hidden)?;
    let mut terminal = Terminal::new(CrosstermBackend::new(std::io::stdout()))
        .context("cannot draw on this terminal")?;
    let keys = read_keys();
    let mut monitor = Monitor::new(
        url,
        own,
        ViewConfig {
            bitrate: args.bitrate,
            dbc,
            ..ViewConfig::default()
        },
    );
    let result = monitor.run(&mut bus, &mut terminal, &keys, &quit);
    drop(terminal);
    drop(guard);
    result
}

/// What a typed line is for.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Entry {
    Filter,
    Send,
}

struct Monitor {
    url: String,
    own: Option<u32>,
    view: BusView,
    epoch: Instant,
    filter: LogFilter,
    paused: bool,
    /// The log as shown (frozen while paused).
    shown_log: Vec<String>,
    entry: Option<(Entry, String)>,
    message: String,
    selected: usize,
    /// The left panel shows signals (with a database) rather than bytes.
    signals: bool,
    /// The first message the signal panel shows.
    scroll: usize,
    /// The frames this monitor sent that the log may still show (time and frame), to mark
    /// them `TX`.
    sent: VecDeque<(Timestamp, Frame)>,
}

impl Monitor {
    fn new(url: String, own: Option<u32>, config: ViewConfig) -> Self {
        let signals = config.dbc.is_some();
        Self {
            url,
            own,
            view: BusView::new(config),
            epoch: Instant::now(),
            filter: LogFilter::all(),
            paused: false,
            shown_log: Vec::new(),
            entry: None,
            message: String::new(),
            selected: 0,
            signals,
            scroll: 0,
            sent: VecDeque::new(),
        }
    }

    fn run(
        &mut self,
        bus: &mut DynBus,
        terminal: &mut Terminal<CrosstermBackend<Stdout>>,
        keys: &Receiver<Vec<u8>>,
        quit: &AtomicBool,
    ) -> anyhow::Result<()> {
        let mut next_status = Instant::now();
        let mut next_draw = Instant::now();
        while !quit.load(Ordering::Relaxed) {
            loop {
                match keys.try_recv() {
                    Ok(bytes) => {
                        for b in bytes {
                            if !self.key(b, bus) {
                                return Ok(());
                            }
                        }
                    }
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return Ok(()),
                }
            }
            if Instant::now() >= next_status {
                let statuses = statuses(bus, self.own);
                let now = self.epoch.elapsed();
                match statuses {
                    Some(list) => self.view.nodes(now, list),
                    None => self.view.tick(now),
                }
                next_status = Instant::now() + STATUS_EVERY;
            }
            if Instant::now() >= next_draw {
                self.redraw(terminal)?;
                next_draw = Instant::now() + REDRAW;
            }
            // Frames until the next redraw or status is due, and no longer: a bus that sends
            // faster than the monitor takes its frames must not keep the screen stale and the
            // keys unread.
            let due = next_draw.min(next_status);
            let mut timeout = due.saturating_duration_since(Instant::now());
            while let Some(m) = bus.recv(Some(timeout)).context("receiving from the bus")? {
                let seen = Instant::now();
                self.view.frame(seen - self.epoch, m.at, m.record);
                if seen >= due {
                    break;
                }
                timeout = Duration::ZERO;
            }
        }
        Ok(())
    }

    /// The log's newest lines (unless paused) and the screen, as they are now.
    fn redraw(&mut self, terminal: &mut Terminal<CrosstermBackend<Stdout>>) -> anyhow::Result<()> {
        let now = self.epoch.elapsed();
        if !self.paused {
            self.shown_log = self
                .view
                .log_tail(&self.filter, LOG_LINES)
                .into_iter()
                .map(|e| {
                    let own =
                        matches!(e.record, Record::Frame(f) if self.sent.contains(&(e.at, f)));
                    format!(
                        "{:>17}  {}{}",
                        e.at.to_string(),
                        e.frame,
                        if own { "  TX" } else { "" }
                    )
                })
                .collect();
        }
        terminal
            .draw(|f| self.draw(f, now))
            .context("cannot draw on the terminal")?;
        Ok(())
    }

    /// A key; `false` to quit.
    fn key(&mut self, b: u8, bus: &mut DynBus) -> bool {
        if let Some((kind, text)) = &mut self.entry {
            match b {
                b'\r' | b'\n' => {
                    let (kind, text) = (*kind, text.clone());
                    self.entry = None;
                    self.apply(kind, &text, bus);
                }
                ESC => self.entry = None,
                0x7F | 0x08 => {
                    text.pop();
                }
                CTRL_C => return false,
                b if (0x20..0x7F).contains(&b) && text.len() < 64 => text.push(char::from(b)),
                _ => {}
            }
            return true;
        }
        match b {
            b'q' | CTRL_C => return false,
            b'p' | b' ' => {
                self.paused = !self.paused;
                self.message = if self.paused { "paused" } else { "running" }.into();
            }
            b'c' => {
                self.view.clear();
                self.shown_log.clear();
                self.message = "cleared".into();
            }
            b'f' => self.entry = Some((Entry::Filter, String::new())),
            b's' => self.entry = Some((Entry::Send, String::new())),
            b'n' => self.selected += 1,
            b'd' if self.view.database().is_some() => self.signals = !self.signals,
            b'j' if self.signals => {
                self.scroll = (self.scroll + 1).min(self.view.message_count().saturating_sub(1));
            }
            b'k' if self.signals => self.scroll = self.scroll.saturating_sub(1),
            _ => {}
        }
        true
    }

    fn apply(&mut self, kind: Entry, text: &str, bus: &mut DynBus) {
        match kind {
            Entry::Filter => match text.parse::<LogFilter>() {
                Ok(f) => {
                    self.message = if f.is_all() {
                        "no filter".into()
                    } else {
                        format!("filter {text}")
                    };
                    self.filter = f;
                }
                Err(e) => self.message = e.to_string(),
            },
            Entry::Send => match text.parse::<Frame>() {
                Ok(frame) => {
                    self.message = match bus.send(&frame) {
                        Ok(()) => {
                            self.show_sent(frame);
                            format!("sent {frame}")
                        }
                        Err(e) => format!("cannot send {frame}: {e}"),
                    }
                }
                Err(e) => self.message = format!("frame {text:?}: {e}"),
            },
        }
    }

    /// A frame the bus took from this monitor, in the table and the log as the bus carries it.
    fn show_sent(&mut self, frame: Frame) {
        // The wall clock, as the frames received from a live bus carry.
        let at = wall_clock();
        self.view.frame(self.epoch.elapsed(), at, frame);
        if self.sent.len() == LOG_LINES {
            self.sent.pop_front();
        }
        self.sent.push_back((at, frame));
    }

    fn draw(&self, f: &mut ratatui::Frame, now: Duration) {
        let [top, middle, log, bottom] = Layout::vertical([
            Constraint::Length(1),
            Constraint::Min(6),
            Constraint::Percentage(30),
            Constraint::Length(1),
        ])
        .areas(f.area());
        let [summary, spark] =
            Layout::horizontal([Constraint::Min(40), Constraint::Length(30)]).areas(top);
        let load = self
            .view
            .load()
            .next_back()
            .and_then(|l| l.percent)
            .map_or("load ?".to_string(), |p| format!("load {p:.1} %"));
        f.render_widget(
            Paragraph::new(format!(
                "{}  {} frames  {}/s  {load}{}",
                self.url,
                self.view.frame_count(),
                self.view.frames_per_s(),
                if self.paused { "  PAUSED" } else { "" }
            )),
            summary,
        );
        let kept = self.view.load().len();
        let points: Vec<u64> = self
            .view
            .load()
            .skip(kept.saturating_sub(usize::from(spark.width)))
            .map(|l| l.percent.map_or(l.frames, |p| p.round() as u64))
            .collect();
        f.render_widget(Sparkline::default().data(&points), spark);

        let [ids, nodes] =
            Layout::horizontal([Constraint::Percentage(58), Constraint::Percentage(42)])
                .areas(middle);
        let highlight = Style::default().add_modifier(Modifier::REVERSED);
        if self.signals {
            self.draw_signals(f, ids, now, highlight);
        } else {
            self.draw_ids(f, ids, now, highlight);
        }
        let mut lines = Vec::new();
        let nodes_shown = self.view.node_views();
        let selected = if nodes_shown.is_empty() {
            None
        } else {
            Some(self.selected % nodes_shown.len())
        };
        for (i, n) in nodes_shown.iter().enumerate() {
            let text = format!(
                "{:>2} {:<10} {:<13} TEC {:>3} REC {:>3}",
                n.number,
                n.name,
                n.state,
                n.tec.map_or("-".into(), |v| v.to_string()),
                n.rec.map_or("-".into(), |v| v.to_string())
            );
            lines.push(if Some(i) == selected {
                Line::styled(text, highlight)
            } else {
                Line::raw(text)
            });
        }
        if let Some(n) = selected.map(|i| &nodes_shown[i]) {
            lines.push(Line::raw(""));
            lines.push(Line::raw(format!(
                "STATUS {}",
                n.status.as_deref().unwrap_or("-")
            )));
            lines.push(Line::raw(format!(
                "ALC {}",
                n.alc.as_deref().unwrap_or("-")
            )));
            lines.push(Line::raw(format!(
                "ECC {}",
                n.ecc.as_deref().unwrap_or("-")
            )));
            lines.push(Line::raw(format!(
                "sent {} received {} bus errors {} bus-off {}",
                n.sent, n.received, n.bus_errors, n.bus_off
            )));
        } else {
            lines.push(Line::raw("no node status (only a buslab bus tells)"));
        }
        f.render_widget(
            Paragraph::new(lines)
                .wrap(ratatui::widgets::Wrap { trim: false })
                .block(Block::bordered().title(" nodes (n: next) ")),
            nodes,
        );
        let height = usize::from(log.height.saturating_sub(2));
        let from = self.shown_log.len().saturating_sub(height);
        let title = if self.filter.is_all() {
            " frames ".to_string()
        } else {
            " frames (filtered) ".to_string()
        };
        f.render_widget(
            Paragraph::new(
                self.shown_log[from..]
                    .iter()
                    .map(|l| Line::raw(l.as_str()))
                    .collect::<Vec<_>>(),
            )
            .block(Block::bordered().title(title)),
            log,
        );
        let help = match &self.entry {
            Some((Entry::Filter, t)) => format!("filter (123, 120:7F0, 300~700; empty: all): {t}_"),
            Some((Entry::Send, t)) => format!("send (123#1122): {t}_"),
            None => format!(
                "q quit  p pause  f filter  c clear  s send  n next node{}   {}",
                if self.view.database().is_some() {
                    "  d signals/bytes  j/k scroll"
                } else {
                    ""
                },
                self.message
            ),
        };
        f.render_widget(Paragraph::new(help), bottom);
    }

    /// The per-ID table: the rows that fit, changed bytes highlighted.
    fn draw_ids(
        &self,
        f: &mut ratatui::Frame,
        ids: ratatui::layout::Rect,
        now: Duration,
        highlight: Style,
    ) {
        // The rows that fit between the borders and under the header, not the whole table
        // (thousands of IDs on a busy bus, redrawn ten times a second).
        let shown = self
            .view
            .rows_page(now, 0, usize::from(ids.height.saturating_sub(3)));
        let rows = shown.iter().map(|r| {
            let mut data = Vec::new();
            for (i, at) in (0..r.data.len()).step_by(2).enumerate() {
                let byte = &r.data[at..at + 2];
                if r.changed & (1 << i) != 0 {
                    data.push(Span::styled(byte, highlight));
                } else {
                    data.push(Span::raw(byte));
                }
                data.push(Span::raw(" "));
            }
            Row::new(vec![
                Line::from(r.id.as_str()),
                Line::from(r.count.to_string()),
                Line::from(r.period_ms.map_or("-".into(), |p| format!("{p:.1}"))),
                Line::from(r.dlc.to_string()),
                Line::from(data),
            ])
        });
        f.render_widget(
            Table::new(
                rows,
                [
                    Constraint::Length(8),
                    Constraint::Length(8),
                    Constraint::Length(8),
                    Constraint::Length(3),
                    Constraint::Min(24),
                ],
            )
            .header(Row::new(["ID", "count", "ms", "DLC", "data"]))
            .block(Block::bordered().title(if self.view.database().is_some() {
                " per ID (d: signals) "
            } else {
                " per ID "
            })),
            ids,
        );
    }

    /// The database's messages seen, each with its signals: the lines that fit from the
    /// message scrolled to, changed values highlighted, inactive branches dimmed.
    fn draw_signals(
        &self,
        f: &mut ratatui::Frame,
        area: ratatui::layout::Rect,
        now: Duration,
        highlight: Style,
    ) {
        let height = usize::from(area.height.saturating_sub(3));
        // Each message takes a line at least: no more messages than lines are put in words.
        let shown = self.view.messages_page(now, self.scroll, height);
        // The names as wide as they are (within reason); the values take the rest.
        let names = shown
            .iter()
            .flat_map(|m| {
                std::iter::once(m.name.len())
                    .chain(m.signals.iter().map(|s| s.name.len() + SIGNAL_INDENT.len()))
            })
            .max()
            .unwrap_or(0)
            .clamp(16, 32);
        let rows = signal_lines(&shown, highlight)
            .into_iter()
            .take(height)
            .map(|(cells, style)| Row::new(cells).style(style));
        let count = self.view.message_count();
        let title = if self.scroll == 0 {
            format!(" signals of {count} messages (d: bytes, j/k: scroll) ")
        } else {
            format!(
                " signals of {count} messages, from message {} (d: bytes, j/k: scroll) ",
                self.scroll + 1
            )
        };
        f.render_widget(
            Table::new(
                rows,
                [
                    Constraint::Length(9),
                    Constraint::Length(names as u16),
                    Constraint::Fill(1),
                ],
            )
            .header(Row::new([
                "ID",
                "message / signal",
                "value (a message: frames, period)",
            ]))
            .block(Block::bordered().title(title)),
            area,
        );
    }
}

/// Every node's status but this monitor's own; `None` if the bus has none to tell.
fn statuses(bus: &mut DynBus, own: Option<u32>) -> Option<Vec<NodeStatus>> {
    let admin = bus.admin()?;
    let nodes = admin.nodes().ok()?;
    Some(
        nodes
            .into_iter()
            .filter(|n| Some(n.number) != own)
            .filter_map(|n| admin.node_status(Some(&NodeRef::Number(n.number))).ok())
            // Names from the server, shown with their control characters written out.
            .map(super::status::shown)
            .collect(),
    )
}

/// What a signal's name is indented by, under its message's.
const SIGNAL_INDENT: &str = "  ";

/// The signal panel's lines: a message's own line (ID, name, frames, period), then one per
/// signal (name, value); a value that changed lately is highlighted, an inactive branch's
/// dimmed.
fn signal_lines(messages: &[MessageRow], highlight: Style) -> Vec<(Vec<Line<'_>>, Style)> {
    let bold = Style::default().add_modifier(Modifier::BOLD);
    let dim = Style::default().add_modifier(Modifier::DIM);
    let mut lines = Vec::new();
    for m in messages {
        lines.push((
            vec![
                Line::from(m.id.as_str()),
                Line::from(m.name.as_str()),
                Line::from(match m.period_ms {
                    Some(p) => format!("{} frames, {p:.1} ms", m.count),
                    None => format!("{} frames", m.count),
                }),
            ],
            bold,
        ));
        for s in &m.signals {
            let value = s.text();
            let value = if s.changed {
                Line::from(Span::styled(value, highlight))
            } else {
                Line::from(value)
            };
            lines.push((
                vec![
                    Line::from(""),
                    Line::from(format!("{SIGNAL_INDENT}{}", s.name)),
                    value,
                ],
                if s.active { Style::default() } else { dim },
            ));
        }
    }
    lines
}
