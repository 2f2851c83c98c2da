//! `buslab sim`: run a bus scenario in virtual time and print what happened.
//!
//! Frames go to stdout in candump log format with the transmitting node as the interface and
//! virtual time as the timestamp, so `canplayer` and `log2asc` can read the output (they skip
//! the `#` status lines). A per-node summary ends the run. Ctrl-C, SIGTERM and SIGHUP end it
//! early as cleanly: the trace, the files and the summary go up to where the run got.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::PathBuf;
use std::sync::atomic::Ordering;

use anyhow::Context;
use buslab_bench::Scenario;
use buslab_can::Frame;
use buslab_can::controller::{ErrorKind, ErrorState, Event};
use buslab_link::fs::BlockWriter;
use buslab_logs::{BitTimeStamps, candump, text};
use buslab_plot::{Band, Figure, Lane, Panel, Series, Shade, StateLanes};
use buslab_sim::observe::signal_names;
use buslab_sim::{
    BitTime, CounterSample, Happening, Record, RecordedEvents, Simulation, Span, VcdWriter,
};

#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML; see docs/sim.md).
    pub scenario: PathBuf,
    /// Write the bus level and each node's TX/RX levels to this VCD file.
    #[arg(long, value_name = "FILE")]
    pub vcd: Option<PathBuf>,
    /// Run this long instead of the scenario's duration (`500ms`, `2s`, or bit-times: `100000bits`).
    #[arg(long)]
    pub duration: Option<Span>,
    /// Use this seed instead of the scenario's.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Also print every frame as each node received it (` R`), transmissions get ` T`.
    #[arg(long)]
    pub rx: bool,
    /// Also print every error a node detected.
    #[arg(long)]
    pub errors: bool,
    /// Write every node's TEC/REC series to this CSV file (`time_s,node,tec,rec,state`), at
    /// the scenario's `sample_every` (1 ms if it has none).
    #[arg(long, value_name = "FILE")]
    pub counters: Option<PathBuf>,
    /// Draw every node's TEC and REC over time and its fault-confinement state as an SVG
    /// figure, the scenario's faults shaded (samples as for --counters, plus every state
    /// change).
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Step every node at every bit-time: no whole frames applied at once, no jump over idle
    /// bus (the reference path; the output is the same, only slower).
    #[arg(long)]
    pub bit_level: bool,
}

/// Bit-times simulated between two flushes of the output.
const CHUNK: BitTime = BitTime::new(100_000);

/// The kinds of events the trace printer (unless `quiet`) and the plot read.
fn recorded_events(args: &Args, quiet: bool) -> RecordedEvents {
    let mut kinds = RecordedEvents::empty();
    if !quiet {
        kinds |= RecordedEvents::TRANSMITTED
            | RecordedEvents::STATE_CHANGED
            | RecordedEvents::WARNING
            | RecordedEvents::DROPPED;
        kinds.set(RecordedEvents::RECEIVED, args.rx);
        kinds.set(RecordedEvents::ERROR, args.errors);
    }
    if args.plot.is_some() {
        kinds |= RecordedEvents::STATE_CHANGED;
    }
    kinds
}

