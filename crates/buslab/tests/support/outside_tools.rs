//! Outside tools the interop tests drive (python-can in the project's `.venv`, can-utils,
//! Wireshark's tools). `scripts/setup-test-deps.sh` (run by `scripts/test.sh`) installs them.
//! Under `CI=1` a missing tool fails the test; elsewhere the test says SKIPPED and returns, so
//! a developer without the tools can still run the rest.

use std::path::PathBuf;
use std::process::{Command, Stdio};

/// The repository's root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The venv's python with python-can, or `None` (allowed outside CI only).
pub fn python_can() -> Option<PathBuf> {
    let python = root().join(".venv/bin/python");
    let has_can = python.exists()
        && Command::new(&python)
            .args(["-c", "import can"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
    present(has_can, "python-can").then_some(python)
}

/// A program on PATH, or `false` (allowed outside CI only).
#[allow(dead_code)] // not every test file needs a program on PATH
pub fn tool(name: &str) -> bool {
    let found = Command::new("sh")
        .args(["-c", &format!("command -v {name}")])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    present(found, name)
}

/// Whether `what` was found; a missing tool fails the test under `CI=1`.
pub fn present(found: bool, what: &str) -> bool {
    if !found {
        assert!(
            std::env::var_os("CI").is_none(),
            "{what} is missing in CI (scripts/setup-test-deps.sh installs it)"
        );
        eprintln!("SKIPPED: {what} is missing; run scripts/setup-test-deps.sh");
    }
    found
}
