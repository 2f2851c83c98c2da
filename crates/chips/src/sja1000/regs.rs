//! Register addresses and bits (names as in the datasheet).

/// PeliCAN addresses.
pub mod peli {
    pub const MOD: usize = 0;
    pub const CMR: usize = 1;
    pub const SR: usize = 2;
    pub const IR: usize = 3;
    pub const IER: usize = 4;
    pub const BTR0: usize = 6;
    pub const BTR1: usize = 7;
    pub const OCR: usize = 8;
    pub const ALC: usize = 11;
    pub const ECC: usize = 12;
    pub const EWLR: usize = 13;
    pub const RXERR: usize = 14;
    pub const TXERR: usize = 15;
    /// Frame window (operating mode) / ACR0..3, AMR0..3 (reset mode).
    pub const WINDOW: usize = 16;
    pub const ACR0: usize = 16;
    pub const AMR0: usize = 20;
    pub const RMC: usize = 29;
    pub const RBSA: usize = 30;
    pub const CDR: usize = 31;
    /// Internal RAM: RX FIFO at 32..95, TX buffer copy at 96..108.
    pub const FIFO_RAM: usize = 32;
    pub const TX_RAM: usize = 96;
}

/// BasicCAN addresses.
pub mod basic {
    pub const CR: usize = 0;
    pub const CMR: usize = 1;
    pub const SR: usize = 2;
    pub const IR: usize = 3;
    pub const ACR: usize = 4;
    pub const AMR: usize = 5;
    pub const BTR0: usize = 6;
    pub const BTR1: usize = 7;
    pub const OCR: usize = 8;
    pub const TX: usize = 10;
    pub const RX: usize = 20;
    pub const CDR: usize = 31;
}

/// MOD (PeliCAN) / CR (BasicCAN) bit 0: reset mode.
pub const MOD_RM: u8 = 0x01;
pub const MOD_LOM: u8 = 0x02;
pub const MOD_STM: u8 = 0x04;
pub const MOD_AFM: u8 = 0x08;
pub const MOD_SM: u8 = 0x10;

/// BasicCAN CR interrupt enables.
pub const CR_RIE: u8 = 0x02;
pub const CR_TIE: u8 = 0x04;
pub const CR_EIE: u8 = 0x08;
pub const CR_OIE: u8 = 0x10;

pub const CMR_TR: u8 = 0x01;
pub const CMR_AT: u8 = 0x02;
pub const CMR_RRB: u8 = 0x04;
pub const CMR_CDO: u8 = 0x08;
/// PeliCAN: self-reception request. BasicCAN: go to sleep.
pub const CMR_SRR: u8 = 0x10;

pub const SR_RBS: u8 = 0x01;
pub const SR_DOS: u8 = 0x02;
pub const SR_TBS: u8 = 0x04;
pub const SR_TCS: u8 = 0x08;
pub const SR_RS: u8 = 0x10;
pub const SR_TS: u8 = 0x20;
pub const SR_ES: u8 = 0x40;
pub const SR_BS: u8 = 0x80;

pub const IR_RI: u8 = 0x01;
pub const IR_TI: u8 = 0x02;
pub const IR_EI: u8 = 0x04;
pub const IR_DOI: u8 = 0x08;
pub const IR_WUI: u8 = 0x10;
pub const IR_EPI: u8 = 0x20;
pub const IR_ALI: u8 = 0x40;
pub const IR_BEI: u8 = 0x80;

/// CDR bit 7: PeliCAN mode.
pub const CDR_PELICAN: u8 = 0x80;
