//! Real Linux SocketCAN, in a virtual machine (this machine's kernel has no `AF_CAN`): QEMU
//! with software emulation boots Debian's kernel with a busybox initramfs holding the CAN
//! modules, this buslab binary and can-utils (`scripts/vm/build-initramfs.sh`); the checks in
//! `scripts/vm/socketcan-test.sh` run inside and report over the serial console:
//! cansend → `buslab dump socketcan:vcan0` (frames, and an error frame in candump's words),
//! `buslab send socketcan:vcan0` → candump,
//! `buslab bridge` between `buslab bus serve` and vcan0, and `buslab slcan serve` attached
//! with slcand as slcan0 and read by candump.
//!
//! Without QEMU, the kernel package or the tools this test fails under `CI` and is skipped
//! elsewhere (scripts/setup-test-deps.sh installs them).

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// What must pass inside the VM.
const CHECKS: [&str; 6] = [
    "cansend-to-buslab-dump",
    "error-frame-decoded",
    "buslab-send-to-candump",
    "bridge-virtual-bus-and-vcan0",
    "slcand-slcan0-candump",
    "cansend-slcan0-to-virtual-bus",
];

/// Booting took 16 s here (TCG, measured): a boot that has not finished after 7 times that is
/// taken as hung.
const BOOT_DEADLINE: Duration = Duration::from_secs(120);

/// The checks took 1.2 times the boot here: they get 10 times the boot this run took, at
/// least a minute, and no more than keeps the whole test under nextest's 5-minute kill.
fn checks_deadline(boot: Duration) -> Duration {
    (boot * 10).clamp(
        Duration::from_secs(60),
        Duration::from_secs(280).saturating_sub(boot),
    )
}

/// Under `CI` a missing piece fails the test; elsewhere it is skipped with a note.
fn missing(what: &str) {
    assert!(
        std::env::var_os("CI").is_none(),
        "the SocketCAN VM test cannot run in CI: {what}"
    );
    eprintln!("SKIPPED: {what}; run scripts/setup-test-deps.sh");
}

struct Vm(Child);

impl Drop for Vm {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn socketcan_in_a_vm() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let qemu = "qemu-system-x86_64";
    if Command::new(qemu)
        .arg("--version")
        .output()
        .map_or(true, |o| !o.status.success())
    {
        return missing("qemu-system-x86_64 is missing");
    }
    // This test's own binary goes into the VM (a release build would cost CI minutes).
    let build = Command::new("bash")
        .arg(root.join("scripts/vm/build-initramfs.sh"))
        .arg(root.join("target/vm"))
        .arg(env!("CARGO_BIN_EXE_buslab"))
        .output()
        .unwrap();
    if !build.status.success() {
        return missing(&format!(
            "the VM cannot be built: {}",
            String::from_utf8_lossy(&build.stderr).trim()
        ));
    }
    let paths = String::from_utf8_lossy(&build.stdout).into_owned();
    let path = |key: &str| {
        paths
            .lines()
            .find_map(|l| l.strip_prefix(key))
            .unwrap_or_else(|| panic!("no {key} from build-initramfs.sh: {paths}"))
            .to_string()
    };
    let (kernel, initrd) = (path("KERNEL="), path("INITRD="));

    let start = Instant::now();
    // At the lowest CPU priority: the emulator would otherwise take a whole core from the
    // tests beside it, some of which pace serial lines to the wall clock. Its own deadlines
    // follow the boot it measures, so a slower VM only waits longer.
    let mut vm = Vm(Command::new("nice")
        .args(["-n", "19", qemu])
        .args(["-accel", "tcg", "-m", "512", "-smp", "1", "-no-reboot"])
        .args(["-display", "none", "-serial", "stdio", "-monitor", "none"])
        .args(["-kernel", &kernel, "-initrd", &initrd])
        .args(["-append", "console=ttyS0 quiet panic=-1"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap());
    let (tx, lines) = mpsc::channel();
    let out = vm.0.stdout.take().unwrap();
    std::thread::spawn(move || {
        let mut out = BufReader::new(out);
        let mut buf = Vec::new();
        while out.read_until(b'\n', &mut buf).is_ok_and(|n| n > 0) {
            let line = String::from_utf8_lossy(&buf).trim_end().to_string();
            buf.clear();
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut console = Vec::new();
    let mut wait_for = |prefix: &str, deadline: Instant| -> Option<String> {
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let line = lines.recv_timeout(left).ok()?;
            // The console also carries the BIOS's escape sequences: look inside the line.
            let found = line.find(prefix).map(|at| line[at..].to_string());
            console.push(line);
            if found.is_some() {
                return found;
            }
        }
    };
    let booted = wait_for("VMTEST BOOTED", start + BOOT_DEADLINE);
    let boot = start.elapsed();
    let Some(booted) = booted else {
        drop(vm);
        panic!(
            "the VM did not boot within {BOOT_DEADLINE:?} (QEMU with -accel tcg); its console:\n{}",
            console.join("\n")
        );
    };
    let done = wait_for("VMTEST DONE", Instant::now() + checks_deadline(boot));
    let total = start.elapsed();
    let report: Vec<&String> = console
        .iter()
        .filter(|l| l.contains("VMTEST") || l.starts_with("  | "))
        .collect();
    // The acceptance output: shown with --no-capture, and with any failure.
    eprintln!(
        "{booted} in {boot:.1?}, all checks in {total:.1?}\n{}",
        report
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
    let console_text = console.join("\n");
    let Some(done) = done else {
        panic!(
            "the checks did not finish within {:?} of the boot; console:\n{console_text}",
            checks_deadline(boot)
        );
    };
    for check in CHECKS {
        assert!(
            console
                .iter()
                .any(|l| l.ends_with(&format!("VMTEST PASS {check}"))),
            "{check} did not pass; console:\n{console_text}"
        );
    }
    assert!(
        done.ends_with(&format!("passed={} failed=0", CHECKS.len())),
        "{done}; console:\n{console_text}"
    );
}
