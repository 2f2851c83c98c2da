//! `buslab gen`: generate traffic like can-utils' cangen (gap, ID/DLC/data modes, count).

use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::bail;
use buslab_can::{Frame, Id};
use buslab_canbus::CanBus;

use super::bus::{BusOpt, open, wait_sent};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// Gap between frames in milliseconds (cangen's -g; 0 = as fast as the bus takes them).
    #[arg(short = 'g', long, default_value_t = 200.0, value_parser = parse_gap)]
    pub gap: f64,
    /// Stop after this many frames (default: until Ctrl-C).
    #[arg(short = 'n', long)]
    pub count: Option<u64>,
    /// ID: a hex value, `r` random or `i` increment.
    #[arg(short = 'I', long = "id", default_value = "r")]
    pub id: Mode<u32>,
    /// DLC: 0..8, `r` random or `i` increment.
    #[arg(short = 'L', long = "dlc", default_value = "r")]
    pub dlc: Mode<u8>,
    /// Data: hex bytes (e.g. DEADBEEF), `r` random or `i` increment (a counter in the bytes).
    #[arg(short = 'D', long = "data", default_value = "r")]
    pub data: Mode<Vec<u8>>,
    /// Extended (29-bit) IDs.
    #[arg(short = 'e', long)]
    pub extended: bool,
    /// Remote frames.
    #[arg(short = 'R', long)]
    pub remote: bool,
    /// Seed for the random modes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Name this client's node on a buslab bus.
    #[arg(long)]
    pub name: Option<String>,
}

/// `-g`: milliseconds, 0..=86400000 (a day); more would overflow the pacing arithmetic.
fn parse_gap(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|g| (0.0..=86_400_000.0).contains(g))
        .ok_or_else(|| format!("gap {text:?} must be a number of milliseconds 0..=86400000"))
}

/// How one field is chosen for each frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Mode<T> {
    Fixed(T),
    Random,
    Increment,
}

fn mode<T>(s: &str, fixed: impl Fn(&str) -> Result<T, String>) -> Result<Mode<T>, String> {
    match s {
        "r" => Ok(Mode::Random),
        "i" => Ok(Mode::Increment),
        other => fixed(other).map(Mode::Fixed),
    }
}

impl FromStr for Mode<u32> {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        mode(s, |t| {
            u32::from_str_radix(t, 16)
                .ok()
                .filter(|&v| v <= 0x1FFF_FFFF && t.len() <= 8)
                .ok_or_else(|| format!("ID {t:?} must be hex 0..1FFFFFFF, r or i"))
        })
    }
}

impl FromStr for Mode<u8> {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        mode(s, |t| {
            t.parse::<u8>()
                .ok()
                .filter(|&v| v <= 8)
                .ok_or_else(|| format!("DLC {t:?} is out of range 0..8 (or r, i)"))
        })
    }
}

impl FromStr for Mode<Vec<u8>> {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        mode(s, |t| {
            let bad = || format!("data {t:?} must be 0..8 bytes of hex (or r, i)");
            if t.len() % 2 != 0 || t.len() > 16 {
                return Err(bad());
            }
            (0..t.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&t[i..i + 2], 16).map_err(|_| bad()))
                .collect()
        })
    }
}

/// xorshift64*: reproducible random fields without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

/// Makes the frames one after another.
pub struct Generator {
    args_id: Mode<u32>,
    args_dlc: Mode<u8>,
    args_data: Mode<Vec<u8>>,
    extended: bool,
    remote: bool,
    rng: Rng,
    n: u64,
}

impl Generator {
    pub fn new(args: &Args) -> anyhow::Result<Self> {
        if let Mode::Fixed(id) = args.id
            && !args.extended
            && id > 0x7FF
        {
            bail!("ID {id:X} needs -e (extended): standard IDs are 000..7FF");
        }
        if let (Mode::Fixed(data), Mode::Fixed(dlc)) = (&args.data, &args.dlc)
            && data.len() != *dlc as usize
        {
            bail!("data has {} bytes but -L says {dlc}", data.len());
        }
        Ok(Self {
            args_id: args.id.clone(),
            args_dlc: args.dlc.clone(),
            args_data: args.data.clone(),
            extended: args.extended,
            remote: args.remote,
            rng: Rng(args.seed.max(1)),
            n: 0,
        })
    }

    pub fn next_frame(&mut self) -> Frame {
        let n = self.n;
        self.n += 1;
        let max = if self.extended { 0x1FFF_FFFF } else { 0x7FF };
        let raw = match self.args_id {
            Mode::Fixed(v) => v,
            Mode::Random => (self.rng.next() as u32) & max,
            Mode::Increment => (n as u32) & max,
        };
        let id = if self.extended {
            Id::extended(raw).expect("masked to 29 bits")
        } else {
            Id::standard(raw as u16).expect("masked to 11 bits")
        };
        let dlc = match (&self.args_dlc, &self.args_data) {
            (Mode::Fixed(d), _) => *d,
            (_, Mode::Fixed(data)) => data.len() as u8,
            (Mode::Random, _) => (self.rng.next() % 9) as u8,
            (Mode::Increment, _) => (n % 9) as u8,
        };
        if self.remote {
            return Frame::remote(id, dlc).expect("dlc 0..8");
        }
        let data: Vec<u8> = match &self.args_data {
            Mode::Fixed(d) => d.clone(),
            Mode::Random => (0..dlc).map(|_| self.rng.next() as u8).collect(),
            Mode::Increment => n.to_le_bytes()[..dlc as usize].to_vec(),
        };
        Frame::data(id, &data).expect("at most 8 bytes")
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut generator = Generator::new(&args)?;
    let mut open = open(&args.bus.bus)?;
    if let (Some(name), true) = (&args.name, open.extensions) {
        open.bus.set_name(name)?;
    }
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst));
    }
    let gap = Duration::from_secs_f64(args.gap / 1000.0);
    let start = Instant::now();
    let mut sent = 0u64;
    while !stop.load(Ordering::SeqCst) && args.count.is_none_or(|n| sent < n) {
        open.bus.send(&generator.next_frame())?;
        sent += 1;
        if !gap.is_zero() {
            // Paced against the start so the rate does not drift.
            let due = start + gap * sent as u32;
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
    }
    let timeout = Duration::from_secs(2) + Duration::from_millis(sent / 2);
    wait_sent(&mut open, sent, timeout)
}
