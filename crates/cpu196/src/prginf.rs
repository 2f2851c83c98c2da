//! The per-bank program information the kernel reads from flash (seed `prginf` at 2800h and
//! `ptrprg` at 2900h, i.e. blocks 28h and 29h of the bank chosen by START).
//!
//! `prginf` (little-endian words): `info_valide` (AA55h) · `hso[8]` · `ad_init[8][18]` ·
//! `adon[8][2]` · `adrs[8]` · `cycle[8][2]` · `cycle1[8]` · `cycle2[8]`.
//!
//! `ptrprg`: 7 upper-level pointers, then `user[8]` of 8 words each. The model cannot run
//! 80C196 code, so word 0 of `user[n]` names the program ([`ProgramRef`]: 0 or FFFFh none,
//! 1..7FFFh a built-in Rust program, `8000h | bank << 8 | block` a module stored in flash) and
//! words 1..7 are its arguments.

use crate::program::{InvalidProgramWord, ProgramRef};
use crate::wire::FLASH_BLOCK;

pub const PRGINF_BLOCK: u8 = 0x28;
pub const PTRPRG_BLOCK: u8 = 0x29;
pub const VALID: u16 = 0xAA55;

const AD_INIT: usize = 10;
const ADON: usize = AD_INIT + 8 * 18;
const ADRS: usize = ADON + 16;
const CYCLE: usize = ADRS + 8;
const CYCLE1: usize = CYCLE + 16;
const CYCLE2: usize = CYCLE1 + 16;
const USER: usize = 14;
const _: () = assert!(CYCLE2 + 16 <= FLASH_BLOCK);

/// One of the 8 configuration sets of a bank.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigSet {
    pub hso: u8,
    pub ad_init: [u8; 18],
    /// PIC A/D: `[mask, rate]` (see PIC `wr_pic_startAD`).
    pub adon: [u8; 2],
    /// PIC channels forwarded to the PC as `FB`.
    pub adrs: u8,
    /// PIC timer `[high, llllllpp]`.
    pub cycle: [u8; 2],
    /// Software timer periods in 0.8 µs steps (1250 per ms); 0 = external clock (never in the
    /// model).
    pub cycle1: u16,
    pub cycle2: u16,
    /// Word 0 of `ptrprg.user[n]` (0 = none; see [`ProgramRef`]) and its 7 arguments.
    pub program: u16,
    pub args: [u16; 7],
}

impl Default for ConfigSet {
    fn default() -> Self {
        Self {
            hso: 0,
            ad_init: [0xFF; 18],
            adon: [0, 0],
            adrs: 0,
            cycle: [0, 0],
            cycle1: 0,
            cycle2: 0,
            program: 0,
            args: [0; 7],
        }
    }
}

impl ConfigSet {
    /// The program word 0 names.
    pub fn program_ref(&self) -> Result<ProgramRef, InvalidProgramWord> {
        ProgramRef::from_word(self.program)
    }
}

