//! The OS area (0000h..03FFh of code space) as a user program sees it: the entry points it
//! may call, the interrupt vectors, and the stand-in EPROM the model answers code fetches with.
//!
//! The OS is the Rust model, not 8051 code: the core stops (a trap) when the program counter
//! enters 0000h..03F3h and the model does what the OS routine there would. Only the waiting
//! loops of `Sende` and `Empf` are real code (at 03F4h, the end of the OS area), so a
//! program's own interrupts go on being served while it waits in them, as on the cell.
//!
//! ```text
//! 0000h  reset: the OS starts and resumes the stored mode (a program may LJMP here)
//! 0003h  INT0 (RxD): "Inter", a byte 0 on the line stops the program
//! 000Bh  timer 0   -> LJMP 040Bh      the other vectors lead into the program area, where
//! 0013h  INT1      -> LJMP 0413h      `sdcc --code-loc 0x400` puts its vector table
//! 001Bh  timer 1   -> LJMP 041Bh
//! 0023h  serial    -> LJMP 0423h
//! 0030h  Sende: sends A
//! 0033h  Empf: receives a byte into A
//! 0040h  where the program returns to (its return address at start): back to the OS
//! 03F4h  JNB TI,$ / LJMP 0036h        Sende's wait (0036h: Sende's end, trapped)
//! 03FAh  JNB RI,$ / LJMP 0039h        Empf's wait (0039h: Empf's end, trapped)
//! other  trapped: a jump anywhere else in the OS area is a fault at the address it reached
//!        (01h bytes to MOVC)
//! ```

use std::ops::RangeInclusive;

use crate::memory::PROGRAM_AREA;

/// The reset entry: the OS starts here (after power-on, RESET, or a program's `LJMP 0`).
pub const RESET: u16 = 0x0000;
/// INT0's vector: the OS's routine "Inter" (RxD is wired to INT0).
pub const INTER: u16 = 0x0003;
/// `Sende`: sends the byte in A on the line and returns when it has left.
pub const SENDE: u16 = 0x0030;
/// `Empf`: waits for a byte from the line and returns it in A.
pub const EMPF: u16 = 0x0033;
/// The return address the OS pushes when it starts a program: a `RET` from the program's
/// outermost level returns to the OS's command loop.
pub const PROGRAM_RETURN: u16 = 0x0040;

/// Where `Sende`'s wait loop falls through to (trapped: the rest of `Sende`).
pub(crate) const SENDE_DONE: u16 = 0x0036;
/// Where `Empf`'s wait loop falls through to (trapped: the rest of `Empf`).
pub(crate) const EMPF_DONE: u16 = 0x0039;
/// `Sende`'s wait: `JNB TI,$`.
pub(crate) const SENDE_WAIT: u16 = 0x03F4;
/// `Empf`'s wait: `JNB RI,$`.
pub(crate) const EMPF_WAIT: u16 = 0x03FA;
/// Where the core stops for the model: the whole OS area but the waits, so a jump into it
/// is seen where it lands.
pub(crate) const TRAPS: RangeInclusive<u16> = 0x0000..=SENDE_WAIT - 1;

/// The interrupt vectors that lead into the program area (all but INT0's), with the address
/// they jump to.
pub(crate) fn vector_target(addr: u16) -> Option<u16> {
    matches!(addr, 0x000B | 0x0013 | 0x001B | 0x0023).then(|| PROGRAM_AREA + addr)
}

/// Machine cycles of the OS code a trap stands for (what the routine would spend besides
/// its waits), so a program's timing is that of the cell.
pub(crate) mod cycles {
    /// `PUSH IE`, `CLR EX0`, `CLR TI`, `MOV SBUF,A`, `LJMP` to the wait.
    pub const SENDE_ENTRY: u64 = 7;
    /// `CLR TI`, restoring EX0 (`POP`, `MOV`), `RET`.
    pub const SENDE_END: u64 = 5;
    /// `PUSH IE`, `CLR EX0`, `LJMP` to the wait.
    pub const EMPF_ENTRY: u64 = 5;
    /// `CLR RI`, `MOV A,SBUF`, `CLR IE0`, restoring EX0, `RET`.
    pub const EMPF_END: u64 = 7;
    /// "Inter" looking at a byte that is not 0: `CLR IE0`, a compare, `RETI`.
    pub const INTER_RETURN: u64 = 6;
    /// The `LJMP` of a vector into the program area.
    pub const VECTOR: u64 = 2;
}

/// What a code fetch (or `MOVC`) below 0400h reads: the stand-in EPROM.
pub(crate) fn code(addr: u16) -> u8 {
    const WAITS: [u8; 12] = [
        0x30, 0x99, 0xFD, // JNB TI,$
        0x02, 0x00, 0x36, // LJMP 0036h
        0x30, 0x98, 0xFD, // JNB RI,$
        0x02, 0x00, 0x39, // LJMP 0039h
    ];
    // Vectors are at 3 + 8n: an LJMP's three bytes from there.
    let offset = addr.wrapping_sub(3) % 8;
    if let Some(target) = vector_target(addr.wrapping_sub(offset)).filter(|_| offset < 3) {
        let [high, low] = target.to_be_bytes();
        return [0x02, high, low][usize::from(offset)];
    }
    match addr.checked_sub(SENDE_WAIT) {
        Some(i) if usize::from(i) < WAITS.len() => WAITS[usize::from(i)],
        _ => 0x01,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stand_in_rom_has_the_vectors_and_the_wait_loops() {
        assert_eq!(
            [code(0x000B), code(0x000C), code(0x000D)],
            [0x02, 0x04, 0x0B]
        );
        assert_eq!(
            [code(0x0023), code(0x0024), code(0x0025)],
            [0x02, 0x04, 0x23]
        );
        assert_eq!(code(0x000E), 0x01);
        assert_eq!(
            [code(0x03F4), code(0x03F5), code(0x03F6)],
            [0x30, 0x99, 0xFD]
        );
        assert_eq!(
            [code(0x03FD), code(0x03FE), code(0x03FF)],
            [0x02, 0x00, 0x39]
        );
        assert_eq!([code(0x010C), code(0x03F3), code(0x0001)], [0x01; 3]);
        assert!(TRAPS.contains(&SENDE_DONE) && TRAPS.contains(&EMPF_DONE));
        assert!(!TRAPS.contains(&SENDE_WAIT) && !TRAPS.contains(&EMPF_WAIT));
        // Everything else in the OS area is trapped.
        assert_eq!((*TRAPS.start(), *TRAPS.end() + 1), (0, SENDE_WAIT));
        assert_eq!(usize::from(EMPF_WAIT + 6), usize::from(PROGRAM_AREA));
    }
}
