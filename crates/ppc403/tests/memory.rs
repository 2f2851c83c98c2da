//! Loads and stores: every width and form, update forms and their invalid cases, byte
//! reversal, multiple and string transfers, reservations, dcbz, alignment.

mod common;

use buslab_ppc403::{Exception, Stop};
use common::*;

const DATA: u32 = 0x8000;

fn with_data(words: &[u32]) -> impl Fn(&mut Board) {
    let words = words.to_vec();
    move |b: &mut Board| b.mem.load_words(DATA, &words)
}

/// Like `exec`, with memory prepared by `prep`.
fn exec_mem(prep: impl Fn(&mut Board), setup: &[(usize, u32)], program: &[u32]) -> Board {
    let mut words = program.to_vec();
    words.push(SC);
    let mut b = Board::new(&words);
    prep(&mut b);
    for &(r, v) in setup {
        b.cpu.set_gpr(r, v);
    }
    assert_eq!(
        b.run_to_sc(),
        Stop::SystemCall {
            at: ORG + 4 * program.len() as u32
        }
    );
    b
}

#[test]
fn d_form_loads_zero_or_sign_extend() {
    let b = exec_mem(
        with_data(&[0x89AB_CDEF, 0x8001_7F02]),
        &[(3, DATA)],
        &[
            lwz(4, 3, 0),
            d_form(34, 5, 3, 1), // lbz 0xAB
            d_form(40, 6, 3, 2), // lhz 0xCDEF
            d_form(42, 7, 3, 2), // lha sign-extended
            d_form(42, 8, 3, 6), // lha 0x7F02
            d_form(34, 9, 3, 4), // lbz 0x80
        ],
    );
    assert_eq!(b.r(4), 0x89AB_CDEF);
    assert_eq!(b.r(5), 0xAB);
    assert_eq!(b.r(6), 0xCDEF);
    assert_eq!(b.r(7), 0xFFFF_CDEF);
    assert_eq!(b.r(8), 0x7F02);
    assert_eq!(b.r(9), 0x80);
}

#[test]
fn stores_write_big_endian_the_low_bytes() {
    let b = exec_mem(
        |_| {},
        &[(3, DATA), (4, 0x1122_3344)],
        &[
            stw(4, 3, 0),
            d_form(38, 4, 3, 4), // stb 0x44
            d_form(44, 4, 3, 6), // sth 0x3344
        ],
    );
    assert_eq!(b.word(DATA), 0x1122_3344);
    assert_eq!(b.word(DATA + 4), 0x4400_3344);
}

#[test]
fn update_forms_write_the_address_back() {
    let b = exec_mem(
        with_data(&[1, 2, 3]),
        &[(3, DATA), (5, DATA + 8), (6, 4), (7, 0xAA)],
        &[
            d_form(33, 4, 3, 4),     // lwzu r4, 4(r3)
            x31(8, 5, 6, 55, false), // lwzux r8, r5, r6 → DATA+12 = 0
            d_form(37, 7, 3, 4),     // stwu r7, 4(r3) → DATA+8
        ],
    );
    assert_eq!(b.r(4), 2);
    assert_eq!(b.r(3), DATA + 8);
    assert_eq!(b.r(8), 0);
    assert_eq!(b.r(5), DATA + 12);
    assert_eq!(b.word(DATA + 8), 0xAA);
}

#[test]
fn invalid_update_forms_are_illegal() {
    for word in [
        d_form(33, 3, 3, 4),      // lwzu with rA = rD
        d_form(33, 3, 0, 4),      // lwzu with rA = 0
        d_form(37, 3, 0, 4),      // stwu with rA = 0
        x31(4, 4, 5, 119, false), // lbzux with rA = rD
    ] {
        let mut b = Board::new(&[word]);
        b.cpu.set_gpr(4, DATA);
        assert_eq!(
            b.run(100),
            Stop::Exception {
                kind: Exception::Illegal { word },
                at: ORG
            },
            "{word:#010x}"
        );
        assert_eq!(b.cpu.registers().srr0, ORG);
        assert_eq!(b.cpu.pc(), 0x700);
    }
    // A store with update where rA = rS is valid: the old value is stored.
    let b = exec_mem(|_| {}, &[(3, DATA)], &[d_form(37, 3, 3, 8)]);
    assert_eq!((b.word(DATA + 8), b.r(3)), (DATA, DATA + 8));
}

