//! CPU196 user programs (issue 31): the examples of examples/cpu196/ built here with Debian's
//! clang (C) and wabt's wat2wasm (WAT), flashed into the served board over its PTY with
//! `buslab cpu196 program flash`, and started by the existing monitor.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use buslab_cpu196::message::Start;
use buslab_cpu196::source::{Inputs, Source};
use buslab_cpu196::{Board, pic::Peer};
use buslab_link::Served;
use buslab_served::cpu196::{BoardOptions, spawn_board};

const BAUD: u32 = 250_000;
/// How long the CLI waits for an answer beyond its time on the line: far above any scheduling
/// delay on a loaded machine (waiting costs nothing when the answer comes).
const ALLOWANCE: &str = "30s";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn examples() -> PathBuf {
    root().join("examples/cpu196")
}

/// Fails naming the setup script when a tool is missing: these tests are the examples' build.
fn need(tool: &str) {
    let found = std::env::var_os("PATH")
        .is_some_and(|path| std::env::split_paths(&path).any(|dir| dir.join(tool).is_file()));
    assert!(
        found,
        "{tool} is missing: scripts/setup-test-deps.sh installs it (Debian clang, lld, wabt; run it as root)"
    );
}

/// Builds the examples into `out` with examples/cpu196/build.sh.
fn build(out: &Path) {
    for tool in ["clang", "wasm-ld", "wat2wasm"] {
        need(tool);
    }
    let run = Command::new("bash")
        .arg(examples().join("build.sh"))
        .arg(out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "build.sh: {}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
}

struct Bench {
    served: Option<Served<Board>>,
    dir: tempfile::TempDir,
    image: PathBuf,
    link: PathBuf,
}

impl Bench {
    /// The board served in this process (so its PWM outputs can be read), with a constant
    /// 3 V on the 80C196's channel 0, and the examples built.
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        build(&dir.path().join("built"));
        std::fs::create_dir(dir.path().join("files")).unwrap();
        let image = dir.path().join("image.toml");
        let link = dir.path().join("board");
        let mut b = Self {
            served: None,
            dir,
            image,
            link,
        };
        b.serve();
        b
    }

    fn serve(&mut self) {
        let mut inputs = Inputs::default();
        inputs.c196[0] = Source::Constant(3.0);
        let _ = std::fs::remove_file(&self.link);
        self.served = Some(
            spawn_board(BoardOptions {
                image: Some(self.image.clone()),
                link: Some(self.link.clone()),
                baud: BAUD,
                inputs,
                peer: Peer::default(),
            })
            .unwrap(),
        );
    }

    fn restart(&mut self) {
        self.served.take().unwrap().stop().unwrap();
        self.serve();
    }

    fn module(&self, name: &str) -> String {
        self.dir
            .path()
            .join("built")
            .join(name)
            .to_str()
            .unwrap()
            .to_string()
    }

    fn files(&self) -> PathBuf {
        self.dir.path().join("files")
    }

    fn cli(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args([
                "cpu196",
                "--baud",
                &BAUD.to_string(),
                "--timeout",
                ALLOWANCE,
            ])
            .arg("--port")
            .arg(&self.link)
            .args(args)
            .stdin(Stdio::null())
            .output()
            .unwrap()
    }

    fn ok(&self, args: &[&str]) -> String {
        let out = self.cli(args);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{args:?} failed: {text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        text
    }

    fn pwm(&self) -> [u8; 3] {
        self.served.as_ref().unwrap().with(|b, _| b.pwm()).unwrap()
    }
}

#[test]
fn the_committed_example_modules_are_what_build_sh_makes_of_the_sources() {
    let dir = tempfile::tempdir().unwrap();
    build(dir.path());
    for name in ["hello.wasm", "runaway.wasm"] {
        assert_eq!(
            std::fs::read(dir.path().join(name)).unwrap(),
            std::fs::read(examples().join(name)).unwrap(),
            "examples/cpu196/{name} is stale: run examples/cpu196/build.sh"
        );
    }
}

#[test]
fn a_c_program_flashed_and_started_by_the_monitor_shows_its_output_pwm_file_and_start() {
    let mut b = Bench::new();
    // Argument 0: 3 lines; argument 1: the START it triggers then (bank 0 set 1, the logger).
    let logger = Start::run(0, 1, true).word().to_string();
    let out = b.ok(&[
        "program",
        "flash",
        &b.module("hello.wasm"),
        "--bank",
        "0",
        "--config",
        "0",
        "--args",
        &format!("3,{logger}"),
        "--yes",
    ]);
    assert!(
        out.starts_with("wrote and verified \"hello\" (")
            && out.contains("into bank 0; hooks init_prog AD_prog fin_prog\n2 blocks of 28h..3Fh written back\nconfiguration 0 of bank 0 runs it"),
        "{out}"
    );
    let files = b.files();
    let out = b.ok(&[
        "monitor",
        "--files",
        files.to_str().unwrap(),
        "--start",
        "0",
        "--duration",
        "1s",
    ]);
    // Its THREAD output, its file, the START it triggered (the logger's greeting).
    let expected = [
        "started bank 0 configuration 0",
        "THREAD: hello from C",
        "opened `hello.txt` (Write)",
        "closed",
        "THREAD: hello: lines written 3",
        "THREAD: logger: writing ad.csv",
    ];
    let mut at = 0;
    for line in expected {
        let found = out[at..]
            .find(line)
            .unwrap_or_else(|| panic!("{line:?} missing after byte {at}:\n{out}"));
        at += found + line.len();
    }
    // 3 V on channel 0: 10-bit 614 (round(3 × 1023 / 5)), the 80C196's 16-bit value >> 6.
    let text = std::fs::read_to_string(files.join("hello.txt")).unwrap();
    let values: Vec<u32> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let (n, v) = l.split_once(": ").unwrap();
            assert_eq!(n, format!("line {}", i + 1));
            v.parse().unwrap()
        })
        .collect();
    assert_eq!(values.len(), 3, "{text}");
    assert!(values.iter().all(|&v| v.abs_diff(614) <= 1), "{text}");
    // Its PWM writes: channel 0's top 8 bits on PWM 0, the line count on PWM 1 (the logger
    // that runs after it leaves them).
    assert_eq!(b.pwm()[..2], [(values[2] >> 2) as u8, 3]);

    // The image keeps the module: after a restart the board lists and runs it.
    b.restart();
    let list = b.ok(&["program", "list", "--bank", "0"]);
    assert!(
        list.contains("  set 0: module at bank 0 block 60h, arguments 3 65 0 0 0 0 0\n")
            && list.contains("  set 1: built-in 1 (logger)")
            && list.contains("  module at block 60h: \"hello\", "),
        "{list}"
    );
    let out = b.ok(&["monitor", "--start", "0", "--duration", "500ms"]);
    assert!(out.contains("THREAD: hello from C"), "{out}");

    // F5 03 (flash erase) takes it away: START says what is missing.
    b.ok(&["flash", "erase", "--bank", "0", "--yes"]);
    let err = String::from_utf8_lossy(&b.cli(&["start", "--config", "0"]).stderr).into_owned();
    assert!(
        err.contains(
            "START bank 0 configuration 0: the board answered msg_invalid_parameter_value"
        ),
        "{err}"
    );
}

