//! The benchmark programs: the committed Intel HEX files are what as31 makes of the committed
//! sources, and the programs do what their comments say (the benchmark's numbers rest on it).

use std::path::PathBuf;
use std::process::{Command, Stdio};

use buslab_mcs51::{Clocks, Event, FlatMemory, Mcs51, Stop};

fn benches() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches")
}

fn image(hex: &str) -> FlatMemory {
    let mut mem = FlatMemory::new();
    for record in ihex::Reader::new(hex) {
        match record.unwrap() {
            ihex::Record::Data { offset, value } => mem.load(offset, &value),
            ihex::Record::EndOfFile => break,
            _ => {}
        }
    }
    mem
}

/// as31 on PATH, or false (allowed outside CI only: under CI=1 a missing tool fails).
fn have_as31() -> bool {
    let found = Command::new("as31")
        .arg("-v")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok();
    if !found {
        assert!(
            std::env::var_os("CI").is_none(),
            "as31 is missing in CI (scripts/setup-test-deps.sh installs it)"
        );
        eprintln!("SKIPPED: as31 is missing; run scripts/setup-test-deps.sh");
    }
    found
}

#[test]
fn the_committed_hex_files_are_as31s_output_of_the_sources() {
    if !have_as31() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("mcs51-as31-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["checksum", "busy"] {
        let out = dir.join(format!("{name}.hex"));
        let status = Command::new("as31")
            .arg("-Fhex")
            .arg(format!("-O{}", out.display()))
            .arg(benches().join(format!("{name}.a51")))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .unwrap();
        assert!(status.success(), "as31 failed on {name}.a51");
        let fresh = std::fs::read_to_string(&out).unwrap();
        let committed = std::fs::read_to_string(benches().join(format!("{name}.hex"))).unwrap();
        assert_eq!(
            fresh, committed,
            "{name}.hex is stale: reassemble {name}.a51"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_checksum_runs_4705006_instructions_and_the_busy_one_keeps_sending() {
    let hex = std::fs::read_to_string(benches().join("checksum.hex")).unwrap();
    let mut mem = image(&hex);
    let mut cpu = Mcs51::new();
    cpu.set_traps(0x0017..=0x0017);
    assert_eq!(cpu.run(&mut mem, Clocks::NEVER), Stop::Trap { pc: 0x0017 });
    // 1 + 255 passes × (3 + 8 pages × (2 + 256 bytes × 9)) instructions.
    assert_eq!(cpu.instructions(), 1 + 255 * (3 + 8 * (2 + 256 * 9)));
    assert_eq!(cpu.now().cycles(), 6_274_276);

    let hex = std::fs::read_to_string(benches().join("busy.hex")).unwrap();
    let mut mem = image(&hex);
    let mut cpu = Mcs51::new();
    cpu.set_traps(0x005F..=0x005F);
    let mut frames = 0;
    loop {
        match cpu.run(&mut mem, Clocks::NEVER) {
            Stop::Trap { pc } => {
                assert_eq!(pc, 0x005F);
                break;
            }
            Stop::Events => {
                while let Some(e) = cpu.poll_event() {
                    if let Event::Serial(f) = e {
                        assert_eq!(f.bit_clocks(), Clocks(1152));
                        frames += 1;
                    }
                }
            }
            other => panic!("{other:?}"),
        }
    }
    // Back-to-back 10-bit frames at 9600 baud over the whole run.
    let expected = cpu.now().0 / (10 * 1152);
    assert!(
        frames + 1 >= expected && frames <= expected,
        "{frames} frames, {expected} fit"
    );
}
