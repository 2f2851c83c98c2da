//! `buslab cpu196` end to end: a served board model on a pseudo-terminal, driven by the CLI.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const BAUD: &str = "250000";

/// How long the CLI waits for an answer beyond its time on the line, and how long a test waits
/// for the served board to appear or stop: far above any scheduling delay on a loaded machine
/// (waiting costs nothing when things happen). Only commands that expect silence wait less.
const ALLOWANCE: &str = "30s";
const ALLOWANCE_S: u64 = 30;

struct Board {
    child: Child,
    link: PathBuf,
    dir: tempfile::TempDir,
}

impl Board {
    fn serve(extra: &[&str]) -> Self {
        let dir = tempfile::tempdir().unwrap();
        Self::serve_in(dir, extra)
    }

    fn serve_in(dir: tempfile::TempDir, extra: &[&str]) -> Self {
        let link = dir.path().join("board");
        let image = dir.path().join("image.toml");
        // The board's log (what the kernel refused, and why), shown when a command fails.
        let log = std::fs::File::create(dir.path().join("serve.log")).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["-vv", "cpu196", "serve", "--baud", BAUD, "--link"])
            .arg(&link)
            .arg("--image")
            .arg(&image)
            .args(extra)
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .unwrap();
        let until = Instant::now() + Duration::from_secs(ALLOWANCE_S);
        while !link.exists() {
            assert!(
                Instant::now() < until,
                "the board never appeared at {}",
                link.display()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Self { child, link, dir }
    }

    fn cli(&self, args: &[&str]) -> Output {
        self.cli_waiting(ALLOWANCE, args)
    }

    fn cli_waiting(&self, timeout: &str, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["cpu196", "--baud", BAUD, "--timeout", timeout, "--port"])
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
            "{args:?} failed: {}{}\nthe served board's log:\n{}",
            text,
            String::from_utf8_lossy(&out.stderr),
            self.log()
        );
        text
    }

    fn fails(&self, args: &[&str]) -> String {
        let out = self.cli(args);
        assert!(!out.status.success(), "{args:?} should have failed");
        String::from_utf8_lossy(&out.stderr).into_owned()
    }

    /// What the served board logged so far.
    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("serve.log")).unwrap_or_default()
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Stops the model (it saves its image) and returns the folder.
    fn shut_down(mut self) -> tempfile::TempDir {
        // SIGINT: the served board saves its image and exits.
        let _ = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status();
        let until = Instant::now() + Duration::from_secs(ALLOWANCE_S);
        while self.child.try_wait().unwrap().is_none() {
            if Instant::now() > until {
                let _ = self.child.kill();
                panic!("the served board did not stop within {ALLOWANCE}");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.wait();
        std::mem::replace(&mut self.dir, tempfile::tempdir().unwrap())
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn info_prints_the_board_identity() {
    let b = Board::serve(&[]);
    let out = b.ok(&["info"]);
    assert!(out.contains("serial number   BL196001"), "{out}");
    assert!(out.contains("quartz          20 MHz"), "{out}");
    drop(b);
    // A scripted device on the PIC's SCI.
    let b = Board::serve(&["--peer", "script:41=4F4B"]);
    let out = b.ok(&["bridge", "sci", "0x41"]);
    assert!(out.contains("SCI received 4Fh"), "{out}");
    let cfg = b.ok(&["cfgad", "0", "5"]);
    assert!(cfg.contains("channel 3  log8-bit format"), "{cfg}");
    assert!(b.fails(&["cfgad", "0", "9"]).contains("out of range 0..7"));
}

#[test]
fn monitor_shows_thread_text_and_serves_a_file_write() {
    let b = Board::serve(&[]);
    let files = b.path("files");
    std::fs::create_dir(&files).unwrap();
    let out = b.ok(&[
        "monitor",
        "--files",
        s(&files),
        "--start",
        "1",
        "--duration",
        "1s",
    ]);
    assert!(out.contains("THREAD: logger: writing ad.csv"), "{out}");
    assert!(out.contains("opened `ad.csv`"), "{out}");
    // Numbers in the THREAD stream: unsigned 16-bit, then the same in hex.
    let lines = std::fs::read_to_string(files.join("ad.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    assert!(
        out.contains(&format!(
            "THREAD: logger: done, lines written: {lines}\nTHREAD: {lines:04X}\n"
        )),
        "{out}"
    );
    let csv = std::fs::read_to_string(files.join("ad.csv")).unwrap();
    assert!(csv.starts_with("ms,ch0,ch1\n"), "{csv}");
    assert!(csv.lines().count() >= 2, "{csv}");
}

#[test]
fn monitor_serves_a_file_the_board_reads() {
    let b = Board::serve(&[]);
    let files = b.path("files");
    std::fs::create_dir(&files).unwrap();
    std::fs::write(files.join("pattern.bin"), (0..100u8).collect::<Vec<_>>()).unwrap();
    // Bank 1 set 0: PWM playback of pattern.bin, one byte per millisecond.
    let out = b.ok(&[
        "monitor",
        "--files",
        s(&files),
        "--bank",
        "1",
        "--start",
        "0",
        "--no-ad",
        "--duration",
        "3s",
    ]);
    assert!(out.contains("opened `pattern.bin` (Read)"), "{out}");
    assert!(
        out.contains("THREAD: pwm-playback: 100 samples played"),
        "{out}"
    );
    // Without a files folder the requests are refused; the program holds its output until the
    // monitor STOPs it.
    let out = b.ok(&[
        "monitor",
        "--bank",
        "1",
        "--start",
        "0",
        "--no-ad",
        "--duration",
        "500ms",
    ]);
    assert!(out.contains("request refused (no --files DIR)"), "{out}");
}

#[test]
fn monitor_starts_a_set_without_an_acquisition_as_the_docs_show() {
    // docs/cpu196.md: `monitor --start 4 --duration 2s` (the pulse train has no A/D sequence).
    let b = Board::serve(&[]);
    let out = b.ok(&["monitor", "--start", "4", "--duration", "2s"]);
    assert!(
        out.contains("started bank 0 configuration 4 with the 80C196 A/D off"),
        "{out}"
    );
    assert!(out.contains("THREAD: pulse-train: 10 pulses"), "{out}");
    // `start` says why the board refuses the acquisition, and what to do.
    let err = b.fails(&["start", "--config", "4"]);
    assert!(
        err.contains(
            "START bank 0 configuration 4: the board answered msg_ad_config_error: the \
             conversion sequence is empty"
        ),
        "{err}"
    );
    assert!(err.contains("--no-ad starts the set"), "{err}");
    b.ok(&["start", "--config", "4", "--no-ad"]);
}

/// `record --config 1` for `duration` with 4 V on the 80C196's channel 0 and 1 V on channel 1:
/// every row of the CSV holds its channel's value; the number of rows.
fn record_4v_and_1v(b: &Board, duration: &str) -> usize {
    let out_csv = b.path("rec.csv");
    let out = b.ok(&[
        "record",
        "--config",
        "1",
        "--out",
        s(&out_csv),
        "--duration",
        duration,
    ]);
    assert!(out.contains("recorded"), "{out}");
    let csv = std::fs::read_to_string(&out_csv).unwrap();
    let mut rows = 0;
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[1], "c196");
        let want = if f[2] == "0" { 4.0 } else { 1.0 };
        let v: f64 = f[4].parse().unwrap();
        assert!((v - want).abs() < 0.005, "{line}");
        rows += 1;
    }
    rows
}

#[test]
fn record_writes_the_configured_acquisition_to_csv() {
    let b = Board::serve(&["--input", "0=const:4", "--input", "1=const:1"]);
    let rows = record_4v_and_1v(&b, "0.5s");
    // 0.5 s at 1 kHz, 2 channels.
    assert!(rows >= 800, "{rows} rows");
}

/// `record --plot`: the recording as a figure: one line per channel, in volts.
#[test]
fn record_plot_shows_each_channel_in_volts() {
    let b = Board::serve(&["--input", "0=sine:2Hz:2V:2.5V", "--input", "1=const:1"]);
    let (csv, svg) = (b.path("rec.csv"), b.path("rec.svg"));
    let out = b.ok(&[
        "record",
        "--config",
        "1",
        "--out",
        s(&csv),
        "--duration",
        "1s",
        "--plot",
        s(&svg),
    ]);
    assert!(out.contains("recorded"), "{out}");
    let svg = std::fs::read_to_string(&svg).unwrap();
    let seen = buslab_plot::inspect::parse(&svg).unwrap();
    let panel = seen.panel("A/D channels").unwrap();
    assert_eq!(panel.legend(), ["c196 ch0", "c196 ch1"]);
    assert_eq!(panel.value_title(), Some("voltage (V)"));
    let span = |points: &[(f64, f64)]| {
        points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.1), hi.max(p.1))
        })
    };
    // 2.5 V ± 2 V at 2 Hz over a second: both extremes drawn (read to a pixel: 5 V over
    // ~200 px).
    let (lo, hi) = span(&panel.series("c196 ch0").unwrap());
    assert!(
        (lo - 0.5).abs() < 0.1 && (hi - 4.5).abs() < 0.1,
        "{lo}..{hi}"
    );
    let (lo, hi) = span(&panel.series("c196 ch1").unwrap());
    assert!(
        (lo - 1.0).abs() < 0.05 && (hi - 1.0).abs() < 0.05,
        "{lo}..{hi}"
    );
    // A refused --plot name costs no recording: checked before the board is started.
    let err = b.fails(&[
        "record",
        "--out",
        s(&b.path("x.csv")),
        "--plot",
        s(&b.path("x.png")),
    ]);
    assert!(err.contains("ending in .svg"), "{err}");
    // The figure is drawn from the samples as they came, not from the CSV read back: a
    // recording that goes nowhere still has its picture (a second of it, as above: the A/D
    // runs at the board's pace, whatever the load).
    let nowhere = b.path("nowhere.svg");
    b.ok(&[
        "record",
        "--config",
        "1",
        "--out",
        "/dev/null",
        "--duration",
        "1s",
        "--plot",
        s(&nowhere),
    ]);
    let seen = buslab_plot::inspect::parse(&std::fs::read_to_string(&nowhere).unwrap()).unwrap();
    let panel = seen.panel("A/D channels").unwrap();
    assert_eq!(panel.legend(), ["c196 ch0", "c196 ch1"]);
}

