//! `buslab plot --dbc FILE LOG SIGNAL… -o FILE.svg`: signals of a DBC database over the time
//! of a log, one panel per unit, each point a frame that carries the signal (a multiplexed
//! signal only where its branch is active).

use std::collections::HashMap;
use std::path::PathBuf;

use buslab_can::Id;
use buslab_dbc::Decoded;
use buslab_dbc::text::Number;
use buslab_logs::{OpenOptions, Timestamp, open_source};
use buslab_plot::{Figure, Panel, Series};

use crate::cmd::log::{Input, Tally, input_format, read_all};
use crate::dbc::{SignalRef, carried, signal_named};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub input: Input,
    /// The DBC database that names the signals.
    #[arg(long, value_name = "FILE")]
    pub dbc: PathBuf,
    /// The signals to draw: `Message.Signal`, or `Signal` alone when one message of the
    /// database has it.
    #[arg(value_name = "SIGNAL", required = true)]
    pub signals: Vec<String>,
    /// The figure to write, an SVG file (written when the log has been read).
    #[arg(short = 'o', long = "out", value_name = "FILE.svg")]
    pub out: PathBuf,
}

/// One drawn signal.
struct Drawn {
    name: String,
    /// Its index in its message's signals.
    index: usize,
    unit: String,
    /// Its value table as `0 Off, 1 On` (short ones only), for the panel's caption.
    labels: Option<String>,
    series: Series,
}

/// A value table longer than this is not spelled out in a caption.
const CAPTION_LABELS: usize = 8;

pub fn run(args: Args) -> anyhow::Result<()> {
    // Everything that can be refused is refused before the log is read.
    super::check_option_target("-o", &args.out)?;
    let database = crate::dbc::load(&args.dbc)?;
    let mut drawn: Vec<Drawn> = Vec::new();
    // The drawn signals of each message, by ID (indices into `drawn`).
    let mut by_id: HashMap<Id, Vec<usize>> = HashMap::new();
    for name in &args.signals {
        let found: SignalRef = signal_named(&database, &args.dbc, name)?;
        let full = found.full_name();
        if drawn.iter().any(|d| d.name == full) {
            continue;
        }
        by_id
            .entry(found.message.id())
            .or_default()
            .push(drawn.len());
        drawn.push(Drawn {
            series: Series::new(full.as_str()),
            name: full,
            index: found.index,
            unit: found.signal().unit().to_string(),
            labels: labels(found.signal()),
        });
    }
    let format = input_format(&args.input)?;
    let path = &args.input.input;
    let mut source = open_source(path, format, &OpenOptions::default())?;
    let stop = super::super::interrupted()?;
    let mut tally = Tally::default();
    let mut origin: Option<Timestamp> = None;
    let mut values: Vec<Decoded> = Vec::new();
    let read = read_all(
        &mut source,
        args.input.skip_bad,
        &stop,
        &mut tally,
        |entry| {
            let first = *origin.get_or_insert(entry.at);
            let Some((id, payload)) = carried(&entry.record) else {
                return Ok(());
            };
            let (Some(wanted), Some(message)) = (by_id.get(&id), database.message(id)) else {
                return Ok(());
            };
            message.decode_into(payload, &mut values);
            let t = entry.at.saturating_since(first).as_secs_f64();
            for &i in wanted {
                let d = &mut drawn[i];
                if let Some(value) = values.iter().find(|v| v.signal == d.index) {
                    d.series.push(t, value.physical);
                }
            }
            Ok(())
        },
    );
    for d in &drawn {
        if d.series.is_empty() {
            tracing::warn!("{}: no frame of {} carries it", d.name, path.display());
        }
    }
    let title = format!(
        "{}: signals of {}",
        path.display(),
        args.dbc.file_name().map_or_else(
            || args.dbc.display().to_string(),
            |n| n.to_string_lossy().into()
        ),
    );
    let written = super::write_option(&figure(title, drawn), "-o", &args.out);
    // A bad record ends the reading; what came before it is still drawn.
    if let Err(failure) = read {
        let kept = match written {
            Ok(()) => format!("{} is drawn from", args.out.display()),
            Err(_) => "nothing to draw in".to_string(),
        };
        return Err(failure.into_error(&tally, &kept));
    }
    written
}

/// One panel per unit, in the order the signals were named; a panel of one signal is named
/// after it, a shared one after its unit.
fn figure(title: String, drawn: Vec<Drawn>) -> Figure {
    let mut units: Vec<(String, Vec<Drawn>)> = Vec::new();
    for d in drawn {
        match units.iter_mut().find(|(unit, _)| *unit == d.unit) {
            Some((_, group)) => group.push(d),
            None => units.push((d.unit.clone(), vec![d])),
        }
    }
    let panels = units
        .into_iter()
        .map(|(unit, group)| {
            let unit = (!unit.is_empty()).then_some(unit);
            let (caption, quantity) = match &group[..] {
                [one] => match &one.labels {
                    Some(labels) => (format!("{} ({labels})", one.name), one.name.clone()),
                    None => (one.name.clone(), one.name.clone()),
                },
                _ => {
                    let names: Vec<&str> = group.iter().map(|d| d.name.as_str()).collect();
                    (names.join(", "), "value".to_string())
                }
            };
            let mut panel = Panel::new(caption, quantity, unit.as_deref());
            panel.series = group.into_iter().map(|d| d.series).collect();
            panel
        })
        .collect();
    Figure {
        panels,
        ..Figure::new(title)
    }
}

/// `0 Off, 1 On, 2 Eco`: the values of a short value table as plotted (scaled) and their
/// labels.
fn labels(signal: &buslab_dbc::Signal) -> Option<String> {
    let choices = signal.choices();
    if choices.is_empty() || choices.len() > CAPTION_LABELS {
        return None;
    }
    let mut sorted = choices.to_vec();
    sorted.sort_by_key(|(raw, _)| *raw);
    let text: Vec<String> = sorted
        .iter()
        .map(|(raw, label)| {
            let physical = *raw as f64 * signal.factor() + signal.offset();
            format!("{} {label}", Number::of(signal, physical))
        })
        .collect();
    Some(text.join(", "))
}
