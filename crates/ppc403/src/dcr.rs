//! The device control registers (`mtdcr`, `mfdcr`): the interrupt controller's EXISR and
//! EXIER, and, as plain registers (the board decodes its banks itself, there is no DMA
//! engine), the bank registers BR0..BR7, BEAR/BESR (set by a data machine check), IOCR and
//! the DMA channels' registers. Any other number is an illegal instruction.

pub mod number {
    pub const EXISR: u32 = 0x40;
    pub const EXIER: u32 = 0x42;
    pub const BR0: u32 = 0x80;
    pub const BR7: u32 = 0x87;
    pub const BEAR: u32 = 0x90;
    pub const BESR: u32 = 0x91;
    pub const IOCR: u32 = 0xA0;
    /// DMACR0 .. DMACC3 (four channels of eight numbers).
    pub const DMA_FIRST: u32 = 0xC0;
    pub const DMA_LAST: u32 = 0xDF;
    pub const DMASR: u32 = 0xE0;
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Dcrs {
    pub br: [u32; 8],
    pub bear: u32,
    pub besr: u32,
    pub iocr: u32,
    pub dma: [u32; (number::DMA_LAST - number::DMA_FIRST + 1) as usize],
    pub dmasr: u32,
}