#[test]
fn flash_bank_write_reads_back_identical_and_survives_a_restart() {
    let b = Board::serve(&[]);
    let mut bank = vec![0xFFu8; 65536];
    for (i, x) in bank[0x6000..0x7000].iter_mut().enumerate() {
        *x = (i * 31 % 251) as u8;
    }
    bank[0x2A00..0x2B00].fill(0x11);
    let input = b.path("bank.bin");
    std::fs::write(&input, &bank).unwrap();
    // Destructive: refused without --yes when stdin is not a terminal.
    assert!(
        b.fails(&["flash", "write", "--bank", "3", "--in", s(&input)])
            .contains("--yes")
    );
    let out = b.ok(&["--yes", "flash", "write", "--bank", "3", "--in", s(&input)]);
    assert!(out.contains("wrote and verified 17 blocks"), "{out}");
    let back = b.path("back.bin");
    b.ok(&["flash", "read", "--bank", "3", "--out", s(&back)]);
    assert_eq!(std::fs::read(&back).unwrap(), bank);
    let err = b.fails(&["--yes", "flash", "write", "--bank", "3", "--in", s(&input)]);
    assert!(err.contains("msg_not_blank_error"), "{err}");
    // Data in a kernel area is refused before anything is written.
    let mut bad = bank.clone();
    bad[0x0300] = 0;
    std::fs::write(&input, &bad).unwrap();
    assert!(
        b.fails(&["--yes", "flash", "write", "--bank", "4", "--in", s(&input)])
            .contains("block 03h")
    );

    let dir = b.shut_down();
    let b = Board::serve_in(dir, &[]);
    let again = b.path("again.bin");
    b.ok(&["flash", "read", "--bank", "3", "--out", s(&again)]);
    assert_eq!(std::fs::read(&again).unwrap(), bank);
    b.ok(&["--yes", "flash", "erase", "--bank", "3"]);
    b.ok(&[
        "flash",
        "read",
        "--bank",
        "3",
        "--block",
        "0x60",
        "--out",
        s(&again),
    ]);
    assert_eq!(std::fs::read(&again).unwrap(), vec![0xFF; 256]);
}