#[test]
fn indexed_forms_and_ra_zero() {
    let b = exec_mem(
        with_data(&[0xDEAD_BEEF, 0xFFFF_8001]),
        &[(0, 0x5555), (3, DATA), (4, 4), (5, 0x77)],
        &[
            x31(6, 3, 4, 23, false),  // lwzx
            x31(7, 0, 3, 23, false),  // lwzx with rA = 0: (rB) only
            x31(8, 3, 4, 343, false), // lhax 0xFFFF
            x31(9, 3, 4, 279, false), // lhzx
            x31(10, 3, 0, 87, false), // lbzx, rB = r0 (a register, not zero)
            x31(5, 3, 4, 215, false), // stbx
            x31(5, 3, 4, 407, false), // sthx
        ],
    );
    assert_eq!(b.r(6), 0xFFFF_8001);
    assert_eq!(b.r(7), 0xDEAD_BEEF);
    assert_eq!(b.r(8), 0xFFFF_FFFF);
    assert_eq!(b.r(9), 0xFFFF);
    assert_eq!(b.r(10), 0, "DATA + 0x5555 is zero RAM");
    assert_eq!(b.word(DATA + 4), 0x0077_8001);
}

#[test]
fn byte_reversed_loads_and_stores() {
    let b = exec_mem(
        with_data(&[0x1122_3344]),
        &[(3, DATA), (4, 0), (5, 0xAABB_CCDD), (6, 4)],
        &[
            x31(7, 3, 4, 534, false), // lwbrx
            x31(8, 3, 4, 790, false), // lhbrx
            x31(5, 3, 6, 662, false), // stwbrx at +4
            addi(6, 6, 4),
            x31(5, 3, 6, 918, false), // sthbrx at +8
        ],
    );
    assert_eq!(b.r(7), 0x4433_2211);
    assert_eq!(b.r(8), 0x2211);
    assert_eq!(b.word(DATA + 4), 0xDDCC_BBAA);
    assert_eq!(b.word(DATA + 8) >> 16, 0xDDCC);
}

#[test]
fn load_and_store_multiple() {
    let b = exec_mem(
        with_data(&[10, 20, 30]),
        &[(3, DATA)],
        &[d_form(46, 29, 3, 0), d_form(47, 29, 3, 16)],
    );
    assert_eq!((b.r(29), b.r(30), b.r(31)), (10, 20, 30));
    assert_eq!(
        (b.word(DATA + 16), b.word(DATA + 20), b.word(DATA + 24)),
        (10, 20, 30)
    );
}

#[test]
fn strings_move_bytes_across_registers_and_wrap_to_r0() {
    let lswi = |rt: u32, ra: u32, nb: u32| x31(rt, ra, nb, 597, false);
    let stswi = |rs: u32, ra: u32, nb: u32| x31(rs, ra, nb, 725, false);
    let b = exec_mem(
        |b| b.mem.load(DATA, b"Hello, world"),
        &[(3, DATA), (4, DATA + 0x20)],
        &[
            lswi(30, 3, 6),  // r30 = "Hell", r31 = "o," 00 00
            stswi(30, 4, 6), // "Hello,"
            lswi(31, 3, 7),  // r31 = "Hell", r0 = "o, " 00
            li(9, 5),
            mtspr(1, 9),               // XER byte count 5
            x31(10, 0, 3, 533, false), // lswx r10, 0, r3: "Hell" "o"
        ],
    );
    assert_eq!(b.r(30), u32::from_be_bytes(*b"Hell"));
    assert_eq!(b.r(31), u32::from_be_bytes(*b"Hell"));
    assert_eq!(b.r(0), u32::from_be_bytes([b'o', b',', b' ', 0]));
    assert_eq!(&b.mem.as_bytes()[DATA as usize + 0x20..][..7], b"Hello,\0");
    assert_eq!(b.r(10), u32::from_be_bytes(*b"Hell"));
    assert_eq!(b.r(11), u32::from_be_bytes([b'o', 0, 0, 0]));
}

#[test]
fn a_string_load_over_its_address_register_is_illegal() {
    let lswi = |rt: u32, ra: u32, nb: u32| x31(rt, ra, nb, 597, false);
    let lswx = |rt: u32, ra: u32, rb: u32| x31(rt, ra, rb, 533, false);
    for (word, xer) in [
        (lswi(3, 4, 8), 0),  // r3, r4: r4 is rA
        (lswi(31, 0, 8), 0), // r31, r0: even rA = 0 counts
        (lswx(3, 5, 4), 8),  // r3, r4: r4 is rB
        (lswx(3, 4, 6), 8),  // r4 is rA
    ] {
        let mut b = Board::new(&[word]);
        b.cpu.registers_mut().xer = xer;
        b.cpu.set_gpr(3, DATA);
        b.cpu.set_gpr(4, DATA);
        b.cpu.set_gpr(5, DATA);
        b.cpu.set_gpr(6, 0);
        assert_eq!(
            b.run(100),
            Stop::Exception {
                kind: Exception::Illegal { word },
                at: ORG
            },
            "{word:#010x}"
        );
    }
    // 32 bytes from r5 load r5..r12: rA = r3 is outside.
    let b = exec_mem(
        |b| b.mem.load(DATA + 28, b"last"),
        &[(3, DATA)],
        &[lswi(5, 3, 0)],
    );
    assert_eq!(b.r(12), u32::from_be_bytes(*b"last"));
    // lswx with rA = 0 in the range, or a count of 0, is fine.
    let b = exec_mem(
        |_| {},
        &[(4, DATA)],
        &[li(9, 8), mtspr(1, 9), lswx(31, 0, 4)],
    );
    assert_eq!((b.r(31), b.r(0)), (0, 0));
}

