//! `buslab dbc show|skeleton`: a database's bits drawn as a person checks them, and a first
//! database learnt from a captured log that reads back, with the periods the log shows.

use std::path::Path;
use std::process::Command;

fn run(args: &[&str], dir: &Path) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(args)
        .current_dir(dir)
        .env_remove("BUSLAB_BUS")
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// cantools' README example: a Motorola message with a value table.
const EXAMPLE: &str = r#"VERSION ""

BU_: PCM1 FOO

BO_ 496 ExampleMessage: 8 PCM1
 SG_ Enable : 7|1@0- (1,0) [0|0] "-" Vector__XXX
 SG_ AverageRadius : 6|6@0+ (0.1,0) [0|5] "m" Vector__XXX
 SG_ Temperature : 0|12@0- (0.01,250) [229.53|270.47] "degK" Vector__XXX

CM_ BO_ 496 "Example message used as template in MuZZy";
VAL_ 496 Enable 0 "Disabled" -1 "Enabled" ;
"#;

#[test]
fn show_draws_each_signals_bits_on_the_bytes_and_names_its_msb_and_lsb() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("example.dbc"), EXAMPLE).unwrap();
    let (ok, out, err) = run(
        &["dbc", "show", "example.dbc", "ExampleMessage"],
        dir.path(),
    );
    assert!(ok, "{err}");
    assert!(
        out.contains("1F0 ExampleMessage  8 bytes  from PCM1"),
        "{out}"
    );
    // Motorola: Temperature starts at bit 0 of byte 0 (its MSB) and runs into byte 1.
    assert!(
        out.contains(
            "C Temperature  start 0 size 12 @0 Motorola signed, MSB byte 0 bit 0, LSB byte 2 bit 5"
        ),
        "{out}"
    );
    assert!(
        out.contains("values: 0 \"Disabled\", -1 \"Enabled\""),
        "{out}"
    );
    assert!(
        out.contains("     0  A B B B B B B C\n     1  C C C C C C C C\n     2  C C C . . . . .\n     3  . . . . . . . .\n"),
        "{out}"
    );
    let (ok, _, err) = run(&["dbc", "show", "example.dbc", "Nope"], dir.path());
    assert!(!ok);
    assert!(
        err.contains("no message \"Nope\" (its messages: ExampleMessage)"),
        "{err}"
    );
}

#[test]
fn garbage_databases_are_refused_with_the_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bad.dbc"),
        "VERSION \"\"\n\nBO_ 12 M: 8 X\n SG_ S : 0|8@1+ (1,0) [0|255] \"\" X\nBO_ x y\n",
    )
    .unwrap();
    let (ok, _, err) = run(&["dbc", "show", "bad.dbc"], dir.path());
    assert!(!ok);
    assert!(err.contains("bad.dbc") && err.contains("line 5"), "{err}");
    let (ok, _, err) = run(&["dbc", "show", "."], dir.path());
    assert!(!ok);
    assert!(err.contains("not a regular file"), "{err}");
}

#[test]
fn a_skeleton_learns_ids_lengths_and_periods_from_a_log_and_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let mut log = String::new();
    for i in 0..50u32 {
        // 123 every 100 ms with jitter (intervals of 102, 102 and 96 ms: the median is 102),
        // 1ABCDEF0 at irregular moments, 7FF once.
        let t = i * 100_000 + (i % 3) * 2_000;
        log += &format!(
            "({}.{:06}) can0 123#11223344\n",
            1_700_000_000 + t / 1_000_000,
            t % 1_000_000
        );
        if [0, 1, 5, 6, 20, 21, 40].contains(&i) {
            let u = t + 5_000;
            log += &format!(
                "({}.{:06}) can0 1ABCDEF0#0102\n",
                1_700_000_000 + u / 1_000_000,
                u % 1_000_000
            );
        }
    }
    log += "(1700000009.000000) can0 7FF#R\n";
    log += "(1700000009.100000) can0 333##1112233445566778899AABBCC\n";
    std::fs::write(dir.path().join("bus.log"), log).unwrap();
    let (ok, _, err) = run(&["dbc", "skeleton", "bus.log", "-o", "bus.dbc"], dir.path());
    assert!(ok, "{err}");
    let (ok, out, err) = run(&["dbc", "show", "bus.dbc"], dir.path());
    assert!(ok, "{err}");
    assert!(out.contains("4 messages"), "{out}");
    assert!(out.contains("333 MSG_333  12 bytes  CAN FD\n"), "{out}");
    assert!(out.contains("123 MSG_123  4 bytes  every 102 ms"), "{out}");
    // Event-driven: no period claimed.
    assert!(out.contains("1ABCDEF0 MSG_X1ABCDEF0  2 bytes\n"), "{out}");
    assert!(out.contains("7FF MSG_7FF  0 bytes\n"), "{out}");
    assert!(
        out.contains("A B0  start 0 size 8 @1 Intel unsigned"),
        "{out}"
    );
    let (ok, _, err) = run(&["dbc", "skeleton", "empty.log"], dir.path());
    assert!(!ok && err.contains("empty.log"), "{err}");
    std::fs::write(dir.path().join("none.log"), "").unwrap();
    let (ok, _, err) = run(&["dbc", "skeleton", "none.log"], dir.path());
    assert!(!ok && err.contains("no frames"), "{err}");
}