#[test]
fn pic_eeprom_pwm_bridge_start_stop_user_reset_powerdown() {
    let b = Board::serve(&[]);
    let pic: Vec<u8> = (0..4096).map(|i| (i % 200) as u8).collect();
    let f = b.path("pic.bin");
    std::fs::write(&f, &pic).unwrap();
    b.ok(&["--yes", "pic", "write", "--block", "2", "--in", s(&f)]);
    let back = b.path("pic-back.bin");
    b.ok(&["pic", "read", "--block", "2", "--out", s(&back)]);
    assert_eq!(std::fs::read(&back).unwrap(), pic);
    assert!(
        b.fails(&["pic", "read", "--block", "4", "--out", s(&back)])
            .contains("1..3")
    );
    std::fs::write(&f, [0x42u8; 256]).unwrap();
    b.ok(&["--yes", "eeprom", "write", "--in", s(&f)]);
    b.ok(&["eeprom", "read", "--out", s(&back)]);
    assert_eq!(std::fs::read(&back).unwrap(), vec![0x42; 256]);
    assert!(b.ok(&["pwm", "1", "200"]).contains("PWM 1 = 200"));
    assert!(b.fails(&["pwm", "dac", "40"]).contains("0..31"));
    assert!(
        b.ok(&["bridge", "spi", "0x5A"])
            .contains("SPI received 5Ah")
    );
    assert!(b.ok(&["bridge", "sci", "65"]).contains("SCI received 41h"));
    b.ok(&["bridge", "par-mask", "0"]);
    b.ok(&["bridge", "par-write", "0xC3"]);
    assert!(b.ok(&["bridge", "par-read"]).contains("reads C3h"));
    // The lower loop refuses CPUINF. Its watchdog would end the run after 3 s without a byte
    // from the PC (the next CLI process may take that long to start on a loaded machine):
    // off, from the next reset.
    b.ok(&["--yes", "format", "boot-set", "--watchdog", "off"]);
    b.ok(&["--yes", "reset"]);
    b.ok(&["start", "--config", "0", "--no-ad"]);
    assert!(b.fails(&["info"]).contains("msg_invalid_command"));
    b.ok(&["stop"]);
    // `user` prints what the board sends within its time-out: a few seconds are plenty for
    // the answer, and the test need not listen for the whole allowance.
    let out = b.cli_waiting("5s", &["user", "0x20"]);
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("msg_invalid_command"),
        "{out:?}"
    );
    assert!(b.fails(&["user", "0xF3"]).contains("00h..EFh"));
    assert!(b.fails(&["reset"]).contains("--yes"));
    assert!(b.ok(&["--yes", "reset"]).contains("the board reset"));
    assert!(b.ok(&["--yes", "powerdown"]).contains("powered down"));
    // A powered-down board stays silent: no need to wait long for that.
    let out = b.cli_waiting("300ms", &["info"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("board lost"), "{err}");
    assert!(err.contains("at 250000 8N1 like this client"), "{err}");
}

