//! Test programs for the PowerPC node, assembled at test time with Debian's cross toolchain
//! (`binutils-powerpc-linux-gnu`, installed by scripts/setup-test-deps.sh) into S-records as
//! the seed built its programs: linked at 0x32000 (the seed's link file), the entry point in
//! an S7 record.
//!
//! [`SEED`] holds the seed's macros (`rwsja.h`: `wrsjai`, `wrsja`, `rdsja` through r18/r19),
//! [`ROUTINES`] its routines (§4.1–4.2: `sja_init_pelican`, `receive_trame`, `send_trame`,
//! `send_trame_sans_verif`, `calibration_slio`, `send_calibration`) as the seed writes them,
//! with these changes: `andi` is `andi.` (the assembler knows no `andi` without the dot);
//! `send_trame_sans_verif` writes DATA 8 from r5's low byte (the seed shifts r5 once before
//! it, so its bytes 5–8 came out one place off); `send_trame`, whose code the seed does not
//! print, waits for TBS as §4.1.2.3 says, then is `send_trame_sans_verif`; and the bit timing
//! is the test bus's (BTR0_VALUE/BTR1_VALUE, given by the test) instead of the seed's
//! 50 kbit/s.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// Where programs are linked (the seed's link file: `output 0x32000`).
pub const TEXT: u32 = 0x32000;

/// The cross tools a test needs.
const TOOLS: [&str; 3] = [
    "powerpc-linux-gnu-as",
    "powerpc-linux-gnu-ld",
    "powerpc-linux-gnu-objcopy",
];

