//! The 403's timers, all clocked by the CPU clock: the 64-bit time base (TBHI:TBLO), the
//! programmable interval timer (PIT, a 32-bit down-counter, reloaded with `TCR[ARE]`), the fixed
//! interval timer (FIT, an event each time the time base crosses a multiple of 2^9, 2^13,
//! 2^17 or 2^21) and the watchdog (a time-out each 2^17, 2^21, 2^25 or 2^29 cycles: the first
//! sets `TSR[ENW]`, the second `TSR[WIS]` (an interrupt with `TCR[WIE]`), the third resets the core
//! when `TCR[WRC]` asks for it).
//!
//! Nothing counts per cycle: the time base is `now` plus an offset, the PIT an expiry cycle,
//! and `catch_up_timers` works out what happened since it last looked.

/// TCR's bits.
pub mod tcr {
    /// Watchdog period: 2^(17 + 4 × WP) cycles.
    pub const WP: u32 = 0xC000_0000;
    /// Watchdog reset control: 0 none, 1 core, 2 chip, 3 system.
    pub const WRC: u32 = 0x3000_0000;
    pub const WIE: u32 = 0x0800_0000;
    pub const PIE: u32 = 0x0400_0000;
    /// FIT period: 2^(9 + 4 × FP) cycles.
    pub const FP: u32 = 0x0300_0000;
    pub const FIE: u32 = 0x0080_0000;
    pub const ARE: u32 = 0x0040_0000;
}

/// TSR's bits (write 1 to clear).
pub mod tsr {
    pub const ENW: u32 = 0x8000_0000;
    pub const WIS: u32 = 0x4000_0000;
    /// The watchdog reset that happened (`TCR[WRC]` at the time).
    pub const WRS: u32 = 0x3000_0000;
    pub const PIS: u32 = 0x0800_0000;
    pub const FIS: u32 = 0x0400_0000;
}

/// The watchdog's reset, as `TCR[WRC]` asked for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WatchdogReset {
    Core,
    Chip,
    System,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Timers {
    pub tcr: u32,
    pub tsr: u32,
    /// The time base is `now + tb_offset` (wrapping).
    pub tb_offset: u64,
    /// The cycle the status bits are up to date for.
    pub checked: u64,
    /// The cycle the PIT reaches 0 (`None`: it is 0, stopped).
    pub pit_expiry: Option<u64>,
    /// The PIT's last written value (what `TCR[ARE]` reloads).
    pub pit_reload: u32,
    /// A watchdog reset due, not yet reported.
    pub reset: Option<WatchdogReset>,
}

pub(crate) fn fit_bits(tcr: u32) -> u32 {
    9 + 4 * ((tcr & tcr::FP) >> 24)
}

pub(crate) fn watchdog_bits(tcr: u32) -> u32 {
    17 + 4 * (tcr >> 30)
}

/// How many multiples of 2^`bits` the time base crossed going from `from` to `to`.
pub(crate) fn crossings(from: u64, to: u64, bits: u32) -> u64 {
    (to >> bits).wrapping_sub(from >> bits)
}

/// The cycles from time base `tb` to its next multiple of 2^`bits` (1..=2^bits).
pub(crate) fn to_next_multiple(tb: u64, bits: u32) -> u64 {
    let period = 1u64 << bits;
    period - (tb & (period - 1))
}