#[test]
fn a_runaway_hook_is_stopped_by_fuel_with_an_alert_and_the_board_goes_on() {
    let b = Bench::new();
    let out = b.ok(&[
        "program",
        "flash",
        &b.module("runaway.wasm"),
        "--bank",
        "3",
        "--config",
        "0",
        "--yes",
    ]);
    assert!(
        out.contains("(a new configuration table: the other sets are empty)"),
        "{out}"
    );
    let out = b.ok(&["monitor", "--bank", "3", "--start", "0", "--duration", "1s"]);
    assert!(
        out.contains(
            "THREAD: runaway: looping\nALERT: alert_user_program_stopped (23h)\nTHREAD: program stopped in init_prog: ran out of fuel: more than 50 ms of CPU time (100000 instructions) in one call; an endless loop?\n"
        ),
        "{out}"
    );
    assert!(out.ends_with("stopped\n"), "{out}");
    // The lower loop ended: the board takes upper-loop commands again.
    assert!(b.ok(&["info"]).contains("serial number"));
}

#[test]
fn a_refused_module_is_named_before_anything_is_written() {
    let b = Bench::new();
    let bad = b.dir.path().join("bad.wasm");
    // A module exporting a misspelt hook.
    std::fs::write(
        &bad,
        [
            &b"\0asm\x01\0\0\0"[..],
            // type section: () -> i32
            &[0x01, 0x05, 0x01, 0x60, 0x00, 0x01, 0x7F],
            // function section: one function of type 0
            &[0x03, 0x02, 0x01, 0x00],
            // export section: "AD_Prog" func 0
            &[0x07, 0x0B, 0x01, 0x07],
            b"AD_Prog",
            &[0x00, 0x00],
            // code section: i32.const 0, end
            &[0x0A, 0x06, 0x01, 0x04, 0x00, 0x41, 0x00, 0x0B],
        ]
        .concat(),
    )
    .unwrap();
    let out = b.cli(&[
        "program",
        "flash",
        bad.to_str().unwrap(),
        "--bank",
        "2",
        "--yes",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.wasm is refused")
            && err.contains("exports the function `AD_Prog`, which is no hook (hooks: init_prog,"),
        "{err}"
    );
    let check = b.cli(&["program", "check", bad.to_str().unwrap()]);
    assert!(!check.status.success());
    let list = b.ok(&["program", "list", "--bank", "2"]);
    assert_eq!(list, "bank 2\n  no configuration table\n");
}
