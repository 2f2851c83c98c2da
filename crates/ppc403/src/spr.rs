//! The special purpose registers (`mfspr`, `mtspr`, `mftb`) and the MSR's instructions
//! (`mfmsr`, `mtmsr`, `wrtee`, `wrteei`).
//!
//! An SPR number with bit 0x10 set is a supervisor register: problem state gets the
//! privileged-instruction exception. A number the 403GA does not have, or a write to a
//! read-only one (PVR, ICDBDR, TBHU/TBLU), is an illegal instruction.

/// The PPC403GA's processor version (as QEMU's CPU table gives it).
pub const PVR_403GA: u32 = 0x0020_0011;

pub mod number {
    pub const XER: u32 = 1;
    pub const LR: u32 = 8;
    pub const CTR: u32 = 9;
    pub const SRR0: u32 = 26;
    pub const SRR1: u32 = 27;
    /// `mftb`'s time base numbers (TBL, TBU).
    pub const TBL_READ: u32 = 268;
    pub const TBU_READ: u32 = 269;
    pub const SPRG0: u32 = 272;
    pub const SPRG3: u32 = 275;
    pub const PVR: u32 = 287;
    /// The user-mode, read-only view of the time base (403GC and later; harmless here).
    pub const TBHU: u32 = 0x3CC;
    pub const TBLU: u32 = 0x3CD;
    pub const ICDBDR: u32 = 0x3D3;
    pub const ESR: u32 = 0x3D4;
    pub const DEAR: u32 = 0x3D5;
    pub const EVPR: u32 = 0x3D6;
    pub const CDBCR: u32 = 0x3D7;
    pub const TSR: u32 = 0x3D8;
    pub const TCR: u32 = 0x3DA;
    pub const PIT: u32 = 0x3DB;
    pub const TBHI: u32 = 0x3DC;
    pub const TBLO: u32 = 0x3DD;
    pub const SRR2: u32 = 0x3DE;
    pub const SRR3: u32 = 0x3DF;
    pub const DBSR: u32 = 0x3F0;
    pub const DBCR: u32 = 0x3F2;
    pub const IAC1: u32 = 0x3F4;
    pub const IAC2: u32 = 0x3F5;
    pub const DAC1: u32 = 0x3F6;
    pub const DAC2: u32 = 0x3F7;
    pub const DCCR: u32 = 0x3FA;
    pub const ICCR: u32 = 0x3FB;
    pub const PBL1: u32 = 0x3FC;
    pub const PBU2: u32 = 0x3FF;
}

/// The supervisor registers kept as written (caches, debug and protection are not
/// modelled).
#[derive(Clone, Debug, Default)]
pub(crate) struct Sprs {
    pub icdbdr: u32,
    pub cdbcr: u32,
    pub dbsr: u32,
    pub dbcr: u32,
    pub iac: [u32; 2],
    pub dac: [u32; 2],
    pub dccr: u32,
    pub iccr: u32,
    /// PBL1, PBU1, PBL2, PBU2.
    pub protection: [u32; 4],
}
