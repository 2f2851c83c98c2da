//! `buslab wire`: a frame as CAN wire bits and back (the seed's bit-by-bit "decode" program).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, bail};
use buslab_can::Frame;
use buslab_can::wire::{self, Bits, Encoded, Field, Span};

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Print a frame's wire bits, SOF to the end of EOF, as on a bus where a receiver
    /// acknowledged (ACK slot dominant). 0 = dominant, 1 = recessive.
    Encode(EncodeArgs),
    /// Rebuild a frame from wire bits starting at SOF (stuff bits included); print it in
    /// can-utils syntax with its CRC, or the error with its wire bit position.
    Decode(DecodeArgs),
}

#[derive(clap::Args)]
struct EncodeArgs {
    /// The frame in can-utils syntax: 123#1122, 12345678#, 123#R, 123#R4.
    frame: String,
    /// Print the de-stuffed bits (no stuff bits) instead of the bits on the wire.
    #[arg(long)]
    unstuffed: bool,
    /// Annotate the bits field by field (stuff bits in [brackets], CRC in hex).
    #[arg(long)]
    fields: bool,
    /// Show the ACK slot recessive, as the transmitter sends it (nobody acknowledged).
    #[arg(long)]
    no_ack: bool,
    /// Also write the bus level as a VCD waveform, with idle bus before and after the frame.
    #[arg(long, value_name = "FILE")]
    vcd: Option<PathBuf>,
    /// Bit rate of the VCD waveform in bit/s (1..=1000000).
    #[arg(long, value_name = "N", default_value_t = 500_000, requires = "vcd")]
    bitrate: u32,
}

#[derive(clap::Args)]
struct DecodeArgs {
    /// The wire bits as 0/1, from SOF; spaces and underscores may separate groups (several
    /// arguments are joined).
    #[arg(required = true, num_args = 1.., allow_hyphen_values = true)]
    bits: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Encode(args) => encode(args),
        Command::Decode(args) => decode(args),
    }
}

fn encode(args: EncodeArgs) -> anyhow::Result<()> {
    let frame: Frame = args
        .frame
        .parse()
        .with_context(|| format!("invalid frame {:?}", args.frame))?;
    if !(1..=1_000_000).contains(&args.bitrate) {
        bail!(
            "bit rate {} is out of range 1..=1000000 bit/s",
            args.bitrate
        );
    }
    let enc = wire::encode(&frame);
    let view = View {
        unstuffed: args.unstuffed,
        acked: !args.no_ack,
    };
    println!("{}", view.bits(&enc));
    if args.fields {
        print!("{}", annotate(&enc, view));
    }
    if let Some(path) = &args.vcd {
        let wire = View {
            unstuffed: false,
            ..view
        };
        let text = vcd(&wire.bits(&enc), args.bitrate, &frame, enc.crc());
        std::fs::write(path, text)
            .with_context(|| format!("cannot write VCD file {}", path.display()))?;
    }
    Ok(())
}

/// Which bits of an encoded frame to show.
#[derive(Clone, Copy)]
struct View {
    unstuffed: bool,
    /// ACK slot dominant (a receiver acknowledged) rather than as sent.
    acked: bool,
}

impl View {
    fn bits(self, enc: &Encoded) -> Bits {
        match (self.unstuffed, self.acked) {
            (false, true) => enc.on_bus(),
            (false, false) => *enc.stuffed(),
            (true, true) => enc.unstuffed_on_bus(),
            (true, false) => enc.unstuffed(),
        }
    }
}

/// One line per field: name, bit positions, the bits (stuff bits in brackets), the value.
fn annotate(enc: &Encoded, view: View) -> String {
    let unstuffed = view.unstuffed;
    let bits = view.bits(enc);
    let spans = if unstuffed {
        enc.fields()
    } else {
        enc.wire_fields()
    };
    let frame = enc.frame();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{frame}  CRC 0x{:04X}  {} stuff bits  {} {} bits SOF..EOF  (0 = dominant, ACK slot {})",
        enc.crc(),
        enc.stuff_bits(),
        bits.len(),
        if unstuffed { "de-stuffed" } else { "wire" },
        if view.acked {
            "as acknowledged"
        } else {
            "as sent"
        },
    );
    for span in spans.iter() {
        let positions = if span.len == 1 {
            format!("{}", span.start)
        } else {
            format!("{}..{}", span.start, span.end() - 1)
        };
        let mut shown = String::new();
        let mut data_bits = 0;
        for i in span.start as usize..span.end() {
            let c = if bits.bit(i) { '1' } else { '0' };
            if !unstuffed && enc.is_stuff_bit(i) {
                let _ = write!(shown, "[{c}]");
                continue;
            }
            // Data bytes are easier to read one group each.
            if span.field == Field::Data && data_bits > 0 && data_bits % 8 == 0 {
                shown.push(' ');
            }
            data_bits += 1;
            shown.push(c);
        }
        let _ = writeln!(
            out,
            "  {:<13} {:>7}  {:<24} {}",
            span.field.name(),
            positions,
            shown,
            value(enc, span)
        );
    }
    if !unstuffed && enc.stuff_bits() > 0 {
        out.push_str("  [x] = stuff bit\n");
    }
    out
}

