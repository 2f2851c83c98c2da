//! The example programs for the PowerPC node (examples/ppc/): the committed `.s37` files are
//! what the sources give (rebuilt here with the cross binutils), and each one is a program the
//! loader takes: inside the program RAM, with an entry point where the seed's link file puts
//! the code.

use std::path::{Path, PathBuf};
use std::process::Command;

use buslab_loader::MemoryMap;

const PROGRAMS: [&str; 5] = ["demo", "echo", "hello", "send", "slio_led"];

fn examples() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/ppc")
}

/// Whether the cross assembler runs; in CI (which installs it: scripts/setup-test-deps.sh) a
/// missing tool is a failure, elsewhere the test says it was skipped.
fn have_cross_binutils() -> bool {
    let found = std::env::var_os("PATH").is_some_and(|path| {
        std::env::split_paths(&path).any(|dir| dir.join("powerpc-linux-gnu-as").is_file())
    });
    if !found {
        assert!(
            std::env::var_os("CI").is_none(),
            "powerpc-linux-gnu-as is missing in CI"
        );
        eprintln!("SKIPPED: powerpc-linux-gnu-as is missing; run scripts/setup-test-deps.sh");
    }
    found
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_committed_programs_are_what_the_sources_build() {
    if !have_cross_binutils() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let status = Command::new("bash")
        .arg(examples().join("build.sh"))
        .arg(out.path())
        .status()
        .unwrap();
    assert!(status.success(), "examples/ppc/build.sh failed: {status}");
    for name in PROGRAMS {
        let file = format!("{name}.s37");
        assert!(
            read(&out.path().join(&file)) == read(&examples().join(&file)),
            "examples/ppc/{file} is not what its sources build: run examples/ppc/build.sh"
        );
    }
}

#[test]
fn every_example_is_a_program_the_loader_takes_with_its_entry_at_0x32000() {
    let map = MemoryMap::ppc403();
    for name in PROGRAMS {
        let text = read(&examples().join(format!("{name}.s37")));
        let program = buslab_loader::loader::check(&map, &text)
            .unwrap_or_else(|e| panic!("examples/ppc/{name}.s37 is refused: {e:?}"));
        assert_eq!(program.start, Some(0x32000), "{name}: the entry point");
        let (first, last) = program.ranges()[0];
        assert!(
            first >= 0x30000 && last < 0x40000,
            "{name}: loaded at {first:08X}..{last:08X}, outside the seed's program area"
        );
    }
}