#[test]
fn format_boot_configuration_serial_and_emergency_erase() {
    let b = Board::serve(&[]);
    let out = b.ok(&["format", "boot"]);
    assert!(
        out.contains("battery         thresholds [100, 140, 220]"),
        "{out}"
    );
    assert!(
        b.fails(&["format", "boot-set", "--thresholds", "1,2,3"])
            .contains("--yes")
    );
    b.ok(&[
        "--yes",
        "format",
        "boot-set",
        "--thresholds",
        "90,150,230",
        "--boot-start",
        "0:1",
    ]);
    let out = b.ok(&["format", "boot"]);
    assert!(out.contains("thresholds [90, 150, 230]"), "{out}");
    assert!(
        out.contains("boot START      bank 0 configuration 1 (A/D on)"),
        "{out}"
    );
    assert!(
        b.fails(&["--yes", "format", "serial", "SHORT"])
            .contains("exactly 8")
    );
    b.ok(&["--yes", "format", "serial", "ABCD1234"]);
    assert!(b.ok(&["info"]).contains("serial number   ABCD1234"));
    // Everything was erased: bank 0 holds no configuration table any more.
    assert!(
        b.fails(&["cfgad", "0", "0"])
            .contains("msg_invalid_parameter_value")
    );
    let k = b.path("kernel.bin");
    std::fs::write(&k, [0x3Cu8; 4096]).unwrap();
    b.ok(&["--yes", "format", "pic-kernel-write", "--in", s(&k)]);
    let ee = b.path("ee-in.bin");
    std::fs::write(&ee, [0x3Cu8; 256]).unwrap();
    b.ok(&["--yes", "eeprom", "write", "--in", s(&ee)]);
    // The boot START names a configuration that was erased: the board would report it at
    // every reset. Switch it off first.
    b.ok(&["--yes", "format", "boot-set", "--boot-start", "none"]);
    b.ok(&["--yes", "format", "emergency", "0xC0"]);
    let back = b.path("ee.bin");
    b.ok(&["eeprom", "read", "--out", s(&back)]);
    assert_eq!(std::fs::read(&back).unwrap(), vec![0xFF; 256]);
}