fn value(enc: &Encoded, span: &Span) -> String {
    let frame = enc.frame();
    let id = frame.id().as_raw();
    match span.field {
        Field::Id if frame.is_extended() => format!("base 0x{:03X}", id >> 18),
        Field::Id => format!("0x{id:03X}"),
        Field::IdExt => format!("0x{:05X} (ID 0x{id:08X})", id & 0x3_FFFF),
        Field::Rtr => (if frame.is_remote() { "remote" } else { "data" }).into(),
        Field::Dlc => format!("{}", enc.dlc()),
        Field::Data => frame
            .payload()
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" "),
        Field::Crc => format!("0x{:04X}", enc.crc()),
        _ => String::new(),
    }
}

/// Idle bus bits written before and after the frame in a VCD.
const VCD_IDLE_BITS: usize = 10;

/// A VCD of the bus level: `VCD_IDLE_BITS` recessive, the frame, `VCD_IDLE_BITS` recessive.
fn vcd(bits: &Bits, bitrate: u32, frame: &Frame, crc: u16) -> String {
    let at = |bit: usize| bit as u64 * 1_000_000_000 / bitrate as u64;
    let mut out = String::new();
    let _ = writeln!(out, "$version buslab wire encode $end");
    let _ = writeln!(
        out,
        "$comment {frame} CRC 0x{crc:04X} at {bitrate} bit/s; 1 = recessive $end"
    );
    let _ = writeln!(out, "$timescale 1 ns $end");
    let _ = writeln!(out, "$scope module can $end");
    let _ = writeln!(out, "$var wire 1 ! can_rx $end");
    let _ = writeln!(out, "$upscope $end");
    let _ = writeln!(out, "$enddefinitions $end");
    let _ = writeln!(out, "#0\n$dumpvars\n1!\n$end");
    let mut level = true;
    for (i, bit) in bits.iter().enumerate() {
        if bit != level {
            level = bit;
            let _ = writeln!(out, "#{}\n{}!", at(VCD_IDLE_BITS + i), bit as u8);
        }
    }
    let end = VCD_IDLE_BITS + bits.len();
    if !level {
        let _ = writeln!(out, "#{}\n1!", at(end));
    }
    let _ = writeln!(out, "#{}", at(end + VCD_IDLE_BITS));
    out
}

fn decode(args: DecodeArgs) -> anyhow::Result<()> {
    let bits = parse_bits(&args.bits.join(" "))?;
    let decoded = wire::decode(bits.iter().copied()).context("cannot decode the bit string")?;
    println!("{}  CRC 0x{:04X}", decoded.frame, decoded.crc);
    let dlc_note = if decoded.dlc > 8 {
        format!(" (raw DLC {}, meaning 8 bytes)", decoded.dlc)
    } else {
        String::new()
    };
    println!(
        "  {} frame, DLC {}{dlc_note}, {} stuff bits, {} wire bits SOF..EOF, ACK slot {}",
        if decoded.frame.is_extended() {
            "extended"
        } else {
            "standard"
        },
        decoded.frame.dlc(),
        decoded.stuff_bits,
        decoded.wire_len,
        if decoded.acked {
            "dominant (acknowledged)"
        } else {
            "recessive (not acknowledged: the transmitter would signal an ACK error)"
        }
    );
    Ok(())
}

/// `0`/`1` characters; spaces and underscores are separators.
fn parse_bits(text: &str) -> anyhow::Result<Vec<bool>> {
    let mut bits = Vec::with_capacity(text.len());
    for (pos, c) in text.chars().enumerate() {
        match c {
            '0' => bits.push(false),
            '1' => bits.push(true),
            ' ' | '_' => {}
            _ => bail!(
                "invalid character {c:?} at position {pos} of the bit string: only 0, 1, spaces and underscores are allowed"
            ),
        }
    }
    if bits.is_empty() {
        bail!("the bit string has no bits: give 0/1 characters starting at SOF");
    }
    Ok(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_strings_allow_separators_only() {
        assert_eq!(parse_bits("01_1 0").unwrap(), [false, true, true, false]);
        for bad in ["012", "0x1", "1,0", "", " _ ", "０"] {
            assert!(parse_bits(bad).is_err(), "{bad:?}");
        }
        let err = parse_bits("01a").unwrap_err().to_string();
        assert!(err.contains("'a' at position 2"), "{err}");
    }

    #[test]
    fn vcd_has_header_and_edges() {
        let frame: Frame = "123#1122".parse().unwrap();
        let enc = wire::encode(&frame);
        let text = vcd(&enc.on_bus(), 500_000, &frame, enc.crc());
        assert!(text.contains("$timescale 1 ns $end"));
        assert!(text.contains("$var wire 1 ! can_rx $end"));
        // SOF falls after 10 idle bits of 2000 ns.
        assert!(text.contains("#20000\n0!"), "{text}");
        // Last timestamp: 10 + 62 + 10 bits.
        assert!(text.trim_end().ends_with("#164000"), "{text}");
    }
}
