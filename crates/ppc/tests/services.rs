//! The firmware's `write` service and its errors, as Linux gives them (r3 = errno, CR0[SO]
//! set), on the board directly: a program built with the cross binutils.

#[path = "support/asm.rs"]
mod asm;

use buslab_ppc::board::Board;
use buslab_ppc::program::{Cycles, EBADF, EFAULT, Ending, MAX_WRITE, Running};

/// Runs `source` until it ends; its ending and its last registers.
fn run(source: &str) -> (Ending, buslab_ppc403::Registers, Vec<u8>) {
    let text = asm::assemble(source, (0x83, 0x67));
    let program = buslab_loader::srec::parse(&text).unwrap();
    let mut board = Board::new();
    for s in &program.segments {
        board.load(s.address, &s.data);
    }
    let mut run = Running::start(board, program.start.unwrap());
    let mut chip = buslab_sja1000::Sja1000::new();
    // 100 ms of CPU time at most: these programs take microseconds.
    for slice in 1..=500u64 {
        if let Some(ending) = run.run(&mut chip, Cycles(slice * 5000)) {
            let out = run.board_mut().spu.flush();
            return (ending, *run.registers(), out);
        }
    }
    panic!("the program did not end: pc {:08X}", run.pc());
}

const SO: u32 = 0x1000_0000;

/// write(fd, buf, len) then exit(0), keeping r3 and CR in r30, r31.
fn write_call(fd: i32, buf: &str, len: u32) -> String {
    format!(
        "_start:\n\tli r0,4\n\tli r3,{fd}\n\tld32b r4,{buf}\n\tld32b r5,{len}\n\tsc\n\
         \tmr r30,r3\n\tmfcr r31\n\tli r0,1\n\tli r3,0\n\tsc\n"
    )
}

#[test]
fn write_to_a_file_that_is_not_the_terminal_is_ebadf() {
    let (ending, r, out) = run(&write_call(3, "_start", 4));
    assert_eq!(
        ending,
        Ending::Exited {
            status: 0,
            returned: None
        }
    );
    assert_eq!((r.gpr[30], r.gpr[31] & SO), (EBADF, SO));
    assert!(out.is_empty());
}

#[test]
fn write_from_outside_the_ram_is_efault() {
    let (_, r, _) = run(&write_call(1, "0x003FFFFE", 4));
    assert_eq!((r.gpr[30], r.gpr[31] & SO), (EFAULT, SO));
    let (_, r, _) = run(&write_call(2, "0x80000000", 1));
    assert_eq!(r.gpr[30], EFAULT);
}

#[test]
fn a_long_write_takes_what_one_call_carries() {
    let (_, r, out) = run(&write_call(1, "0x00100000", 5000));
    assert_eq!((r.gpr[30], r.gpr[31] & SO), (MAX_WRITE, 0));
    assert_eq!(out.len(), MAX_WRITE as usize);
    let (_, r, out) = run(&write_call(2, "_start", 8));
    assert_eq!(r.gpr[30], 8);
    assert_eq!(
        out[..4],
        [0x38, 0x00, 0x00, 0x04],
        "the bytes at _start: li r0,4"
    );
}