#[test]
fn bad_durations_are_refused_with_the_value_not_a_panic() {
    for args in [
        &["record", "--out", "x.csv", "--duration", "nan"][..],
        &["record", "--out", "x.csv", "--duration=-1"],
        &["monitor", "--duration", "1e300"],
        &["monitor", "--duration", "inf"],
        // A unit is always needed.
        &["monitor", "--duration", "2"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["cpu196", "--port", "/nonexistent/board"])
            .args(args)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let value = args.last().unwrap().trim_start_matches("--duration=");
        assert!(
            err.contains(&format!("duration {value:?}")),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn serve_offers_only_what_it_uses_and_every_argument_has_help() {
    let help = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(args)
            .arg("--help")
            .output()
            .unwrap();
        assert!(out.status.success(), "{args:?}");
        String::from_utf8(out.stdout).unwrap()
    };
    let serve = help(&["cpu196", "serve"]);
    for client_only in ["--port", "--timeout", "--yes"] {
        assert!(
            !serve.contains(client_only),
            "serve offers {client_only}:\n{serve}"
        );
    }
    assert!(serve.contains("--baud"), "{serve}");
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["cpu196", "--port", "/dev/null", "serve"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("are for the client commands"));
    // Every option and positional of every subcommand says what it is.
    for cmd in [
        &["cpu196"][..],
        &["cpu196", "serve"],
        &["cpu196", "monitor"],
        &["cpu196", "record"],
        &["cpu196", "user"],
        &["cpu196", "bridge"],
        &["cpu196", "pwm"],
        &["cpu196", "cfgad"],
        &["cpu196", "flash", "read"],
        &["cpu196", "flash", "write"],
        &["cpu196", "flash", "erase"],
        &["cpu196", "pic", "write"],
        &["cpu196", "eeprom", "write"],
        &["cpu196", "format", "boot-set"],
        &["cpu196", "format", "serial"],
        &["cpu196", "format", "emergency"],
        &["zelle"],
        &["zelle", "serve"],
        &["zelle", "measure"],
        &["zelle", "peek"],
        &["zelle", "poke"],
        &["zelle", "reg"],
        &["zelle", "bus"],
        &["zelle", "upload"],
        &["zelle", "load"],
        &["zelle", "port1"],
        &["zelle", "p26"],
    ] {
        let text = help(cmd);
        for line in text.lines() {
            let entry = line.trim_start();
            let is_arg = entry.starts_with('-') || entry.starts_with('<') || entry.starts_with('[');
            if is_arg {
                // `  --name <VALUE>  Help text`: two spaces separate the name from its help.
                assert!(
                    entry
                        .split_once("  ")
                        .is_some_and(|(_, h)| !h.trim().is_empty()),
                    "{cmd:?}: no help for `{entry}`"
                );
            }
        }
    }
}

#[test]
fn a_refused_start_names_the_bank_and_configuration() {
    // Bank 3 of the default image holds no configuration table.
    let board = Board::serve(&[]);
    let err = board.fails(&["start", "--bank", "3", "--config", "2"]);
    assert!(
        err.contains(
            "START bank 3 configuration 2: the board answered msg_invalid_parameter_value"
        ),
        "{err}"
    );
    let err = board.fails(&["cfgad", "3", "1"]);
    assert!(err.contains("CFGAD bank 3 configuration 1: "), "{err}");
    let err = board.fails(&[
        "record",
        "--bank",
        "3",
        "--out",
        "/dev/null",
        "--duration",
        "0s",
    ]);
    assert!(err.contains("START bank 3 configuration 0: "), "{err}");
}

#[test]
fn a_serial_number_must_be_8_ascii_characters() {
    let board = Board::serve(&[]);
    // 8 bytes, but not 8 ASCII characters.
    let err = board.fails(&["format", "serial", "éééé", "--yes"]);
    assert!(
        err.contains("serial number `éééé` must be exactly 8 ASCII characters"),
        "{err}"
    );
    // Nothing changed.
    assert!(board.ok(&["info"]).contains("BL196001"));
}

#[test]
fn serve_refuses_an_image_it_cannot_write() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["cpu196", "serve", "--image", "/nonexistent/dir/board.toml"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // It must stop at once with an error (before, it served on and lost every change).
    let until = std::time::Instant::now() + Duration::from_secs(ALLOWANCE_S);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > until {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still serving with a file it cannot write");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot write image /nonexistent/dir/board.toml"),
        "{err}"
    );
}

#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    // `buslab cpu196 info | head -1`: the reader goes away, the writer must not panic.
    let board = Board::serve(&[]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["cpu196", "--baud", BAUD, "--timeout", ALLOWANCE, "--port"])
        .arg(&board.link)
        .arg("info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
}

#[test]
fn analog_inputs_take_the_zelles_spelling_and_a_csv_replay() {
    let dir = tempfile::tempdir().unwrap();
    let replay = dir.path().join("battery.csv");
    std::fs::write(&replay, "seconds,volts\n0,4.0\n1e6,3.1\n").unwrap();
    let refused = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["cpu196", "serve"])
            .args(args)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} was taken");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // The former comma spelling is refused with what to write instead.
    let err = refused(&["--input", "0=sine:2.5,2,2"]);
    assert!(err.contains("write sine:2Hz:2V:2.5V"), "{err}");
    let err = refused(&["--pic-input", "8=1V"]);
    assert!(err.contains("channel `8` is out of range 0..7"), "{err}");
    let err = refused(&["--input", "1=csv:/nonexistent/replay.csv"]);
    assert!(err.contains("/nonexistent/replay.csv"), "{err}");
    // A replay (4 V for the first 10^6 s) and the unit spellings are what the board converts.
    let csv = format!("0=csv:{}", replay.display());
    let b = Board::serve(&["--input", &csv, "--input", "1=1000mV"]);
    assert!(record_4v_and_1v(&b, "0.2s") > 0, "nothing recorded");
}
