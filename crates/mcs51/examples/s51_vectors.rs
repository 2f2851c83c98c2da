//! Makes per-opcode test vectors with SDCC's simulator `s51` (ucsim), or checks a fresh random
//! sample of them against this core.
//!
//! ```sh
//! # the committed vectors: N per opcode, seeds 0..N
//! cargo run --release -p buslab-mcs51 --example s51_vectors -- generate 32 crates/mcs51/tests/data/s51_vectors.txt
//! # N random (opcode, seed) pairs run in s51 and in the core, compared; exit 1 on a difference
//! cargo run --release -p buslab-mcs51 --example s51_vectors -- compare 2000 [BASE_SEED]
//! ```
//!
//! `s51` runs one command file per batch: for each vector it writes the state (internal RAM,
//! the registers, code and external data bytes), sets PC, steps once and dumps RAM, SFRs and
//! the external data bytes; the PC and the clock count come from its step report.

#[path = "../tests/vectors/mod.rs"]
mod vectors;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};

use vectors::{Rng, Setup, Snapshot, Vector, WATCHED_SFRS};

/// The part `s51` simulates: an 80C51 (128 bytes of internal RAM).
const S51_CPU: &str = "80C51";
const BATCH: usize = 400;
/// PSW and ACC.
const PSW_ACC: (u8, u8) = (0xD0, 0xE0);

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["generate", per, out] => parse(per).and_then(|per| generate(per, Path::new(out))),
        ["compare", count] => parse(count).and_then(|n| compare(n, random_seed())),
        ["compare", count, seed] => {
            parse(count).and_then(|n| parse(seed).and_then(|seed| compare(n, seed)))
        }
        _ => Err("usage: s51_vectors generate PER_OPCODE FILE | compare COUNT [BASE_SEED]".into()),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("s51_vectors: {e}");
            ExitCode::from(2)
        }
    }
}

fn parse<T: std::str::FromStr>(s: &str) -> Result<T, String> {
    s.parse()
        .map_err(|_| format!("{s:?} is not a number (a count or seed is expected)"))
}

fn random_seed() -> u64 {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    t ^ u64::from(std::process::id()) << 32
}

fn generate(per_opcode: u32, out: &Path) -> Result<bool, String> {
    let setups: Vec<Setup> = (0..=255u8)
        .flat_map(|op| (0..per_opcode).map(move |seed| vectors::setup(op, seed)))
        .collect();
    let results = run_s51(&setups)?;
    let mut text = format!(
        "# Per-opcode vectors of buslab's MCS-51 core, made with SDCC's s51 ({}, -t {S51_CPU}) by\n\
         # `cargo run --release -p buslab-mcs51 --example s51_vectors -- generate {per_opcode} FILE`.\n\
         # A line: opcode (hex), seed (the state before is tests/vectors/mod.rs's setup(opcode,\n\
         # seed)), machine cycles, then what changed: pc=PC, iXX=internal RAM, sXX=SFR,\n\
         # xXXXX=external data.\n",
        s51_version()?
    );
    for (s, (after, cycles)) in setups.iter().zip(&results) {
        let v = Vector {
            op: s.op,
            seed: s.seed,
            cycles: *cycles,
            changes: vectors::changes(&s.before(), after),
        };
        writeln!(text, "{}", v.line()).unwrap();
    }
    let tmp = out.with_extension(format!("tmp.{}", std::process::id()));
    std::fs::write(&tmp, &text).map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, out).map_err(|e| format!("cannot rename to {}: {e}", out.display()))?;
    println!(
        "{} vectors ({per_opcode} per opcode) in {}",
        setups.len(),
        out.display()
    );
    Ok(true)
}

fn compare(count: usize, base: u64) -> Result<bool, String> {
    let mut rng = Rng::new(base);
    let setups: Vec<Setup> =
        std::iter::repeat_with(|| vectors::setup(rng.byte(), rng.next() as u32))
            .filter(|s| !vectors::beyond_s51(s))
            .take(count)
            .collect();
    let results = run_s51(&setups)?;
    let mut differ = 0;
    let mut opcodes = [false; 256];
    for (s, (after, cycles)) in setups.iter().zip(&results) {
        opcodes[usize::from(s.op)] = true;
        let expected = Vector {
            op: s.op,
            seed: s.seed,
            cycles: *cycles,
            changes: vectors::changes(&s.before(), after),
        };
        if let Err(e) = vectors::check(&expected) {
            differ += 1;
            if differ <= 20 {
                println!("DIFFERENT {e}");
            }
        }
    }
    let ops = opcodes.iter().filter(|&&o| o).count();
    println!(
        "s51 against buslab-mcs51: {count} random vectors over {ops} opcodes (base seed {base}): \
         {} equal, {differ} different",
        count - differ
    );
    Ok(differ == 0)
}

fn s51_version() -> Result<String, String> {
    let out = Command::new("s51")
        .arg("-v")
        .output()
        .map_err(|e| format!("cannot run s51 (Debian package sdcc-ucsim): {e}"))?;
    Ok(String::from_utf8_lossy(&out.stdout)
        .trim()
        .replace("s51: ", "ucsim "))
}

