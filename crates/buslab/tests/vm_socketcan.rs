//! Real Linux SocketCAN, in a virtual machine (this machine's kernel has no `AF_CAN`): QEMU
//! with software emulation boots Debian's kernel with a busybox initramfs holding the CAN
//! modules, this buslab binary and can-utils (`scripts/vm/build-initramfs.sh`); the checks in
//! `scripts/vm/socketcan-test.sh` run inside and report over the serial console:
//! cansend → `buslab dump socketcan:vcan0` (frames, and an error frame in candump's words),
//! `buslab send socketcan:vcan0` → candump,
//! `buslab bridge` between `buslab bus serve` and vcan0 (whose pump is woken by the frames it
//! is handed), and `buslab slcan serve` attached
//! with slcand as slcan0 and read by candump; CAN FD on interfaces with MTU 72 (cansend's FD
//! frames in `buslab dump -L`, `buslab bridge` between two FD interfaces both ways, and to a
//! classic interface, where FD frames are counted and the MTU named).
//!
//! Without QEMU, the kernel package or the tools this test fails under `CI` and is skipped
//! elsewhere (scripts/setup-test-deps.sh installs them).

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// What must pass inside the VM.
const CHECKS: [&str; 10] = [
    "cansend-to-buslab-dump",
    "error-frame-decoded",
    "buslab-send-to-candump",
    "bridge-virtual-bus-and-vcan0",
    "bridge-pump-woken-for-vcan0",
    "slcand-slcan0-candump",
    "cansend-slcan0-to-virtual-bus",
    "fd-cansend-to-buslab-dump",
    "fd-bridge-vcan1-vcan2",
    "fd-to-a-classic-interface-counted",
];

/// Booting took 16 s of QEMU's CPU time here (TCG, measured): a boot that has used 7 times
/// that without finishing is taken as hung.
const BOOT_WORK: Duration = Duration::from_secs(120);

/// The checks took about 1 times the boot's work here, and up to 10 times it on a host with
/// 4 busy loops and builds beside it (the guest's waits for events, however sparse, cost
/// work as the wall time they last grows): they get 30 times this run's boot, and at least
/// 4 minutes of it. This only catches a guest spinning forever; a slow one has `WALL_LIMIT`.
fn checks_work(boot: Duration) -> Duration {
    (boot * 30).max(Duration::from_secs(240))
}

/// A guest that hangs idle uses no CPU time: it is given up on after this much wall time,
/// under the 20-minute kill `.config/nextest.toml` gives this test. Starved by a loaded host
/// (QEMU runs at nice 19), the VM needed about 18 times its unloaded wall time.
const WALL_LIMIT: Duration = Duration::from_secs(18 * 60);

/// The work the VM has done so far: the CPU time QEMU used, all its threads. With software
/// emulation the guest only runs while QEMU computes, so a VM the host starves progresses
/// slower in wall time but not in this, and deadlines in it hold on any load.
fn vm_work(pid: u32) -> Duration {
    // Linux reports these in USER_HZ, 100 per second on every architecture it runs on.
    const TICKS_PER_SECOND: u64 = 100;
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // After "pid (name) ": the state is field 3, utime and stime fields 14 and 15.
    let fields: Vec<&str> = stat
        .rsplit_once(") ")
        .map_or("", |(_, rest)| rest)
        .split_whitespace()
        .collect();
    let ticks: u64 = fields
        .get(11..13)
        .unwrap_or_default()
        .iter()
        .filter_map(|f| f.parse::<u64>().ok())
        .sum();
    Duration::from_millis(ticks * 1000 / TICKS_PER_SECOND)
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
        // no_timer_check: the kernel times its timer interrupt against the emulated CPU at boot;
        // on a loaded host (nice 19) TCG is too slow for it and the kernel panics with
        // "IO-APIC + timer doesn't work" (a stress run did). Virtual machines skip that check.
        .args(["-append", "console=ttyS0 quiet panic=-1 no_timer_check"])
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
    let pid = vm.0.id();
    let mut console = Vec::new();
    // Until a line holding `prefix`, the VM's work reaching `work`, or the wall-time limit.
    let mut wait_for = |prefix: &str, work: Duration| -> Option<String> {
        loop {
            let left = WALL_LIMIT.saturating_sub(start.elapsed());
            if left.is_zero() || vm_work(pid) >= work {
                return None;
            }
            // The VM's work is looked at every second between lines.
            let line = match lines.recv_timeout(left.min(Duration::from_secs(1))) {
                Ok(line) => line,
                Err(mpsc::RecvTimeoutError::Timeout) => continue,
                Err(mpsc::RecvTimeoutError::Disconnected) => return None,
            };
            // The console also carries the BIOS's escape sequences: look inside the line.
            let found = line.find(prefix).map(|at| line[at..].to_string());
            console.push(line);
            if found.is_some() {
                return found;
            }
        }
    };
    let booted = wait_for("VMTEST BOOTED", BOOT_WORK);
    let boot = start.elapsed();
    let boot_work = vm_work(pid);
    let Some(booted) = booted else {
        drop(vm);
        panic!(
            "the VM did not boot within {BOOT_WORK:?} of QEMU's CPU time (-accel tcg; \
             {boot:.1?} wall time, limit {WALL_LIMIT:?}); its console:\n{}",
            console.join("\n")
        );
    };
    let done = wait_for("VMTEST DONE", boot_work + checks_work(boot_work));
    let total = start.elapsed();
    let report: Vec<&String> = console
        .iter()
        .filter(|l| l.contains("VMTEST") || l.starts_with("  | "))
        .collect();
    // The acceptance output: shown with --no-capture, and with any failure.
    eprintln!(
        "{booted} in {boot:.1?} ({boot_work:.1?} of CPU), all checks in {total:.1?} ({:.1?} \
         of CPU)\n{}",
        vm_work(pid),
        report
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
    let console_text = console.join("\n");
    let Some(done) = done else {
        panic!(
            "the checks did not finish within {:?} of QEMU's CPU time after the boot (or \
             {WALL_LIMIT:?} of wall time in all); console:\n{console_text}",
            checks_work(boot_work)
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
