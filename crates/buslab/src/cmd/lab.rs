//! `buslab lab`: the whole virtual bench, paced to real time.
//!
//! The bench is a simulated CAN bus with a few nodes exchanging periodic and bursty traffic,
//! and a listen-only monitor whose frames are printed like `candump` prints them; next to it a
//! ZELLE cell and a CPU196 board, each served on its own pseudo-terminal (see [`Devices`]).

use std::io::{self, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use std::path::{Path, PathBuf};

use anyhow::Context;
use buslab_can::controller::{ControllerConfig, Event};
use buslab_can::{Frame, Id};
use buslab_sim::{BitTime, Happening, Simulation, Span, Traffic};

#[derive(clap::Args)]
pub struct Args {
    /// Stop after this long (`2s`, `500ms`); default: run until Ctrl-C.
    #[arg(long)]
    pub duration: Option<Span>,
    /// Bit rate of the simulated CAN bus.
    #[arg(long, default_value_t = 500_000, value_parser = clap::value_parser!(u32).range(1_000..=1_000_000))]
    pub bitrate: u32,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Prefix each frame with its virtual time since the start, as `candump -t z`.
    #[arg(short = 't', long)]
    pub timestamps: bool,
    /// Keep the devices' state here (zelle.toml, cpu196.toml) and link their ports as
    /// DIR/zelle and DIR/cpu196; default: in memory, ports printed at start.
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
    /// Only the CAN bus: no ZELLE cell or CPU196 board.
    #[arg(long)]
    pub no_devices: bool,
}

/// Interface name shown in the candump-style output.
const IFACE: &str = "sim0";
/// Wall-clock time between two slices of simulation.
const SLICE: Duration = Duration::from_millis(2);

pub fn run(args: Args) -> anyhow::Result<()> {
    // A reader that goes away (`| head`) ends the run quietly, as for other Unix tools.
    match run_lab(args) {
        Err(e)
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

fn run_lab(args: Args) -> anyhow::Result<()> {
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .context("cannot install the Ctrl-C handler")?;
    }
    let end = args.duration.map(|d| d.to_bits(args.bitrate));
    let devices = if args.no_devices {
        None
    } else {
        Some(Devices::start(args.dir.as_deref())?)
    };
    let mut lab = Lab::start(args.bitrate, args.seed);
    eprintln!(
        "buslab lab: simulated CAN bus {IFACE} at {} bit/s, nodes: {}",
        args.bitrate,
        lab.node_names().join(", ")
    );
    if let Some(devices) = &devices {
        devices.describe();
    }
    eprintln!("Ctrl-C to stop");

    let stdout = io::stdout();
    let mut out = stdout.lock();
    let mut candump = Candump {
        timestamps: args.timestamps.then_some(args.bitrate),
        ..Candump::default()
    };
    let started = Instant::now();
    loop {
        // Virtual time follows the wall clock and is never ahead of it.
        let wall = started.elapsed();
        let mut target = (wall.as_secs_f64() * args.bitrate as f64) as BitTime;
        if let Some(end) = end {
            target = target.min(end);
        }
        for (time, frame) in lab.advance(target) {
            candump.print(&mut out, IFACE, time, &frame)?;
        }
        out.flush()?;
        if end.is_some_and(|end| lab.now() >= end) || stop.load(Ordering::SeqCst) {
            break;
        }
        std::thread::sleep(SLICE);
    }
    if let Some(devices) = devices {
        devices.stop()?;
    }
    Ok(())
}

/// The serial devices of the bench, each served on a pseudo-terminal by its own thread (and
/// stopped, with its state saved, when the bench stops).
struct Devices {
    zelle: super::zelle::ServedCell,
    cpu196: buslab_cpu196::served::Served,
}

impl Devices {
    fn start(dir: Option<&Path>) -> anyhow::Result<Self> {
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create the lab folder {}", dir.display()))?;
        }
        let file = |name: &str| dir.map(|d| d.join(name));
        // Two sine waves on the cell's first channels, so a measurement shows something.
        let sine = |amplitude, offset| buslab_zelle::analog::Source::Wave {
            shape: buslab_zelle::analog::Shape::Sine,
            hz: 0.5,
            amplitude,
            offset,
        };
        let zelle = super::zelle::spawn_served(super::zelle::ServeOptions {
            state: file("zelle.toml"),
            link: file("zelle"),
            analog: vec![(1, sine(2.0, 2.5)), (2, sine(1.0, 2.5))],
        })
        .context("starting the ZELLE cell")?;
        let cpu196 = super::cpu196::spawn_served(
            file("cpu196.toml").as_deref(),
            file("cpu196").as_deref(),
            super::cpu196::DEFAULT_BAUD,
            buslab_cpu196::source::Inputs::default(),
        )
        .context("starting the CPU196 board")?;
        Ok(Self { zelle, cpu196 })
    }

    fn describe(&self) {
        eprintln!(
            "  ZELLE cell   on {}  (9600 8N2; try: buslab zelle --port {} analog 1)",
            self.zelle.path().display(),
            self.zelle.path().display()
        );
        eprintln!(
            "  CPU196 board on {}  ({} 8N1; try: buslab cpu196 --port {} info)",
            self.cpu196.path().display(),
            super::cpu196::DEFAULT_BAUD,
            self.cpu196.path().display()
        );
    }

    fn stop(self) -> anyhow::Result<()> {
        self.zelle.stop().context("stopping the ZELLE cell")?;
        self.cpu196.stop().context("stopping the CPU196 board")?;
        Ok(())
    }
}

/// The bench: the bus and (later) the devices attached to it.
struct Lab {
    bus: Simulation,
    monitor: usize,
    counter: CounterNode,
}

impl Lab {
    /// Builds the bus with its nodes.
    ///
    /// Devices served on pseudo-terminals start here too: `super::zelle::spawn_served` and
    /// `super::cpu196::spawn_served` run in their own threads and stop when their handle is
    /// dropped, so keep the handles in `Lab` and print their PTY paths with the banner.
    fn start(bitrate: u32, seed: u64) -> Self {
        let mut bus = Simulation::new(bitrate, seed);
        let ms = |m: u64| m * bitrate as u64 / 1000;
        let f = |text: &str| -> Frame { text.parse().expect("built-in frame") };
        let plain = ControllerConfig::default();

        let brakes = bus.add_node("brakes", plain);
        bus.add_traffic(brakes, periodic(f("080#0140"), ms(20), 0));
        let engine = bus.add_node("engine", plain);
        bus.add_traffic(engine, periodic(f("0C0#0FA0003C00000000"), ms(10), ms(1)));
        let body = bus.add_node("body", plain);
        bus.add_traffic(body, periodic(f("18FF0010#A5"), ms(100), ms(3)));
        let dash = bus.add_node("dash", plain);
        bus.add_traffic(
            dash,
            Traffic::Burst {
                frame: f("300#D1D2D3D4"),
                count: 4,
                period: ms(250),
                start: ms(5),
            },
        );
        let counter = CounterNode {
            node: bus.add_node("counter", plain),
            id: Id::standard(0x200).expect("valid ID"),
            period: ms(50),
            next: ms(7),
            value: 0,
        };
        let monitor = bus.add_node(
            IFACE,
            ControllerConfig {
                listen_only: true,
                ..plain
            },
        );
        Lab {
            bus,
            monitor,
            counter,
        }
    }

    fn node_names(&self) -> Vec<&str> {
        let nodes = self.bus.nodes();
        nodes[..self.monitor].iter().map(|n| n.name()).collect()
    }

    fn now(&self) -> BitTime {
        self.bus.now()
    }

    /// Runs everything up to bit-time `target`; returns the frames the monitor received, with
    /// their bit-time.
    fn advance(&mut self, target: BitTime) -> Vec<(BitTime, Frame)> {
        while self.bus.now() < target {
            let until = target.min(self.counter.next);
            self.bus.run_until(until);
            if self.bus.now() == self.counter.next {
                self.counter.fire(&mut self.bus);
            }
        }
        self.bus
            .take_records()
            .into_iter()
            .filter_map(|r| match r.what {
                Happening::Node {
                    node,
                    event: Event::Received(frame),
                } if node == self.monitor => Some((r.time, frame)),
                _ => None,
            })
            .collect()
    }
}

fn periodic(frame: Frame, period: BitTime, start: BitTime) -> Traffic {
    Traffic::Periodic {
        frame,
        period,
        start,
        count: None,
    }
}

/// A node whose payload changes: a 32-bit little-endian counter every `period`.
struct CounterNode {
    node: usize,
    id: Id,
    period: BitTime,
    next: BitTime,
    value: u32,
}

impl CounterNode {
    fn fire(&mut self, bus: &mut Simulation) {
        let frame = Frame::data(self.id, &self.value.to_le_bytes()).expect("4 bytes");
        // A full queue only means the bus is overloaded; the next value follows anyway.
        let _ = bus.enqueue(self.node, frame);
        self.value = self.value.wrapping_add(1);
        self.next += self.period;
    }
}

/// candump's default terminal format: `  sim0  123   [2]  11 22`, with `-t z` timestamps
/// ` (000.012345)  sim0  123   [2]  11 22`.
#[derive(Default)]
struct Candump {
    /// Once an extended frame was shown, standard IDs are padded to 8 columns (as candump).
    eff_seen: bool,
    /// Print timestamps (bit-times at this bit rate).
    timestamps: Option<u32>,
}

impl Candump {
    fn print(
        &mut self,
        out: &mut impl Write,
        iface: &str,
        time: BitTime,
        frame: &Frame,
    ) -> io::Result<()> {
        if let Some(bitrate) = self.timestamps {
            let (s, us) = buslab_sim::time::seconds_micros(time, bitrate);
            write!(out, " ({s:03}.{us:06})")?;
        }
        self.eff_seen |= frame.is_extended();
        let id = frame.id().to_string();
        let id = if self.eff_seen && !frame.is_extended() {
            format!("{id:>8}")
        } else {
            id
        };
        // As can-utils: "[len] ", then " XX" per byte (so two spaces before the first).
        write!(out, "  {iface}  {id}   [{}] ", frame.dlc())?;
        if frame.is_remote() {
            writeln!(out, " remote request")
        } else {
            for byte in frame.payload() {
                write!(out, " {byte:02X}")?;
            }
            writeln!(out)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn show(frames: &[&str]) -> String {
        let mut c = Candump::default();
        let mut out = Vec::new();
        for f in frames {
            c.print(&mut out, "vcan0", 0, &f.parse().unwrap()).unwrap();
        }
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn candump_zero_based_timestamps() {
        let mut c = Candump {
            timestamps: Some(500_000),
            ..Candump::default()
        };
        let mut out = Vec::new();
        c.print(&mut out, "sim0", 617_284, &"123#11".parse().unwrap())
            .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            " (001.234568)  sim0  123   [1]  11\n"
        );
    }

    #[test]
    fn candump_layout() {
        assert_eq!(
            show(&["123#112233", "7FF#R", "12345678#DEADBEEF", "123#"]),
            "  vcan0  123   [3]  11 22 33\n\
             \x20 vcan0  7FF   [0]  remote request\n\
             \x20 vcan0  12345678   [4]  DE AD BE EF\n\
             \x20 vcan0       123   [0] \n"
        );
    }
}
