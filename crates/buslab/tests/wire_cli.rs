//! `buslab wire encode|decode` end to end.

use assert_cmd::Command;

/// SFF 0x123, DLC 2, 11 22 on a bus with a receiver, SOF..EOF (facts sheet §1.5).
const WIRE_123: &str = "00010010001100000110000100010010001000001100101101111011111111";

fn buslab() -> Command {
    Command::cargo_bin("buslab").unwrap()
}

fn stdout(args: &[&str]) -> String {
    let out = buslab().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn failure(args: &[&str]) -> String {
    let out = buslab().args(args).output().unwrap();
    assert!(!out.status.success(), "{args:?} should fail");
    String::from_utf8(out.stderr).unwrap()
}

#[test]
fn encode_prints_the_facts_sheet_string() {
    assert_eq!(
        stdout(&["wire", "encode", "123#1122"]),
        format!("{WIRE_123}\n")
    );
    let unstuffed = stdout(&["wire", "encode", "123#1122", "--unstuffed"]);
    assert_eq!(unstuffed.trim().len(), 60);
    assert!(unstuffed.starts_with("00010010001100000100001000100100010000010010110111"));
}

#[test]
fn no_ack_shows_the_transmitters_view() {
    let sent = stdout(&["wire", "encode", "123#1122", "--no-ack"]);
    let mut expected = WIRE_123.as_bytes().to_vec();
    expected[53] = b'1';
    assert_eq!(sent.trim().as_bytes(), expected.as_slice());
    let out = stdout(&["wire", "decode", sent.trim()]);
    assert!(out.contains("not acknowledged"), "{out}");
}

#[test]
fn fields_show_crc_and_stuff_bits() {
    let out = stdout(&["wire", "encode", "123#1122", "--fields"]);
    assert!(out.starts_with(WIRE_123));
    assert!(out.contains("CRC 0x04B7"), "{out}");
    let crc_line = out
        .lines()
        .find(|l| l.trim_start().starts_with("CRC "))
        .unwrap();
    assert!(
        crc_line.contains("0000[1]10010110111") && crc_line.contains("0x04B7"),
        "{crc_line}"
    );
    let dlc_line = out
        .lines()
        .find(|l| l.trim_start().starts_with("DLC"))
        .unwrap();
    assert!(dlc_line.contains("00[1]10"), "{dlc_line}");
    assert!(out.contains("ACK slot"));
}

#[test]
fn decode_round_trips_with_separators() {
    let out = stdout(&["wire", "decode", WIRE_123]);
    assert!(out.starts_with("123#1122  CRC 0x04B7"), "{out}");
    let spaced = format!(
        "{} {}_{}",
        &WIRE_123[..10],
        &WIRE_123[10..20],
        &WIRE_123[20..]
    );
    assert!(stdout(&["wire", "decode", &spaced]).starts_with("123#1122"));
    let eff = stdout(&["wire", "encode", "1ABCDEF0#R3"]);
    assert!(stdout(&["wire", "decode", eff.trim()]).starts_with("1ABCDEF0#R3"));
}

#[test]
fn every_flipped_bit_is_reported_with_its_position() {
    for i in 0..WIRE_123.len() {
        if i == 53 {
            continue; // ACK slot: either level decodes
        }
        let mut bits = WIRE_123.as_bytes().to_vec();
        bits[i] ^= 1; // '0' <-> '1'
        let err = failure(&["wire", "decode", std::str::from_utf8(&bits).unwrap()]);
        assert!(
            err.contains("error at wire bit") || err.contains("signalled at wire bit"),
            "{i}: {err}"
        );
    }
    // Stuff bit 17 flipped: six zeros.
    let mut bits = WIRE_123.as_bytes().to_vec();
    bits[17] = b'0';
    let err = failure(&["wire", "decode", std::str::from_utf8(&bits).unwrap()]);
    assert!(err.contains("stuff error at wire bit 17"), "{err}");
}

#[test]
fn garbage_is_rejected_clearly() {
    let err = failure(&["wire", "decode", "0001x001"]);
    assert!(err.contains("invalid character 'x' at position 4"), "{err}");
    let err = failure(&["wire", "decode", "000100"]);
    assert!(err.contains("ends after 6 bits"), "{err}");
    let err = failure(&["wire", "decode", "_ _"]);
    assert!(err.contains("no bits"), "{err}");
    let err = failure(&["wire", "encode", "123#R9"]);
    assert!(err.contains("DLC 9 is out of range 0..8"), "{err}");
    let err = failure(&[
        "wire",
        "encode",
        "123#11",
        "--vcd",
        "/dev/null",
        "--bitrate",
        "0",
    ]);
    assert!(err.contains("bit rate 0 is out of range"), "{err}");
}

#[test]
fn vcd_waveform_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.vcd");
    let out = stdout(&[
        "wire",
        "encode",
        "123#1122",
        "--vcd",
        path.to_str().unwrap(),
        "--bitrate",
        "125000",
    ]);
    assert_eq!(out.trim(), WIRE_123);
    let vcd = std::fs::read_to_string(&path).unwrap();
    assert!(vcd.contains("$timescale 1 ns $end") && vcd.contains("$enddefinitions $end"));
    // Replay the value changes: 10 idle bits, the frame, 10 idle bits at 8000 ns per bit.
    let mut level = '1';
    let mut changes = Vec::new();
    let mut time = 0u64;
    for line in vcd
        .lines()
        .skip_while(|l| !l.starts_with("$enddefinitions"))
    {
        if let Some(t) = line.strip_prefix('#') {
            time = t.parse().unwrap();
        } else if line.ends_with('!') && line.len() == 2 {
            changes.push((time, line.chars().next().unwrap()));
        }
    }
    let mut sampled = String::new();
    for bit in 0..82u64 {
        let t = bit * 8000 + 4000;
        for &(at, v) in &changes {
            if at <= t {
                level = v;
            }
        }
        sampled.push(level);
    }
    assert_eq!(
        sampled,
        format!("{}{WIRE_123}{}", "1".repeat(10), "1".repeat(10))
    );
    assert_eq!(time, 82 * 8000);
}
