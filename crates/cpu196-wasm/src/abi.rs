//! The contract between a module and the kernel: the hooks a module may export (the seed's
//! names), the kernel API it may import (module `kernel`), the hooks' return convention and
//! the limits of a run. One table each, read by validation, the runtime and the docs' tests.

/// A WebAssembly value type of the contract.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ty {
    I32,
    I64,
}

/// A function of the contract: a hook or a kernel service.
#[derive(Clone, Copy, Debug)]
pub struct Signature {
    pub name: &'static str,
    pub params: &'static [Ty],
    pub results: &'static [Ty],
    /// What the seed calls it.
    pub seed: &'static str,
}

impl Signature {
    /// `(i32, i32) -> i32`.
    pub fn describe(&self) -> String {
        describe(self.params, self.results)
    }
}

pub(crate) fn describe(params: &[Ty], results: &[Ty]) -> String {
    let list = |t: &[Ty]| {
        t.iter()
            .map(|t| match t {
                Ty::I32 => "i32",
                Ty::I64 => "i64",
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match results {
        [] => format!("({})", list(params)),
        _ => format!("({}) -> {}", list(params), list(results)),
    }
}

use Ty::{I32, I64};

const fn sig(
    name: &'static str,
    params: &'static [Ty],
    results: &'static [Ty],
    seed: &'static str,
) -> Signature {
    Signature {
        name,
        params,
        results,
        seed,
    }
}

/// The import module every kernel service lives in.
pub const IMPORT_MODULE: &str = "kernel";

/// The hooks, in the order of [`Hook`].
pub const HOOKS: [Signature; 9] = [
    sig("init_prog", &[], &[I32], "_init_prog_"),
    sig("user_prog", &[], &[I32], "_user_prog_"),
    sig("RS_prog", &[I32, I32], &[], "_RS_prog_"),
    sig("pic_prog", &[I32, I32], &[I32], "_pic_prog_"),
    sig("pas_prog1", &[], &[I32], "_pas_prog1_"),
    sig("pas_prog2", &[], &[I32], "_pas_prog2_"),
    sig("AD_prog", &[], &[I32], "_AD_prog_"),
    sig("fin_prog", &[], &[], "_fin_prog_"),
    sig("Main_Fread", &[I32, I32], &[], "Main_Fread"),
];

/// A hook by its place in [`HOOKS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hook {
    Init,
    User,
    Rs,
    Pic,
    Timer1,
    Timer2,
    Ad,
    Fin,
    Fread,
}

impl Hook {
    pub const ALL: [Hook; 9] = [
        Hook::Init,
        Hook::User,
        Hook::Rs,
        Hook::Pic,
        Hook::Timer1,
        Hook::Timer2,
        Hook::Ad,
        Hook::Fin,
        Hook::Fread,
    ];

    pub fn signature(self) -> &'static Signature {
        &HOOKS[self as usize]
    }

    pub fn name(self) -> &'static str {
        self.signature().name
    }

    pub fn by_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|h| h.name() == name)
    }
}

/// The kernel API (imports from [`IMPORT_MODULE`]).
pub const IMPORTS: [Signature; 20] = [
    sig("affiche", &[I32, I32, I32], &[], "affiche(n, format, tab)"),
    sig("fopen", &[I32, I32, I32], &[I32], "fopen(n, nom, mode)"),
    sig("fwrite", &[I32, I32, I32], &[], "fwrite(f, n, tab)"),
    sig("fread", &[I32, I32], &[], "fread(f, n)"),
    sig("fclose", &[I32], &[], "fclose(f)"),
    sig(
        "emission_canal_virtuel_16bits",
        &[I32, I32],
        &[],
        "emission_canal_virtuel_16bits(n, d)",
    ),
    sig(
        "emission_canal_virtuel_12bits",
        &[I32, I32],
        &[],
        "emission_canal_virtuel_12bits(n, d)",
    ),
    sig(
        "emission_canal_virtuel_8bits",
        &[I32, I32],
        &[],
        "emission_canal_virtuel_8bits(n, d)",
    ),
    sig("pwm", &[I32, I32], &[], "pwm0(c), pwm1(c), pwm2(c)"),
    sig("alerte", &[I32], &[], "FD _CMDALERTE_ alerte"),
    sig("ad_voie", &[I32], &[I32], "ad_voie[n].donnee"),
    sig("ad_pic", &[I32], &[I32], "ad_pic.donnee"),
    sig("arg", &[I32], &[I32], "ptrprg.user[n] words 1..7"),
    sig("now_us", &[], &[I64], "(none: the model's time)"),
    sig("wr_pic_pwm", &[I32], &[], "04 wr_pic_pwm"),
    sig("wr_pic_reference", &[I32], &[], "02 wr_pic_reference"),
    sig("wr_pic_sci", &[I32], &[], "0B wr_pic_sci"),
    sig("wr_pic_user", &[I32], &[], "0F wr_pic_user"),
    sig(
        "user_command",
        &[I32, I32],
        &[],
        "(none: the fixed length of a user command)",
    ),
    sig(
        "event_data",
        &[I32, I32],
        &[I32],
        "(none: the bytes of RS_prog / Main_Fread)",
    ),
];

/// Imports that read or write the module's memory (it must export it as `memory`).
pub const USES_MEMORY: [&str; 4] = ["affiche", "fopen", "fwrite", "event_data"];

pub fn import(name: &str) -> Option<&'static Signature> {
    IMPORTS.iter().find(|s| s.name == name)
}

/// A hook's result: bits 0..15 the seed's START word (`_NoStart_` 8000h: none), bit 16
/// `_StopExec_`; bits 17..31 must be 0.
pub const CONT_EXEC: u32 = 0x8000;
/// [`CONT_EXEC`] with the stop bit.
pub const STOP_EXEC: u32 = 0x1_8000;
pub const STOP_BIT: u32 = 0x1_0000;

/// An 80C196KC at 20 MHz: a state time is 100 ns and its common instructions take 4 to 6
/// states, so about 2 instructions a microsecond; a WebAssembly instruction (one unit of
/// wasmi's fuel) counts as one of them.
pub const FUEL_PER_US: u64 = 2;
/// The CPU time one hook call may take before the kernel stops the program.
pub const HOOK_TIME_LIMIT_US: u64 = 50_000;
/// Fuel of one hook call (and of instantiation).
pub const HOOK_FUEL: u64 = FUEL_PER_US * HOOK_TIME_LIMIT_US;
/// Linear memory a module may have, in 64 KiB pages.
pub const MAX_MEMORY_PAGES: u64 = 4;
/// Bytes of messages to the PC one hook call may queue (the kernel's transmit FIFO).
pub const MAX_OUTPUT_PER_CALL: usize = 4096;
/// Nested WebAssembly calls.
pub const MAX_CALL_DEPTH: usize = 256;
/// Table elements (function pointers).
pub const MAX_TABLE_ELEMENTS: usize = 1024;