fn run(tool: &str, args: &[&str], dir: &std::path::Path) {
    let out = Command::new(tool)
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap_or_else(|e| {
            panic!("{tool}: {e}: the PowerPC cross toolchain is missing; run scripts/setup-test-deps.sh (it installs binutils-powerpc-linux-gnu)")
        });
    assert!(
        out.status.success(),
        "{tool} {args:?}:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The seed's frame format in r3, r4, r5 (§4.1.1) for `frame` (standard, 8 bytes at most):
/// `ld32b` lines.
pub fn frame_registers(frame: &buslab_can::Frame) -> String {
    let raw = frame.id().as_raw();
    let ffi = u32::from(frame.dlc()) | if frame.is_remote() { 0x40 } else { 0 };
    let r3 = ffi << 16 | (raw >> 3) << 8 | (raw & 7) << 5;
    let mut data = [0u8; 8];
    data[..frame.payload().len()].copy_from_slice(frame.payload());
    let r4 = u32::from_be_bytes(data[..4].try_into().unwrap());
    let r5 = u32::from_be_bytes(data[4..].try_into().unwrap());
    format!("\tld32b r3,0x{r3:08X}\n\tld32b r4,0x{r4:08X}\n\tld32b r5,0x{r5:08X}\n")
}

/// Assembles `source` (with [`SEED`] and `.equ`s for `btr` before it, [`ROUTINES`] after), links it at
/// [`TEXT`] with `_start` as the entry point, and returns the S-record file (S3 records, S7).
pub fn assemble(source: &str, btr: (u8, u8)) -> Vec<u8> {
    assemble_at(source, btr, TEXT)
}

/// [`assemble`], linked at `text` (0x30000: the seed's interrupt handlers' area, so the
/// program's own vectors can be at EVPR 0x00030000 + the vector's offset).
pub fn assemble_at(source: &str, btr: (u8, u8), text: u32) -> Vec<u8> {
    for tool in TOOLS {
        let found = std::env::var_os("PATH")
            .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()));
        assert!(
            found,
            "{tool} is missing: run scripts/setup-test-deps.sh (it installs binutils-powerpc-linux-gnu)"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let path: PathBuf = dir.path().join("prog.s");
    let file = format!(
        "\t.equ BTR0_VALUE,0x{:02X}\n\t.equ BTR1_VALUE,0x{:02X}\n{SEED}\n\t.text\n\t.globl _start\n{source}\n{ROUTINES}\n",
        btr.0, btr.1
    );
    std::fs::write(&path, file).unwrap();
    let d = dir.path();
    // -m403: the 403's own instructions too (mtdcr, mfdcr, wrteei).
    run(
        "powerpc-linux-gnu-as",
        &["-m403", "-mregnames", "-o", "prog.o", "prog.s"],
        d,
    );
    run(
        "powerpc-linux-gnu-ld",
        &[
            &format!("-Ttext=0x{text:X}"),
            "-e",
            "_start",
            "-o",
            "prog.elf",
            "prog.o",
        ],
        d,
    );
    run(
        "powerpc-linux-gnu-objcopy",
        &["-O", "srec", "--srec-forceS3", "prog.elf", "prog.s37"],
        d,
    );
    std::fs::read(d.join("prog.s37")).unwrap()
}

/// The seed's macros (seed 002 §3.1.2.1, `ld32b`, `push`/`pop`) and its PeliCAN register
/// names (`pelican.h`); its routines (§4.1, §4.2) are [`ROUTINES`].
pub const SEED: &str = r#"
	.equ MODE,0
	.equ COMMAND,1
	.equ STATUS,2
	.equ INTERRUPT,3
	.equ INTERRUPT_ENABLE,4
	.equ BUS_TIMING_0,6
	.equ BUS_TIMING_1,7
	.equ OUTPUT_CONTROL,8
	.equ ACCEPTANCE_CODE_0,16
	.equ ACCEPTANCE_MASK_0,20
	.equ ACCEPTANCE_MASK_1,21
	.equ ACCEPTANCE_MASK_2,22
	.equ ACCEPTANCE_MASK_3,23
	.equ RX_FRAME_INFO,16
	.equ RX_ID_1_S,17
	.equ RX_ID_2_S,18
	.equ RX_DATA_S,19
	.equ TX_FRAME_INFO,16
	.equ TX_ID_1_S,17
	.equ TX_ID_2_S,18
	.equ TX_DATA_S,19
	.equ CLOCK_DIVIDER,31

	.macro wrsjai d, r
	li    r2,\r
	stb   r2,0(r18)
	li    r2,\d
	stb   r2,0(r19)
	.endm

	.macro wrsja p1, p2
	li    r2,\p2
	stb   r2,0(r18)
	stb   \p1,0(r19)
	.endm

	.macro rdsja p1, p2
	li    r2,\p1
	stb   r2,0(r18)
	lbz   \p2,0(r19)
	.endm

	.macro push r
	stwu  \r,-4(r1)
	.endm

	.macro pop r
	lwz   \r,0(r1)
	addi  r1,r1,4
	.endm

	.macro pushlr
	mflr  r0
	push  r0
	.endm

	.macro poplr
	pop   r0
	mtlr  r0
	.endm

	.macro ld32b r, v
	lis   \r,(\v)@h
	ori   \r,\r,(\v)@l
	.endm

"#;

/// The seed's routines, after the test's own code (so `_start` is at [`TEXT`]).
pub const ROUTINES: &str = r#"
sja_init_pelican:
	push r3
attente_mode_reset:
	wrsjai 0x01,MODE
	rdsja  MODE,r3
	andi.  r3,r3,0x01
	beq    attente_mode_reset
attente_pelican:
	wrsjai 0x80,CLOCK_DIVIDER
	rdsja  CLOCK_DIVIDER,r2
	andi.  r2,r2,0x80
	beq    attente_pelican
	wrsjai 0xFF,ACCEPTANCE_MASK_0
	wrsjai 0xFF,ACCEPTANCE_MASK_1
	wrsjai 0xFF,ACCEPTANCE_MASK_2
	wrsjai 0xFF,ACCEPTANCE_MASK_3
	wrsjai BTR0_VALUE,BUS_TIMING_0
	wrsjai BTR1_VALUE,BUS_TIMING_1
	wrsjai 0x00,INTERRUPT_ENABLE
	wrsjai 0xDB,OUTPUT_CONTROL
attente_fin_mode_reset:
	wrsjai 0x08,MODE
	rdsja  MODE,r3
	andi.  r3,r3,0x01
	bne    attente_fin_mode_reset
	pop r3
	blr

receive_trame:
	pushlr
	li      r3,0x0
	rdsja   STATUS,r6
	andi.   r6,r6,0x01
	beq     fin_receive_trame
	rdsja   RX_FRAME_INFO,r3
	slwi    r3,r3,0x8
	rdsja   RX_ID_1_S,r6
	or      r3,r3,r6
	slwi    r3,r3,0x8
	rdsja   RX_ID_2_S,r6
	or      r3,r3,r6
	rdsja   RX_DATA_S,r4
	slwi    r4,r4,8
	rdsja   RX_DATA_S+1,r6
	or      r4,r4,r6
	slwi    r4,r4,8
	rdsja   RX_DATA_S+2,r6
	or      r4,r4,r6
	slwi    r4,r4,8
	rdsja   RX_DATA_S+3,r6
	or      r4,r4,r6
	rdsja   RX_DATA_S+4,r5
	slwi    r5,r5,8
	rdsja   RX_DATA_S+5,r6
	or      r5,r5,r6
	slwi    r5,r5,8
	rdsja   RX_DATA_S+6,r6
	or      r5,r5,r6
	slwi    r5,r5,8
	rdsja   RX_DATA_S+7,r6
	or      r5,r5,r6
	wrsjai  0x04,COMMAND
	li      r6,0xFF
	rdsja   STATUS,r2
	andi.   r2,r2,0x02
	beq     fin_receive_trame
	wrsjai  0x08,COMMAND
fin_receive_trame:
	poplr
	blr

send_trame:
	pushlr
	push r3
attente_tx_buffer:
	rdsja STATUS,r3
	andi. r3,r3,0x04
	beq   attente_tx_buffer
	pop r3
	bl    send_trame_sans_verif
	poplr
	blr

send_trame_sans_verif:
	pushlr
	push r3
	wrsja    r3, TX_ID_2_S
	srwi     r3, r3, 8
	wrsja    r3, TX_ID_1_S
	srwi     r3, r3, 8
	wrsja    r3, TX_FRAME_INFO
	mr       r3, r4
	wrsja    r3, TX_DATA_S+3
	srwi     r3, r3, 8
	wrsja    r3, TX_DATA_S+2
	srwi     r3, r3, 8
	wrsja    r3, TX_DATA_S+1
	srwi     r3, r3, 8
	wrsja    r3, TX_DATA_S
	mr       r3, r5
	wrsja    r3, TX_DATA_S+7
	srwi     r3, r3, 8
	wrsja    r3, TX_DATA_S+6
	srwi     r3, r3, 8
	wrsja    r3, TX_DATA_S+5
	srwi     r3, r3, 8
	wrsja    r3, TX_DATA_S+4
	wrsjai   0x01, COMMAND
	pop r3
	poplr
	blr

calibration_slio:
	pushlr
	push r3
	push r4
	li    r4,0x30
attente_buffer:
	rdsja STATUS,r3
	andi. r3,r3,0x04
	beq   attente_buffer
	wrsjai 0x40,TX_ID_2_S
	wrsjai 0x15,TX_ID_1_S
	wrsjai 0x02,TX_FRAME_INFO
	wrsjai 0xAA,TX_DATA_S
	wrsjai 0x04,TX_DATA_S+1
attente_fin_transmission_prec:
	rdsja STATUS,r3
	andi. r3,r3,0x20
	bne   attente_fin_transmission_prec
	wrsjai 0x01,COMMAND
attente_debut_transmission:
	rdsja STATUS,r3
	andi. r3,r3,0x20
	beq   attente_debut_transmission
	wrsjai 0x02,COMMAND
	subic.   r4,r4,1
	bne     attente_fin_transmission_prec
	pop r4
	pop r3
	poplr
	blr

send_calibration:
	pushlr
	ld32b   r3,0x00021540
	ld32b   r4,0xAA040000
	bl      send_trame_sans_verif
	poplr
	blr
"#;
