//! The host side, over any [`Port`]: flash a module into a bank with the existing `F5` block
//! writes (each read back), and list the programs the banks' configuration sets name.
//!
//! Flashing erases the bank (flash is written only blank, and erased only a bank at a time):
//! the bank's blocks 28h..3Fh (its configuration sets and whatever else a user keeps there) are
//! read first and written back, then the module from block 60h; the bank's 60h..FFh belongs to
//! its module.

use buslab_cpu196::flash::is_user_block;
use buslab_cpu196::host::{Client, ClientError, Port};
use buslab_cpu196::prginf::{self, ConfigSet, PRGINF_BLOCK, PTRPRG_BLOCK, VALID};
use buslab_cpu196::program::{ProgramRef, Registry};
use buslab_cpu196::wire::FLASH_BLOCK;

use crate::layout::{self, DEFAULT_BLOCK, HEADER};
use crate::validate::{ModuleError, ModuleInfo};
use crate::{WasmRuntime, abi::Hook};

/// Why flashing or listing failed.
#[derive(Debug, thiserror::Error)]
pub enum ProgramError {
    #[error("{0}")]
    Module(#[from] ModuleError),
    #[error("bank {bank}: {source}")]
    Board {
        bank: u8,
        #[source]
        source: ClientError,
    },
    #[error("no configuration set {0} (0..7)")]
    NoSet(u8),
}

/// A configuration set to name the module in, with its arguments.
#[derive(Clone, Copy, Debug)]
pub struct NameIn {
    pub config: u8,
    pub args: [u16; 7],
}

/// What [`flash`] did.
#[derive(Clone, Debug)]
pub struct Flashed {
    pub info: ModuleInfo,
    pub bytes: usize,
    /// The module's blocks, from [`DEFAULT_BLOCK`].
    pub blocks: usize,
    /// Blocks of 28h..3Fh written back after the erase.
    pub kept: usize,
    /// Whether a valid `prginf` had to be made (the bank had none).
    pub new_table: bool,
}

impl Flashed {
    /// The blocks the module takes, for messages: `60h..61h`.
    pub fn span(&self) -> String {
        let last = DEFAULT_BLOCK as usize + self.blocks - 1;
        format!("{DEFAULT_BLOCK:02X}h..{last:02X}h")
    }
}

fn board(bank: u8) -> impl Fn(ClientError) -> ProgramError {
    move |source| ProgramError::Board { bank, source }
}

/// Checks `module`, then erases `bank`, writes its blocks 28h..3Fh back (with the set of
/// `name_in` naming the module), and writes the module from block 60h; every block read back.
/// `progress` gets the blocks written so far and their total.
pub fn flash<P: Port>(
    c: &mut Client<P>,
    bank: u8,
    name: &str,
    module: &[u8],
    name_in: Option<NameIn>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Flashed, ProgramError> {
    let info = WasmRuntime::new().check(module)?;
    let blocks = layout::encode(name, module, DEFAULT_BLOCK).map_err(ModuleError::from)?;
    if let Some(n) = name_in
        && n.config > 7
    {
        return Err(ProgramError::NoSet(n.config));
    }
    let err = board(bank);
    let mut keep = Vec::new();
    for k in 0x28..=0x3F {
        keep.push((k, *c.flash_read(bank, k).map_err(&err)?));
    }
    let mut new_table = false;
    if let Some(n) = name_in {
        let has_table = u16::from_le_bytes([keep[0].1[0], keep[0].1[1]]) == VALID;
        if !has_table {
            let (a, p) = prginf::encode(&<[ConfigSet; 8]>::default());
            keep[0].1 = a;
            keep[1].1 = p;
            new_table = true;
        }
        let word = ProgramRef::Module {
            bank,
            block: DEFAULT_BLOCK,
        }
        .word()
        .expect("bank 0..7");
        prginf::set_program(&mut keep[1].1, n.config, word, n.args);
    }
    let keep: Vec<_> = keep
        .into_iter()
        .filter(|(_, d)| *d != [0xFF; FLASH_BLOCK])
        .collect();
    c.flash_erase(bank).map_err(&err)?;
    let total = keep.len() + blocks.len();
    for (i, (k, data)) in keep.iter().chain(&blocks).enumerate() {
        debug_assert!(is_user_block(*k));
        c.flash_write(bank, *k, data).map_err(&err)?;
        progress(i + 1, total);
    }
    Ok(Flashed {
        info,
        bytes: module.len(),
        blocks: blocks.len(),
        kept: keep.len(),
        new_table,
    })
}

/// A configuration set that names a program.
#[derive(Clone, Debug)]
pub struct SetListing {
    pub config: u8,
    /// `Err(word)`: a word that names no program.
    pub program: Result<ProgramRef, u16>,
    pub args: [u16; 7],
}

/// A module found in a bank.
#[derive(Clone, Debug)]
pub struct ModuleListing {
    pub block: u8,
    pub name: String,
    pub bytes: usize,
    /// Its hooks, or why it would not run.
    pub check: Result<ModuleInfo, String>,
}

/// What one bank holds.
#[derive(Clone, Debug)]
pub struct BankListing {
    pub bank: u8,
    /// `None`: no valid configuration table (`prginf` without AA55h).
    pub sets: Option<Vec<SetListing>>,
    pub modules: Vec<ModuleListing>,
}

/// Reads each bank's configuration sets and the modules at 60h and wherever a set points.
pub fn list<P: Port>(c: &mut Client<P>, banks: &[u8]) -> Result<Vec<BankListing>, ProgramError> {
    let runtime = WasmRuntime::new();
    let mut out = Vec::new();
    for &bank in banks {
        let err = board(bank);
        let a = c.flash_read(bank, PRGINF_BLOCK).map_err(&err)?;
        let p = c.flash_read(bank, PTRPRG_BLOCK).map_err(&err)?;
        let sets = prginf::read_config(&a[..], &p[..], 0).map(|_| {
            (0..8)
                .filter_map(|n| {
                    let set = prginf::read_config(&a[..], &p[..], n).expect("valid table");
                    (set.program != 0).then(|| SetListing {
                        config: n,
                        program: set.program_ref().map_err(|e| e.0),
                        args: set.args,
                    })
                })
                .collect::<Vec<_>>()
        });
        let mut places = vec![DEFAULT_BLOCK];
        for s in sets.iter().flatten() {
            if let Ok(ProgramRef::Module { bank: b, block }) = s.program
                && b == bank
                && !places.contains(&block)
            {
                places.push(block);
            }
        }
        let mut modules = Vec::new();
        for block in places {
            if let Some(m) = read_module(c, &runtime, bank, block)? {
                modules.push(m);
            }
        }
        out.push(BankListing {
            bank,
            sets,
            modules,
        });
    }
    Ok(out)
}

fn read_module<P: Port>(
    c: &mut Client<P>,
    runtime: &WasmRuntime,
    bank: u8,
    block: u8,
) -> Result<Option<ModuleListing>, ProgramError> {
    let err = board(bank);
    if !is_user_block(block) {
        return Ok(None);
    }
    let first = c.flash_read(bank, block).map_err(&err)?;
    let Some((name, len, crc)) = layout::parse_header(&first[..]) else {
        return Ok(None);
    };
    let mut listing = ModuleListing {
        block,
        name,
        bytes: len,
        check: Err(String::new()),
    };
    let last = block as usize + layout::blocks_for(len) - 1;
    let area_end = if block <= 0x3F { 0x3F } else { 0xFF };
    if last > area_end {
        listing.check = Err(format!(
            "its header says {len} bytes, more than fit before block {area_end:02X}h"
        ));
        return Ok(Some(listing));
    }
    let mut bytes = first[HEADER..].to_vec();
    for k in block as usize + 1..=last {
        bytes.extend_from_slice(&c.flash_read(bank, k as u8).map_err(&err)?[..]);
    }
    bytes.truncate(len);
    listing.check = if crc32fast::hash(&bytes) != crc {
        Err("damaged: its CRC-32 does not match (flash it again)".into())
    } else {
        runtime.check(&bytes).map_err(|e| e.to_string())
    };
    Ok(Some(listing))
}

/// The listing as `program list` prints it.
pub fn describe(listing: &[BankListing]) -> String {
    use std::fmt::Write as _;
    let builtins: Vec<(u16, &str)> = Registry::default().list().collect();
    let mut s = String::new();
    for bank in listing {
        let _ = writeln!(s, "bank {}", bank.bank);
        match &bank.sets {
            None => {
                let _ = writeln!(s, "  no configuration table");
            }
            Some(sets) if sets.is_empty() => {
                let _ = writeln!(s, "  no set names a program");
            }
            Some(sets) => {
                for set in sets {
                    let what = match set.program {
                        Ok(ProgramRef::BuiltIn(id)) => match builtins.iter().find(|b| b.0 == id) {
                            Some((_, name)) => format!("built-in {id} ({name})"),
                            None => format!("built-in {id} (not installed)"),
                        },
                        Ok(ProgramRef::Module { bank, block }) => {
                            format!("module at bank {bank} block {block:02X}h")
                        }
                        Ok(ProgramRef::None) => continue,
                        Err(word) => format!("invalid program word {word:04X}h"),
                    };
                    let args: Vec<String> = set.args.iter().map(u16::to_string).collect();
                    let _ = writeln!(
                        s,
                        "  set {}: {what}, arguments {}",
                        set.config,
                        args.join(" ")
                    );
                }
            }
        }
        for m in &bank.modules {
            let _ = write!(
                s,
                "  module at block {:02X}h: \"{}\", {} bytes, ",
                m.block, m.name, m.bytes
            );
            let _ = match &m.check {
                Ok(info) => writeln!(s, "hooks {}", hook_names(&info.hooks)),
                Err(why) => writeln!(s, "will not run: {why}"),
            };
        }
    }
    s
}

/// The hooks as a list, for messages.
pub fn hook_names(hooks: &[Hook]) -> String {
    hooks.iter().map(|h| h.name()).collect::<Vec<_>>().join(" ")
}
