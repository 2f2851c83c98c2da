//! `buslab gen [IFACE]`: generate traffic like can-utils' cangen (the interface first, gap,
//! ID/DLC/data modes, count).

use std::str::FromStr;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::bail;
use buslab_backends::{BusUrl, resolve};
use buslab_can::{Frame, Id};
use buslab_canbus::Filter;

use super::busopt::{WORST_FRAME_BITS, confirm_sent, one_bus, open, set_name};
use crate::units::CanUtilsDuration;

#[derive(clap::Args)]
pub struct Args {
    /// The bus, as cangen takes its interface: vcan0 (buslab's bus on this machine), an
    /// interface (can0), an SLCAN adapter's path (/dev/ttyACM0) or a URL. Default: the
    /// configuration's `bus` (docs/config.md), else vcan0.
    #[arg(value_name = "IFACE", value_parser = resolve)]
    pub iface: Option<BusUrl>,
    /// The bus, as IFACE (one or the other).
    #[arg(long, value_name = "BUS", value_parser = resolve)]
    pub bus: Option<BusUrl>,
    /// Gap between frames, with a unit (`10ms`; `0s` = as fast as the bus takes them); a bare
    /// number is milliseconds, as cangen's -g (with a warning).
    #[arg(short = 'g', long, value_name = "DURATION", default_value = "200ms", value_parser = crate::units::milliseconds_if_bare)]
    pub gap: CanUtilsDuration,
    /// Stop after this many frames (default: until Ctrl-C).
    #[arg(short = 'n', long, value_name = "COUNT")]
    pub count: Option<u64>,
    /// ID: a hex value, `r` random or `i` increment.
    #[arg(short = 'I', long = "id", value_name = "ID|r|i", default_value = "r")]
    pub id: Mode<u32>,
    /// DLC: 0..8, `r` random or `i` increment.
    #[arg(short = 'L', long = "dlc", value_name = "DLC|r|i", default_value = "r")]
    pub dlc: Mode<u8>,
    /// Data: hex bytes (e.g. DEADBEEF), `r` random or `i` increment (a counter in the bytes).
    #[arg(
        short = 'D',
        long = "data",
        value_name = "HEX|r|i",
        default_value = "r"
    )]
    pub data: Mode<Vec<u8>>,
    /// Extended (29-bit) IDs.
    #[arg(short = 'e', long)]
    pub extended: bool,
    /// Remote frames.
    #[arg(short = 'R', long)]
    pub remote: bool,
    /// Seed for the random modes (the same seed gives the same frames).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Name this client's node on a buslab bus (shown by `buslab status`).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// How long to wait at the end for the frames to be sent, beyond the time they need on
    /// the bus, with a unit (`2s`, `500ms`). A plain socketcand cannot confirm: no wait.
    #[arg(long, value_name = "DURATION", default_value = "10s", value_parser = crate::units::duration)]
    pub timeout: Duration,
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
                .filter(|_| t.bytes().all(|b| b.is_ascii_hexdigit()))
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
            // Hex digits only: `from_str_radix` would take a sign (`+f`).
            if t.len() % 2 != 0 || t.len() > 16 || !t.bytes().all(|b| b.is_ascii_hexdigit()) {
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
    args.gap.warn_if_bare("-g", "cangen");
    let gap = args.gap.duration;
    let url = &one_bus(args.iface.as_ref(), args.bus.as_ref())?;
    let mut bus = open(url)?;
    set_name(&mut bus, url, args.name.as_deref())?;
    // Only this client's own frames matter; what the bus carries is read and let go.
    bus.set_filters(&[Filter::NONE])?;
    let stop = super::interrupted()?;
    // As fast as the bus takes them, the client must not run far ahead of the bus: every frame
    // written but not sent waits in the sockets, and so does any request behind it (the last
    // `< buslab_status >` waited behind 20000 sends and timed out). So every half a lead the
    // frames so far are flushed, keeping at most about a second of bus time in flight.
    let lead = if gap.is_zero() {
        bus.admin()
            .map(|admin| admin.node_status(None))
            .transpose()?
            .map(|st| (u64::from(st.bus.bitrate) / WORST_FRAME_BITS).max(2))
    } else {
        None
    };
    // Paced against the start so the rate does not drift.
    let mut due = Instant::now();
    let mut sent = 0u64;
    while !stop.load(Ordering::SeqCst) && args.count.is_none_or(|n| sent < n) {
        bus.send(&generator.next_frame())?;
        sent += 1;
        if let Some(lead) = lead
            && sent.is_multiple_of(lead / 2)
            && let Some(admin) = bus.admin()
        {
            let wait = args.timeout + Duration::from_secs(1);
            if let Err(e) = admin.flush(wait) {
                tracing::debug!("flush after {sent} frames: {e}");
                break;
            }
        }
        if !gap.is_zero() {
            let Some(next) = due.checked_add(gap) else {
                bail!("gap {gap:?} is too long for this clock");
            };
            due = next;
            // Waiting = reading: the server need not hold the bus's frames back for us.
            while let Some(left) = due.checked_duration_since(Instant::now()) {
                if left.is_zero() {
                    break;
                }
                bus.recv(Some(left))?;
            }
        }
    }
    confirm_sent(&mut bus, url, sent, args.timeout)
}
