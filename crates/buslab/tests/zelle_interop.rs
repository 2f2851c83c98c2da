//! An independent serial program (pyserial) drives the served cell.

#[path = "support/zelle_served.rs"]
mod served;

use std::path::PathBuf;
use std::process::Command;

use served::Served;

#[test]
fn pyserial_drives_a_served_cell() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let python = root.join(".venv/bin/python");
    if !python.exists() {
        // CI installs it (scripts/setup-test-deps.sh): there, a missing tool is a failure.
        assert!(
            std::env::var_os("CI").is_none(),
            "{} is missing in CI",
            python.display()
        );
        eprintln!(
            "SKIPPED: {} is missing; run scripts/setup-test-deps.sh to install pyserial",
            python.display()
        );
        return;
    }
    let s = Served::start(&["--analog", "1=2.5V"]);
    let out = Command::new(&python)
        .arg(root.join("tests/interop/zelle_pyserial.py"))
        .arg(&s.pty)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "pyserial script failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "ok");
}
