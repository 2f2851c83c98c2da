//! `buslab load` onto the PowerPC node of `buslab bus serve --ppc`: a bad line is named and
//! nothing is sent; a good program is loaded, reported on the node's VT100 terminal (read by an
//! independent emulator, the `vt100` crate), saved in the memory file, read back, and run.

#[path = "support/vt100_terminal.rs"]
mod vt100_terminal;

mod bus_common;

use bus_common::Serve;
use vt100_terminal::Terminal;

/// One S-record with `kind`, an address of `address_len` bytes and `data`.
fn record(kind: u8, address: u32, data: &[u8], address_len: usize) -> String {
    let mut body = vec![(address_len + data.len() + 1) as u8];
    body.extend_from_slice(&address.to_be_bytes()[4 - address_len..]);
    body.extend_from_slice(data);
    let sum = !body.iter().fold(0u8, |a, b| a.wrapping_add(*b));
    let hex: String = body.iter().map(|b| format!("{b:02X}")).collect();
    format!("S{kind}{hex}{sum:02X}")
}

/// A program of 64 records of 32 bytes at 0x32000 with its entry point; its lines. Its first
/// word is `b .` (0x48000000): run, it loops there.
fn program() -> Vec<String> {
    let mut lines = vec![record(0, 0, b"test", 2)];
    for i in 0..64u32 {
        let mut data: Vec<u8> = (0..32u32).map(|j| (i * 7 + j * 13) as u8).collect();
        if i == 0 {
            data[..4].copy_from_slice(&[0x48, 0, 0, 0]);
        }
        lines.push(record(3, 0x32000 + i * 32, &data, 4));
    }
    lines.push(record(7, 0x32000, &[], 4));
    lines
}

#[test]
fn a_program_is_checked_loaded_reported_saved_and_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("monican");
    let memory = dir.path().join("ppc.s37");
    let control = dir.path().join("ppc.sock");
    let serve = Serve::start_with(
        125_000,
        &[
            "--ppc",
            link.to_str().unwrap(),
            "--ppc-memory",
            memory.to_str().unwrap(),
            "--ppc-control",
            control.to_str().unwrap(),
        ],
    );
    let mut terminal = Terminal::open(&link);

    // A corrupted record: refused with its line number before anything is sent.
    let mut bad = program();
    let line = &mut bad[9];
    line.replace_range(line.len() - 2.., "00");
    let bad_file = dir.path().join("bad.s37");
    std::fs::write(&bad_file, bad.join("\n") + "\n").unwrap();
    let out = serve
        .buslab()
        .args(["load", bad_file.to_str().unwrap(), "--bus", &serve.url])
        .args(["--verify", control.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("line 10: checksum"), "{stderr}");

    // A good one: loaded, reported, saved, and every byte read back.
    let good_file = dir.path().join("prog.s37");
    std::fs::write(&good_file, program().join("\n") + "\n").unwrap();
    let out = serve
        .buslab()
        .args(["load", good_file.to_str().unwrap(), "--bus", &serve.url])
        .args(["--verify", control.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("verified"), "{stderr}");
    assert!(stderr.contains("00032000-000327FF"), "{stderr}");
    // The loader jumped: the program loops at its entry point.
    assert!(
        stderr.contains("the node runs the program: running pc=00032000"),
        "{stderr}"
    );
    terminal.wait_for_text("Program loaded: 2048 bytes");
    terminal.wait_for_text("00032000");
    terminal.wait_for_text("Entry point: 00032000");

    // The node's memory file holds the program (it was saved before the node reported).
    let saved = buslab_loader::srec::parse(&std::fs::read(&memory).unwrap()).unwrap();
    let sent = buslab_loader::srec::parse((program().join("\n") + "\n").as_bytes()).unwrap();
    assert_eq!(saved.ranges(), sent.ranges());
    let image = buslab_loader::MemoryImage::from_program(&saved);
    let expected = buslab_loader::MemoryImage::from_program(&sent);
    assert_eq!(image.read(0x32000, 2048), expected.read(0x32000, 2048));
}

#[test]
fn without_a_loader_the_handshake_says_so() {
    let serve = Serve::start(125_000);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("prog.s37");
    std::fs::write(&file, program().join("\n") + "\n").unwrap();
    let out = serve
        .buslab()
        .args(["load", file.to_str().unwrap(), "--bus", &serve.url])
        .args(["--timeout", "1s"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("no loader answered on ID 000"), "{stderr}");
}