#[test]
fn lwarx_stwcx_store_only_with_the_reservation() {
    let b = exec_mem(
        with_data(&[5]),
        &[(3, DATA), (4, 0)],
        &[
            x31(5, 3, 4, 20, false), // lwarx r5
            addi(5, 5, 1),
            x31(5, 3, 4, 150, true), // stwcx. → stored, EQ
            x31(6, 0, 0, 19, false), // mfcr r6
            x31(5, 3, 4, 150, true), // again: no reservation
        ],
    );
    assert_eq!(b.word(DATA), 6);
    assert_eq!(b.r(6) >> 28, 0b0010);
    assert_eq!(b.cpu.registers().cr >> 28, 0);
}

#[test]
fn dcbz_zeroes_the_16_byte_line() {
    let b = exec_mem(
        with_data(&[1, 2, 3, 4, 5, 6, 7, 8]),
        &[(3, DATA + 16), (4, 5)],
        &[x31(0, 3, 4, 1014, false)],
    );
    let words: Vec<u32> = (0..8).map(|i| b.word(DATA + 4 * i)).collect();
    assert_eq!(words, [1, 2, 3, 4, 0, 0, 0, 0]);
}

#[test]
fn cache_and_sync_instructions_are_harmless() {
    let b = exec_mem(
        with_data(&[42]),
        &[(3, DATA)],
        &[
            x31(0, 0, 3, 86, false),  // dcbf
            x31(0, 0, 3, 54, false),  // dcbst
            x31(0, 0, 3, 278, false), // dcbt
            x31(0, 0, 3, 246, false), // dcbtst
            x31(0, 0, 3, 982, false), // icbi
            x31(0, 0, 3, 470, false), // dcbi
            x31(0, 0, 3, 454, false), // dccci
            x31(0, 0, 3, 966, false), // iccci
            x31(0, 0, 0, 598, false), // sync
            x31(0, 0, 0, 854, false), // eieio
            0x4C00_012C,              // isync
            lwz(4, 3, 0),
        ],
    );
    assert_eq!(b.r(4), 42);
}

#[test]
fn misaligned_word_and_half_accesses_take_the_alignment_exception() {
    for (word, addr) in [
        (lwz(4, 3, 2), DATA + 2),
        (d_form(40, 4, 3, 1), DATA + 1),
        (stw(4, 3, 1), DATA + 1),
        (d_form(46, 30, 3, 2), DATA + 2),
    ] {
        let mut b = Board::new(&[word]);
        b.cpu.set_gpr(3, DATA);
        assert_eq!(
            b.run(100),
            Stop::Exception {
                kind: Exception::Alignment { addr },
                at: ORG
            }
        );
        let r = b.cpu.registers();
        assert_eq!((r.dear, r.srr0, r.pc), (addr, ORG, 0x600));
    }
    // Bytes are never misaligned.
    let b = exec_mem(
        with_data(&[0x0102_0304]),
        &[(3, DATA)],
        &[d_form(34, 4, 3, 3)],
    );
    assert_eq!(b.r(4), 4);
}

#[test]
fn a_bus_error_is_a_machine_check_saved_in_srr2_srr3() {
    let mut b = Board::new(&[lwz(4, 3, 0)]);
    b.cpu.set_gpr(3, 0x4000_0000);
    b.cpu.registers_mut().msr = 0x0000_9000; // EE, ME
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::MachineCheck { addr: 0x4000_0000 },
            at: ORG
        }
    );
    let r = b.cpu.registers();
    assert_eq!((r.srr2, r.srr3, r.msr, r.pc), (ORG, 0x9000, 0, 0x200));
    assert_eq!(b.cpu.dcr(0x90), Some(0x4000_0000), "BEAR");
    assert_eq!(b.r(4), 0, "the load did not complete");
}

#[test]
fn a_fetch_bus_error_is_an_instruction_machine_check() {
    let mut b = Board::new(&[b(0x20_0000)]); // to ORG + 2 MiB, past the RAM
    b.cpu.registers_mut().evpr = 0x0001_0000;
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::MachineCheck {
                addr: ORG + 0x20_0000
            },
            at: ORG + 0x20_0000
        }
    );
    let r = b.cpu.registers();
    assert_eq!(
        (r.srr2, r.esr, r.pc),
        (ORG + 0x20_0000, 0x8000_0000, 0x0001_0200)
    );
}