/// `quiet` (the global `-q`): print only the summary.
pub fn run(args: Args, quiet: bool) -> anyhow::Result<()> {
    // A reader that goes away (`| head`) ends the run quietly, as for other Unix tools.
    match simulate(args, quiet) {
        Err(e)
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

/// The most a scenario file may hold: a `file` traffic of the largest size (16 MiB) as hex
/// fits, and `/dev/zero` or a wrong path is not read until memory runs out.
const MAX_SCENARIO_BYTES: u64 = 64 << 20;

/// Reads a scenario file, refusing one larger than [`MAX_SCENARIO_BYTES`] and what is not a
/// regular file (a FIFO would block, a device never end).
pub fn read_scenario(path: &std::path::Path) -> anyhow::Result<String> {
    buslab_link::fs::read_text_limited(path, MAX_SCENARIO_BYTES)
        .with_context(|| format!("cannot read scenario {}", path.display()))
}

fn simulate(args: Args, quiet: bool) -> anyhow::Result<()> {
    if let Some(path) = &args.plot {
        super::plot::check_target(path)?;
    }
    let text = read_scenario(&args.scenario)?;
    let mut scenario = Scenario::from_toml(&text)
        .with_context(|| format!("bad scenario {}", args.scenario.display()))?;
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    let end = args
        .duration
        .map_or(scenario.duration, |d| d.to_bits(scenario.bitrate));
    if end > buslab_bench::scenario::max_duration(scenario.bitrate) {
        anyhow::bail!(
            "--duration {} is longer than a simulation may run: up to {} s of virtual time",
            args.duration.map(|d| d.to_string()).unwrap_or_default(),
            buslab_bench::scenario::MAX_DURATION.as_duration().as_secs()
        );
    }
    if (args.counters.is_some() || args.plot.is_some()) && scenario.sample_every.is_none() {
        scenario.sample_every = Some(
            Span::Seconds(1e-3)
                .to_bits(scenario.bitrate)
                .max(BitTime::ONE),
        );
    }
    let mut sim = scenario.build()?;
    if args.bit_level {
        sim.set_whole_frames(false);
        sim.set_fast_forward(false);
    }
    // Only what the trace printer and the plot read is recorded (the summary's counters are
    // kept either way): without receptions and lost arbitrations the engine advances the
    // nodes that only watch as a group.
    sim.set_record_events(recorded_events(&args, quiet));
    let mut counters = match &args.counters {
        Some(path) => {
            let file = File::create(path)
                .with_context(|| format!("cannot create counters file {}", path.display()))?;
            let mut w = BufWriter::new(file);
            writeln!(w, "time_s,node,tec,rec,state")?;
            Some(w)
        }
        None => None,
    };

    let mut vcd = match &args.vcd {
        Some(path) => {
            sim.trace_levels();
            let file = File::create(path)
                .with_context(|| format!("cannot create VCD file {}", path.display()))?;
            let names = signal_names(sim.nodes().iter().map(|n| n.name()));
            Some(VcdWriter::new(BufWriter::new(file), sim.bitrate(), &names)?)
        }
        None => None,
    };

    let mut plot = args.plot.as_ref().map(|_| CounterPlot::new(&scenario));
    // A trace going to a regular file is written in whole, aligned blocks (half the kernel's
    // time); one whose descriptor cannot be duplicated goes the other way.
    let mut blocks = if quiet {
        None
    } else {
        BlockWriter::for_stdout().ok().flatten()
    };
    let stdout = io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut printer = Printer::new(&scenario, &args);
    let mut csv = Vec::new();
    let stop = super::interrupted()?;
    while sim.now() < end {
        if stop.load(Ordering::Relaxed) {
            let (secs, us) = sim.now().secs_and_micros_at(sim.bitrate());
            tracing::warn!(
                "interrupted at {secs}.{us:06} s of virtual time: the output ends there"
            );
            break;
        }
        // A chunk may end a little late, at the end of the frame it would have cut (that
        // frame is then applied whole); the run still ends at `end` exactly.
        sim.run_past(end.min(sim.now() + CHUNK), end);
        let records = sim.take_records();
        let series = sim.take_series();
        if let Some(w) = &mut counters {
            csv.clear();
            counter_rows(&mut csv, &scenario, &series);
            w.write_all(&csv)?;
        }
        if let Some(plot) = &mut plot {
            plot.add(&records, &series);
        }
        if !quiet {
            printer.print_merged(&records, &series);
            match &mut blocks {
                Some(blocks) => blocks.write_blocks(&mut printer.buf)?,
                None => {
                    out.write_all(&printer.buf)?;
                    printer.buf.clear();
                }
            }
        }
        if let Some(vcd) = &mut vcd {
            vcd.write_changes(&sim.take_level_changes())?;
        }
    }
    if let Some(vcd) = vcd {
        vcd.finish(sim.now())?;
    }
    if let Some(mut w) = counters {
        w.flush()?;
    }
    if let (Some(plot), Some(path)) = (plot, &args.plot) {
        let title = format!("{}: error counters and states", args.scenario.display());
        super::plot::write(&plot.figure(&scenario, title, sim.now()), path)?;
    }
    if let Some(blocks) = &mut blocks {
        // Before the summary, which goes through `out` (the same file offset).
        blocks.write_rest(&mut printer.buf)?;
    }
    summary(&mut out, &sim)?;
    out.flush()?;
    Ok(())
}

/// The `--counters` rows of `series`: `time_s,node,tec,rec,state`.
fn counter_rows(out: &mut Vec<u8>, scenario: &Scenario, series: &[CounterSample]) {
    for c in series {
        let (secs, us) = c.time.secs_and_micros_at(scenario.bitrate);
        text::push_u64(out, secs);
        out.push(b'.');
        text::push_u64_zeros(out, u64::from(us), 6);
        out.push(b',');
        out.extend_from_slice(scenario.nodes[c.node].name.as_bytes());
        out.push(b',');
        text::push_u64(out, u64::from(c.tec));
        out.push(b',');
        text::push_u64(out, u64::from(c.rec));
        out.push(b',');
        out.extend_from_slice(state_name(c.state).as_bytes());
        out.push(b'\n');
    }
}

/// The `--plot` figure: each node's TEC and REC over time with the fault-confinement regions
/// shaded, its state in a lane below, the scenario's faults shaded across.
struct CounterPlot {
    bitrate: u32,
    tec: Vec<Series>,
    rec: Vec<Series>,
    lanes: Vec<Lane>,
}

/// The lanes' states, in the order of [`state_index`].
const STATES: [(&str, Shade); 3] = [
    ("error-active", Shade::Good),
    ("error-passive", Shade::Warning),
    ("bus-off", Shade::Danger),
];

fn state_index(state: ErrorState) -> usize {
    match state {
        ErrorState::Active => 0,
        ErrorState::Passive => 1,
        ErrorState::BusOff => 2,
    }
}

impl CounterPlot {
    /// Every node starts error-active with both counters at 0.
    fn new(scenario: &Scenario) -> Self {
        let names = || scenario.nodes.iter().map(|n| n.name.as_str());
        let start = |name| Series::from_points(name, [(0.0, 0.0)]);
        let lanes = names()
            .map(|name| {
                let mut lane = Lane::new(name);
                lane.enter(0.0, state_index(ErrorState::Active));
                lane
            })
            .collect();
        CounterPlot {
            bitrate: scenario.bitrate,
            tec: names().map(start).collect(),
            rec: names().map(start).collect(),
            lanes,
        }
    }

    /// The samples, and the state changes at the bit-time they happened, in time order.
    fn add(&mut self, records: &[Record], series: &[CounterSample]) {
        let changes = records.iter().filter_map(|r| match &r.what {
            Happening::Node {
                node,
                event: Event::StateChanged { to, tec, rec, .. },
            } => Some((r.time, *node, *tec, *rec, *to)),
            _ => None,
        });
        let samples = series
            .iter()
            .map(|c| (c.time, c.node, c.tec, c.rec, c.state));
        let mut points: Vec<_> = changes.chain(samples).collect();
        points.sort_by_key(|p| p.0);
        for (time, node, tec, rec, state) in points {
            let t = time.secs_f64_at(self.bitrate);
            self.tec[node].push(t, f64::from(tec));
            self.rec[node].push(t, f64::from(rec));
            self.lanes[node].enter(t, state_index(state));
        }
    }

    fn figure(mut self, scenario: &Scenario, title: String, end: BitTime) -> Figure {
        let seconds = |t: BitTime| t.secs_f64_at(scenario.bitrate);
        for lane in &mut self.lanes {
            lane.end(seconds(end));
        }
        let warning = || Band::new(96.0, 128.0, "error warning (≥ 96)", Shade::Caution);
        let passive = |to| Band::new(128.0, to, "error-passive (≥ 128)", Shade::Warning);
        let mut tec = Panel::new("transmit error counter", "TEC", None);
        tec.series = self.tec;
        tec.bands = vec![
            warning(),
            passive(256.0),
            Band::new(256.0, f64::INFINITY, "bus-off (≥ 256)", Shade::Danger),
        ];
        tec.covers = Some((0.0, 270.0));
        let mut rec = Panel::new("receive error counter", "REC", None);
        rec.series = self.rec;
        rec.bands = vec![warning(), passive(f64::INFINITY)];
        rec.covers = Some((0.0, 140.0));
        let mut figure = Figure::new(title);
        figure.panels = vec![tec, rec];
        figure.lanes = Some(StateLanes {
            caption: "fault-confinement state".to_owned(),
            states: STATES
                .iter()
                .map(|(name, shade)| (name.to_string(), *shade))
                .collect(),
            lanes: self.lanes,
        });
        figure.time_bands = scenario
            .faults
            .iter()
            .enumerate()
            .filter(|(_, f)| f.start < end)
            .map(|(i, f)| {
                let label = format!("fault {}: {}", i + 1, scenario.describe_fault(i));
                Band::new(
                    seconds(f.start),
                    seconds(f.end.min(end)),
                    label,
                    Shade::Event,
                )
            })
            .collect();
        figure.time_range = Some((0.0, seconds(end)));
        figure
    }
}

/// Formats trace records as candump log lines and `#` status lines into one buffer, written
/// once per chunk of the run (or in blocks to a file): nothing allocated per line, digits and
/// hex by table, a node's transmitted frame formatted once while it sends the same one. Records
/// no line shows are not recorded at all (see [`recorded_events`]) and passed over here.
struct Printer<'a> {
    scenario: &'a Scenario,
    /// Each node's name right-aligned to the longest, the frame lines' interface column
    /// (names are ASCII: the scenario checks them).
    columns: Vec<String>,
    rx: bool,
    errors: bool,
    /// The last TEC/REC values printed, to print the series only when it changes.
    last_counters: Vec<(u16, u16)>,
    /// Each node's last transmitted frame and its line after the timestamp (` NAME FRAME`).
    sent: Vec<(Option<Frame>, Vec<u8>)>,
    stamps: BitTimeStamps,
    /// The text not yet written.
    buf: Vec<u8>,
}

impl<'a> Printer<'a> {
    fn new(scenario: &'a Scenario, args: &Args) -> Self {
        let width = scenario
            .nodes
            .iter()
            .map(|n| n.name.len())
            .max()
            .unwrap_or(0);
        Self {
            scenario,
            columns: scenario
                .nodes
                .iter()
                .map(|n| format!("{:>width$}", n.name))
                .collect(),
            rx: args.rx,
            errors: args.errors,
            last_counters: vec![(0, 0); scenario.nodes.len()],
            sent: vec![(None, Vec::new()); scenario.nodes.len()],
            stamps: BitTimeStamps::new(scenario.bitrate),
            buf: Vec::with_capacity(64 * 1024),
        }
    }

    /// Prints records and counter samples in time order (samples first at equal times) into
    /// `buf`.
    fn print_merged(&mut self, records: &[Record], series: &[CounterSample]) {
        let mut samples = series.chunk_by(|a, b| a.time == b.time).peekable();
        for record in records {
            while let Some(group) = samples.next_if(|g| g[0].time <= record.time) {
                self.counters(group);
            }
            self.record(record);
        }
        for group in samples {
            self.counters(group);
        }
    }

    /// `(0000000001.250000)`: the candump log timestamp of bit-time `t`.
    fn stamp(&mut self, t: BitTime) {
        self.stamps.push(&mut self.buf, t);
    }

    /// `# (…) `: the start of a status line.
    fn status(&mut self, t: BitTime) {
        self.buf.extend_from_slice(b"# ");
        self.stamp(t);
        self.buf.push(b' ');
    }

    /// `# (…) NODE: `: the start of a node's status line.
    fn node_status(&mut self, t: BitTime, node: usize) {
        self.status(t);
        self.buf
            .extend_from_slice(self.scenario.nodes[node].name.as_bytes());
        self.buf.extend_from_slice(b": ");
    }

    /// ` (TEC 8, REC 0)` and the end of the line.
    fn counters_end(&mut self, tec: u16, rec: u16) {
        self.buf.extend_from_slice(b" (TEC ");
        text::push_u64(&mut self.buf, u64::from(tec));
        self.buf.extend_from_slice(b", REC ");
        text::push_u64(&mut self.buf, u64::from(rec));
        self.buf.extend_from_slice(b")\n");
    }

    /// One sample of every node's TEC/REC, if any changed since the last one printed.
    fn counters(&mut self, group: &[CounterSample]) {
        let same = group.len() == self.last_counters.len()
            && group
                .iter()
                .zip(&self.last_counters)
                .all(|(s, &last)| (s.tec, s.rec) == last);
        if same {
            return;
        }
        self.status(group[0].time);
        self.buf.extend_from_slice(b"TEC/REC:");
        for (sample, node) in group.iter().zip(&self.scenario.nodes) {
            self.buf.push(b' ');
            self.buf.extend_from_slice(node.name.as_bytes());
            self.buf.push(b' ');
            text::push_u64(&mut self.buf, u64::from(sample.tec));
            self.buf.push(b'/');
            text::push_u64(&mut self.buf, u64::from(sample.rec));
        }
        self.buf.push(b'\n');
        self.last_counters.clear();
        self.last_counters
            .extend(group.iter().map(|s| (s.tec, s.rec)));
    }

    fn record(&mut self, record: &Record) {
        let t = record.time;
        let (node, event) = match &record.what {
            Happening::FaultStarted { index } => return self.fault(t, *index, "started"),
            Happening::FaultEnded { index } => return self.fault(t, *index, "ended"),
            Happening::Node { node, event } => (*node, event),
        };
        match event {
            Event::Transmitted(frame) => self.sent_frame(t, node, frame),
            Event::Received(frame) if self.rx => self.frame(t, node, frame, b" R\n"),
            Event::StateChanged { from, to, tec, rec } => {
                self.node_status(t, node);
                self.buf.extend_from_slice(state_name(*from).as_bytes());
                self.buf.extend_from_slice(b" -> ");
                self.buf.extend_from_slice(state_name(*to).as_bytes());
                self.counters_end(*tec, *rec);
            }
            Event::Warning { above, tec, rec } => {
                self.node_status(t, node);
                self.buf.extend_from_slice(if *above {
                    b"error warning: a counter reached 96"
                } else {
                    b"error warning cleared: both counters below 96"
                });
                self.counters_end(*tec, *rec);
            }
            Event::Error {
                kind,
                transmitter,
                bit,
                tec,
                rec,
            } if self.errors => {
                self.node_status(t, node);
                self.buf.extend_from_slice(kind_name(*kind).as_bytes());
                self.buf.extend_from_slice(if *transmitter {
                    b" error as transmitter at bit "
                } else {
                    b" error as receiver at bit "
                });
                text::push_u64(&mut self.buf, u64::from(*bit));
                self.counters_end(*tec, *rec);
            }
            Event::Dropped(frame) => {
                // A single-shot attempt that failed, or what a chip's bus-off aborted.
                self.node_status(t, node);
                self.buf.extend_from_slice(b"frame ");
                candump::push_frame(&mut self.buf, frame);
                self.buf.extend_from_slice(b" given up\n");
            }
            _ => {}
        }
    }

    /// [`Self::frame`] for a frame `node` sent: its text after the timestamp is formatted
    /// once while the node sends the same frame.
    fn sent_frame(&mut self, t: BitTime, node: usize, frame: &Frame) {
        self.stamp(t);
        let (last, line) = &mut self.sent[node];
        if *last != Some(*frame) {
            *last = Some(*frame);
            line.clear();
            line.push(b' ');
            line.extend_from_slice(self.columns[node].as_bytes());
            line.push(b' ');
            candump::push_frame(line, frame);
        }
        self.buf.extend_from_slice(line);
        let end: &[u8] = if self.rx { b" T\n" } else { b"\n" };
        self.buf.extend_from_slice(end);
    }

    /// `(…) NODE FRAME`, then ` T`/` R` with `--rx`, and the end of the line.
    fn frame(&mut self, t: BitTime, node: usize, frame: &Frame, direction: &[u8; 3]) {
        self.stamp(t);
        self.buf.push(b' ');
        self.buf.extend_from_slice(self.columns[node].as_bytes());
        self.buf.push(b' ');
        candump::push_frame(&mut self.buf, frame);
        let end: &[u8] = if self.rx { direction } else { b"\n" };
        self.buf.extend_from_slice(end);
    }

    fn fault(&mut self, t: BitTime, index: usize, what: &str) {
        // Rare: the description may allocate.
        let description = self.scenario.describe_fault(index);
        self.status(t);
        self.buf.extend_from_slice(b"fault ");
        text::push_u64(&mut self.buf, index as u64 + 1);
        self.buf.push(b' ');
        self.buf.extend_from_slice(what.as_bytes());
        self.buf.extend_from_slice(b": ");
        self.buf.extend_from_slice(description.as_bytes());
        self.buf.push(b'\n');
    }
}

fn state_name(state: ErrorState) -> &'static str {
    match state {
        ErrorState::Active => "error-active",
        ErrorState::Passive => "error-passive",
        ErrorState::BusOff => "bus-off",
    }
}