/// Runs every setup in `s51`; the state after each and its machine cycles.
fn run_s51(setups: &[Setup]) -> Result<Vec<(Snapshot, u64)>, String> {
    let dir = std::env::temp_dir().join(format!("s51_vectors.{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let result = setups
        .chunks(BATCH)
        .enumerate()
        .map(|(i, batch)| run_batch(&dir.join(format!("batch{i}.cmd")), batch))
        .collect::<Result<Vec<_>, _>>();
    let _ = std::fs::remove_dir_all(&dir);
    Ok(result?.into_iter().flatten().collect())
}

fn run_batch(file: &PathBuf, batch: &[Setup]) -> Result<Vec<(Snapshot, u64)>, String> {
    let mut cmd = String::new();
    for s in batch {
        write!(cmd, "set memory iram 0").unwrap();
        for b in s.iram {
            write!(cmd, " 0x{b:02x}").unwrap();
        }
        cmd.push('\n');
        for &(a, v) in &s.sfrs {
            writeln!(cmd, "set memory sfr 0x{a:02x} 0x{v:02x}").unwrap();
        }
        for &(a, v) in &s.code {
            writeln!(cmd, "set memory rom 0x{a:04x} 0x{v:02x}").unwrap();
        }
        for &(a, v) in &s.xdata {
            writeln!(cmd, "set memory xram 0x{a:04x} 0x{v:02x}").unwrap();
        }
        writeln!(cmd, "pc 0x{:04x}\nstep", s.pc).unwrap();
        writeln!(cmd, "dump /h iram 0 0x7f 128\ndump /h sfr 0x80 0xff 128").unwrap();
        for a in s.xdata_addresses() {
            writeln!(cmd, "dump /h xram 0x{a:04x} 0x{a:04x} 1").unwrap();
        }
    }
    cmd.push_str("quit\n");
    std::fs::write(file, cmd).map_err(|e| format!("{}: {e}", file.display()))?;
    let out = Command::new("s51")
        .args(["-t", S51_CPU, "-b", "-q", "-C"])
        .arg(file)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot run s51 (Debian package sdcc-ucsim): {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let mut lines = text.lines();
    batch.iter().map(|s| read_result(&mut lines, s)).collect()
}

/// Reads one vector's step report and dumps.
fn read_result<'a>(
    lines: &mut impl Iterator<Item = &'a str>,
    s: &Setup,
) -> Result<(Snapshot, u64), String> {
    let context = || format!("s51 output for opcode {:02x} seed {}", s.op, s.seed);
    let mut find = |prefix: &str| {
        lines
            .find(|l| l.starts_with(prefix))
            .ok_or_else(|| format!("{}: no line starting {prefix:?}", context()))
    };
    // "Stop at 0x000102: (109) stepped 12 ticks"
    let stop = find("Stop at 0x")?;
    let pc = u16::from_str_radix(&stop[10..16], 16).map_err(|e| format!("{stop:?}: {e}"))?;
    let ticks: u64 = stop
        .split_whitespace()
        .rev()
        .nth(1)
        .and_then(|t| t.parse().ok())
        .ok_or_else(|| format!("{}: no tick count in {stop:?}", context()))?;
    find("dump /h iram")?;
    let iram_line = find("0x00 ")?;
    let iram: [u8; 128] = hex_bytes(iram_line, 128)?.try_into().unwrap();
    find("dump /h sfr")?;
    let sfr = hex_bytes(find("0x80 ")?, 128)?;
    let mut sfrs: Vec<u8> = WATCHED_SFRS
        .iter()
        .map(|&a| sfr[usize::from(a - 0x80)])
        .collect();
    // s51 shows PSW.P as last written until A changes (after POP PSW, say); the hardware
    // recomputes it from A every cycle.
    let acc = sfr[usize::from(PSW_ACC.1 - 0x80)];
    let psw = &mut sfrs[WATCHED_SFRS.iter().position(|&a| a == PSW_ACC.0).unwrap()];
    *psw = (*psw & !1) | (acc.count_ones() & 1) as u8;
    let mut xdata = Vec::new();
    for a in s.xdata_addresses() {
        find("dump /h xram")?;
        let line = find(&format!("0x{a:04x} "))?;
        xdata.push((a, hex_bytes(line, 1)?[0]));
    }
    Ok((
        Snapshot {
            pc,
            iram,
            sfrs,
            xdata,
        },
        ticks / 12,
    ))
}

/// The `n` hex bytes after the address of a `dump /h` line.
fn hex_bytes(line: &str, n: usize) -> Result<Vec<u8>, String> {
    let bytes: Vec<u8> = line
        .split_whitespace()
        .skip(1)
        .take(n)
        .map(|b| u8::from_str_radix(b, 16))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("dump line {line:?}: {e}"))?;
    if bytes.len() == n {
        Ok(bytes)
    } else {
        Err(format!(
            "dump line {line:?} has {} bytes, not {n}",
            bytes.len()
        ))
    }
}