fn word(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn put(b: &mut [u8], at: usize, w: u16) {
    b[at..at + 2].copy_from_slice(&w.to_le_bytes());
}

/// Reads config set `n` from the two blocks; `None` when `prginf` is not marked valid.
pub fn read_config(prginf: &[u8], ptrprg: &[u8], n: u8) -> Option<ConfigSet> {
    if word(prginf, 0) != VALID {
        return None;
    }
    let n = n as usize & 7;
    let mut ad_init = [0u8; 18];
    ad_init.copy_from_slice(&prginf[AD_INIT + 18 * n..AD_INIT + 18 * n + 18]);
    let u = USER + 16 * n;
    let program = match word(ptrprg, u) {
        0xFFFF => 0,
        p => p,
    };
    Some(ConfigSet {
        hso: prginf[2 + n],
        ad_init,
        adon: [prginf[ADON + 2 * n], prginf[ADON + 2 * n + 1]],
        adrs: prginf[ADRS + n],
        cycle: [prginf[CYCLE + 2 * n], prginf[CYCLE + 2 * n + 1]],
        cycle1: word(prginf, CYCLE1 + 2 * n),
        cycle2: word(prginf, CYCLE2 + 2 * n),
        program,
        args: core::array::from_fn(|i| word(ptrprg, u + 2 + 2 * i)),
    })
}

/// Sets config set `n`'s program word and arguments in a `ptrprg` block, leaving the rest of
/// the block as it is.
pub fn set_program(ptrprg: &mut [u8; FLASH_BLOCK], n: u8, program: u16, args: [u16; 7]) {
    let u = USER + 16 * (n as usize & 7);
    put(ptrprg, u, program);
    for (i, &arg) in args.iter().enumerate() {
        put(ptrprg, u + 2 + 2 * i, arg);
    }
}

/// Builds the two blocks from 8 config sets.
pub fn encode(sets: &[ConfigSet; 8]) -> ([u8; FLASH_BLOCK], [u8; FLASH_BLOCK]) {
    let mut a = [0xFFu8; FLASH_BLOCK];
    let mut p = [0xFFu8; FLASH_BLOCK];
    put(&mut a, 0, VALID);
    for (n, s) in sets.iter().enumerate() {
        a[2 + n] = s.hso;
        a[AD_INIT + 18 * n..AD_INIT + 18 * n + 18].copy_from_slice(&s.ad_init);
        a[ADON + 2 * n..ADON + 2 * n + 2].copy_from_slice(&s.adon);
        a[ADRS + n] = s.adrs;
        a[CYCLE + 2 * n..CYCLE + 2 * n + 2].copy_from_slice(&s.cycle);
        put(&mut a, CYCLE1 + 2 * n, s.cycle1);
        put(&mut a, CYCLE2 + 2 * n, s.cycle2);
        let u = USER + 16 * n;
        put(&mut p, u, s.program);
        for (i, &arg) in s.args.iter().enumerate() {
            put(&mut p, u + 2 + 2 * i, arg);
        }
    }
    (a, p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_sets_round_trip_through_flash_blocks() {
        let mut sets: [ConfigSet; 8] = Default::default();
        sets[3].ad_init[16] = 42;
        sets[3].cycle1 = 1250;
        sets[3].program = 2;
        sets[3].args[1] = 800;
        sets[7].adrs = 0x81;
        let (a, p) = encode(&sets);
        for n in 0..8 {
            assert_eq!(read_config(&a, &p, n).as_ref(), Some(&sets[n as usize]));
        }
        assert_eq!(read_config(&[0xFF; 256], &p, 0), None);
        let mut patched = p;
        set_program(&mut patched, 3, 0x8260, [9; 7]);
        let set = read_config(&a, &patched, 3).unwrap();
        assert_eq!((set.program, set.args), (0x8260, [9; 7]));
        assert_eq!(read_config(&a, &patched, 2), read_config(&a, &p, 2));
    }

    #[test]
    fn the_program_word_names_nothing_a_built_in_or_a_module_in_flash() {
        assert_eq!(ProgramRef::from_word(0), Ok(ProgramRef::None));
        assert_eq!(ProgramRef::from_word(0xFFFF), Ok(ProgramRef::None));
        assert_eq!(ProgramRef::from_word(4), Ok(ProgramRef::BuiltIn(4)));
        let module = ProgramRef::Module {
            bank: 5,
            block: 0x60,
        };
        assert_eq!(ProgramRef::from_word(0x8560), Ok(module));
        assert_eq!(module.word(), Some(0x8560));
        assert_eq!(
            ProgramRef::from_word(0x8860).unwrap_err().to_string(),
            "program word 8860h names no program: a module is 8000h | bank << 8 | block (bank 0..7, bits 11..14 zero)"
        );
        assert_eq!(ProgramRef::BuiltIn(0x8000).word(), None);
    }
}