fn kind_name(kind: ErrorKind) -> &'static str {
    match kind {
        ErrorKind::Bit => "bit",
        ErrorKind::Stuff => "stuff",
        ErrorKind::Crc => "CRC",
        ErrorKind::Form => "form",
        ErrorKind::Ack => "ACK",
    }
}

fn summary(out: &mut impl Write, sim: &Simulation) -> io::Result<()> {
    let width = sim
        .nodes()
        .iter()
        .map(|n| n.name().len())
        .max()
        .unwrap_or(0)
        .max(4);
    writeln!(out, "#")?;
    writeln!(
        out,
        "# {:<width$} {:>8} {:>8} {:>7} {:>8} {:>8} {:>5} {:>5} {:>8}  state",
        "node", "sent", "received", "errors", "arb.lost", "bus-off", "TEC", "REC", "max TEC"
    )?;
    for n in sim.nodes() {
        let s = n.stats();
        let c = n;
        writeln!(
            out,
            "# {:<width$} {:>8} {:>8} {:>7} {:>8} {:>8} {:>5} {:>5} {:>8}  {}",
            n.name(),
            s.sent,
            s.received,
            s.errors,
            s.arbitration_lost,
            s.bus_off,
            c.tec(),
            c.rec(),
            s.max_tec,
            state_name(c.state())
        )?;
    }
    let bus = sim.bus_stats();
    let (secs, us) = sim.now().secs_and_micros_at(sim.bitrate());
    writeln!(
        out,
        "# bus: {} bit/s, {secs}.{us:06} s ({} bit-times), load {:.1} %, {} frames, {} errors",
        sim.bitrate(),
        sim.now(),
        bus.load() * 100.0,
        bus.frames,
        bus.errors
    )
}
