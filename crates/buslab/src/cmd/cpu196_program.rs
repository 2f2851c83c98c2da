//! `buslab cpu196 program`: user programs as WebAssembly modules in the board's flash
//! (issue 31). Arguments and printing; checking, the flash layout and the writes are in
//! `buslab-cpu196-wasm`.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use buslab_cpu196::host::{Client, Port};
use buslab_cpu196::program::ProgramRef;
use buslab_cpu196_wasm::WasmRuntime;
use buslab_cpu196_wasm::host::{self, NameIn, hook_names};
use buslab_cpu196_wasm::layout::{DEFAULT_BLOCK, MAX_MODULE, stored_name};
use buslab_link::fs::read_limited;

use super::{Confirm, bank, bar, confirm, emit};

#[derive(clap::Subcommand)]
pub enum ProgramCmd {
    /// Check a module (its imports, exports and limits) and write it into a bank from block
    /// 60h with F5 block writes, each read back. The bank is erased first: its blocks
    /// 28h..3Fh (the configuration sets) are read before and written back, 60h..FFh are the
    /// module's.
    Flash {
        /// The module (`.wasm`, at most 40928 bytes).
        module: PathBuf,
        /// Bank 0..7.
        #[arg(long, value_parser = bank)]
        bank: u8,
        /// Name the module in this configuration set (0..7) of the bank, so that START runs
        /// it (a bank without a configuration table gets one with empty sets).
        #[arg(long, value_parser = bank, value_name = "N")]
        config: Option<u8>,
        /// With --config: the set's arguments (up to 7 words, comma-separated; `arg(i)` in the
        /// module); unnamed ones are 0.
        #[arg(
            long,
            value_delimiter = ',',
            value_name = "W,W,...",
            requires = "config"
        )]
        args: Vec<u16>,
        /// The name kept with it in flash (20 bytes; default: the file name's stem).
        #[arg(long)]
        name: Option<String>,
        #[command(flatten)]
        confirm: Confirm,
    },
    /// List what each bank's configuration sets run, and the modules in flash with their
    /// hooks.
    List {
        /// Only this bank (0..7).
        #[arg(long, value_parser = bank)]
        bank: Option<u8>,
    },
    /// Check a module file against the kernel's contract, without a board.
    Check {
        /// The module (`.wasm`).
        module: PathBuf,
    },
}

fn read_module(path: &Path) -> anyhow::Result<Vec<u8>> {
    read_limited(path, MAX_MODULE as u64).with_context(|| {
        format!(
            "module {} (at most {MAX_MODULE} bytes fit in a bank)",
            path.display()
        )
    })
}

/// `program check`, which needs no board.
pub fn check(module: &Path) -> anyhow::Result<()> {
    let bytes = read_module(module)?;
    let info = WasmRuntime::new()
        .check(&bytes)
        .with_context(|| format!("{} is refused", module.display()))?;
    say!(
        "{}: {} bytes, hooks {}; imports {}",
        module.display(),
        bytes.len(),
        hook_names(&info.hooks),
        if info.imports.is_empty() {
            "nothing".to_string()
        } else {
            info.imports.join(" ")
        }
    );
    Ok(())
}

pub fn run<P: Port>(c: &mut Client<P>, p: ProgramCmd, yes: bool) -> anyhow::Result<()> {
    match p {
        ProgramCmd::Check { module } => check(&module),
        ProgramCmd::List { bank } => {
            let banks: Vec<u8> = match bank {
                Some(b) => vec![b],
                None => (0..8).collect(),
            };
            let listing = host::list(c, &banks)?;
            emit(format_args!("{}", host::describe(&listing)));
            Ok(())
        }
        ProgramCmd::Flash {
            module,
            bank,
            config,
            args,
            name,
            confirm: Confirm { yes: also },
        } => {
            if args.len() > 7 {
                bail!(
                    "--args: {} words given; a configuration set has 7",
                    args.len()
                );
            }
            let bytes = read_module(&module)?;
            // Checked before anything is asked or erased.
            let info = WasmRuntime::new()
                .check(&bytes)
                .with_context(|| format!("{} is refused", module.display()))?;
            let name = name.unwrap_or_else(|| {
                module
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default()
            });
            confirm(
                yes || also,
                &format!(
                    "erase flash bank {bank} and write {} into it (its blocks 28h..3Fh are read first and written back)",
                    module.display()
                ),
            )?;
            let name_in = config.map(|config| {
                let mut words = [0u16; 7];
                words[..args.len()].copy_from_slice(&args);
                NameIn {
                    config,
                    args: words,
                }
            });
            let pb = bar(0, &format!("writing bank {bank}"));
            let flashed = host::flash(c, bank, &name, &bytes, name_in, &mut |done, total| {
                pb.set_length(total as u64 * 256);
                pb.set_position(done as u64 * 256);
            })?;
            pb.finish_and_clear();
            say!(
                "wrote and verified \"{}\" ({} bytes, blocks {}) into bank {bank}; hooks {}",
                stored_name(&name),
                flashed.bytes,
                flashed.span(),
                hook_names(&info.hooks)
            );
            if flashed.kept > 0 {
                say!("{} blocks of 28h..3Fh written back", flashed.kept);
            }
            match config {
                Some(n) => say!(
                    "configuration {n} of bank {bank} runs it{}: START it with `monitor --bank {bank} --start {n}`",
                    if flashed.new_table {
                        " (a new configuration table: the other sets are empty)"
                    } else {
                        ""
                    }
                ),
                None => say!(
                    "no configuration set names it yet: flash it with --config N, or set a set's program word to {:04X}h",
                    ProgramRef::Module {
                        bank,
                        block: DEFAULT_BLOCK
                    }
                    .word()
                    .unwrap_or_default()
                ),
            }
            Ok(())
        }
    }
}
