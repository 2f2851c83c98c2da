//! `buslab lab` carries the seed's SLIO bench: three demo boards and the PowerPC node running
//! MoniCAN, whose VT100 terminal the lab serves as DIR/monican. The test is the user at that
//! terminal: it opens the link at 19200 8N1 and reads the screen back with an independent
//! VT100 emulator (the `vt100` crate).

#[path = "support/vt100_terminal.rs"]
mod vt100_terminal;

#[path = "support/pty_program.rs"]
mod pty_program;

use std::collections::HashSet;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use buslab_monican::app::PAGE_HINT;
use buslab_monican::layout::*;
use buslab_slio::SlioId;
use pty_program::{PtyProgram, Stderr};
use vt100_terminal::{CEILING, READ_SIZE, Terminal};

/// The lab (or another tool), stopped (SIGTERM) when the test ends; what the lab logged is
/// shown when the test fails (a failure seen only on loaded machines needs the lab's side).
struct Lab {
    child: Child,
    log: Option<std::path::PathBuf>,
}

impl Drop for Lab {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let _ = self.child.wait();
        if let Some(log) = self.log.as_ref().filter(|_| std::thread::panicking()) {
            let log = std::fs::read_to_string(log).unwrap_or_default();
            // The calibration frame MoniCAN sends every 40 ms is routine; the rest tells.
            let tail: Vec<&str> = log
                .lines()
                .rev()
                .filter(|line| !line.ends_with("PowerPC sent 0AA#AA04"))
                .take(200)
                .collect();
            eprintln!("the lab's log, last {} lines but calibrations:", tail.len());
            for line in tail.iter().rev() {
                eprintln!("  {line}");
            }
        }
    }
}

/// `buslab lab` with `args` and its files in `dir`, once it is up (`DIR/bus`, written last);
/// its bus URL.
fn lab(dir: &Path, args: &[&str]) -> (Lab, String) {
    let log = dir.join("lab.log");
    let child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["lab", "-q", "--no-web", "--listen", "127.0.0.1:0", "--dir"])
        .arg(dir)
        .args(args)
        .env_remove("BUSLAB_BUS")
        // Warnings, and what the PowerPC node's driver gives up on.
        .env("RUST_LOG", "warn,buslab_ppc=debug")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let lab = Lab {
        child,
        log: Some(log),
    };
    let bus = dir.join("bus");
    let start = Instant::now();
    let url = loop {
        if let Ok(text) = std::fs::read_to_string(&bus)
            && text.ends_with('\n')
        {
            break text.trim().to_string();
        }
        assert!(
            start.elapsed() < CEILING,
            "the lab never wrote {}",
            bus.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    (lab, url)
}

/// Waits until the lab's MoniCAN has initialised its three SLIO boards: each board has sent
/// its sign-on and its answers to MoniCAN's five initialisation requests (six frames). Seen
/// through `buslab status` (administrative requests, no frame on the bus): a second SLIO host
/// asking the boards (`buslab slio list`) would race MoniCAN's own requests, and a read and a
/// write of one SLIO carry the same identifier with other data, so the two collide, as on a
/// real bus, and MoniCAN's node went bus-off on a loaded machine.
fn wait_for_initialised_boards(url: &str) {
    const SENT_WHEN_INITIALISED: u64 = 6;
    let start = Instant::now();
    loop {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["status", "--bus", url])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        let sent = |board: &str| -> u64 {
            let Some((_, after)) = text.split_once(&format!("({board})\n")) else {
                return 0;
            };
            after
                .lines()
                .take_while(|line| !line.is_empty())
                .find_map(|line| line.strip_prefix("sent:"))
                .and_then(|n| n.trim().parse().ok())
                .unwrap_or(0)
        };
        if ["slio0", "slio3", "slioA"]
            .iter()
            .all(|board| sent(board) >= SENT_WHEN_INITIALISED)
        {
            return;
        }
        assert!(
            start.elapsed() < CEILING,
            "the boards were never initialised: {text}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The lab's MoniCAN terminal, redrawn (Ctrl L), once it shows `slios` signed on.
fn lab_terminal(dir: &Path, slios: &[u8]) -> Terminal {
    let mut t = Terminal::open(&dir.join("monican"));
    t.type_keys(b"\x0c");
    t.wait_until("the title and the boards", |t| {
        t.row(TITLE_ROW).contains(TITLE)
            && slios
                .iter()
                .all(|&n| t.row(slio_row_of(n)).starts_with('*'))
    });
    t
}

/// The 4 hex digits of the DIGITAL OUTPUTS column of a SLIO's row, once there.
fn outputs_cell(row: &str) -> Option<&str> {
    row.get(OUTPUTS_COL as usize - 1..OUTPUTS_COL as usize + 3)
}

fn slio_row_of(n: u8) -> u8 {
    slio_row(SlioId::new(n).unwrap())
}

/// The 2 hex digits of the ADC2 column of a SLIO's row.
fn adc2(t: &Terminal, n: u8) -> Option<u8> {
    let row = t.row(slio_row_of(n));
    let cell = row.get(ADC2_COL as usize - 1..ADC2_COL as usize + 1)?;
    u8::from_str_radix(cell, 16).ok()
}

#[test]
fn the_labs_monican_terminal_drives_the_three_boards() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, _) = lab(dir.path(), &["--no-devices"]);
    // Ctrl-L redraws the whole screen for a terminal that connects late.
    let mut t = lab_terminal(dir.path(), &[0, 3, 10]);
    assert!(t.row(HEADER_ROW).contains(HEADER));
    // The other rows stay unknown.
    assert!(
        t.row(slio_row_of(1)).contains("XXXX"),
        "{}",
        t.row(slio_row_of(1))
    );
    // A command lights SLIO 3's LED on P11 (PIN B): DATA_OUTPUT shows 2800 once the SLIO
    // confirmed it (MoniCAN initialised it to 2000, the input switches selected).
    t.type_keys(b"3OB01");
    t.wait_until("the LED's confirmation", |t| {
        // (`get`: a row being redrawn may be shorter for a moment.)
        t.row(slio_row_of(3))
            .get(OUTPUTS_COL as usize - 1..)
            .is_some_and(|cell| cell.starts_with("2800"))
    });
    // The ADC2 column follows the potentiometer (a 0..5 V sine, 10 s a turn): conversions a
    // second apart do not all read the same.
    let adc2_line = |t: &Terminal| {
        let row = t.row(INPUT_LOG_ROW);
        let value = row.trim_end().strip_prefix("ID_slio:3 ADC2:")?.to_string();
        (value.len() == 4 && value.bytes().all(|b| b.is_ascii_hexdigit())).then_some(value)
    };
    // (A reading may be the previous one again: other traffic also changes the last-frame
    // row. Fresh ones differ within a turn of the potentiometer: up to 10 readings 1 s apart.)
    let mut seen: Vec<String> = Vec::new();
    for _ in 0..10 {
        if seen.iter().any(|v| Some(v) != seen.first()) {
            break;
        }
        t.drain();
        let previous_frame = t.row(LAST_FRAME_ROW);
        t.type_keys(b"3I6");
        // The answer is a new frame from SLIO 3, then the log line with its value.
        t.wait_until("an ADC2 conversion", |t| {
            t.row(LAST_FRAME_ROW) != previous_frame
                && adc2_line(t).is_some()
                && adc2(t, 3).is_some()
        });
        seen.push(adc2_line(&t).unwrap());
        std::thread::sleep(Duration::from_secs(1));
    }
    seen.dedup();
    assert!(seen.len() > 1, "the potentiometer did not move: {seen:?}");
    // Shown with `--no-capture`: the screen a user sees, for the record.
    eprintln!(
        "MoniCAN on the lab's terminal:\n{}\nADC2 of SLIO 3, a second apart: {seen:?}",
        t.contents()
    );
}

/// Issue 26 (5): `buslab monican` beside the lab switched off LEDs the user did not touch:
/// the lab's MoniCAN had lit P7 and P11 of SLIO 3, and `3O801` typed in the user's MoniCAN
/// (which never saw SLIO 3 sign on: its outputs column said `XXXX`) wrote DATA_OUTPUT 2100.
/// Now it reads the pin levels first and keeps them: both MoniCANs show 2980.
/// Issue 28 (4): tried as a new user would, `screen DIR/monican 19200` showed a blank screen
/// until Ctrl L: the screen drawn before the terminal came waited in the PTY, and the terminal
/// program threw it away as it started. The terminal now gets the whole screen when it opens
/// the port, and again when it throws away what it had not read.
#[test]
fn a_terminal_opened_late_shows_the_whole_screen_without_ctrl_l() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, url) = lab(dir.path(), &["--no-devices"]);
    // The screen is drawn (to nobody) and the boards initialised before anyone looks.
    wait_for_initialised_boards(&url);
    let mut t = Terminal::open_flushing(&dir.path().join("monican"));
    t.wait_until("the title, the header and the boards, no key typed", |t| {
        t.row(TITLE_ROW).contains(TITLE)
            && t.row(HEADER_ROW).contains(HEADER)
            && [0, 3, 10]
                .iter()
                .all(|&n| t.row(slio_row_of(n)).starts_with('*'))
    });
}

#[test]
fn monican_beside_the_lab_keeps_the_leds_the_lab_lit() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, url) = lab(dir.path(), &["--no-devices"]);
    let mut lab_screen = lab_terminal(dir.path(), &[3]);
    let row = slio_row_of(3);
    lab_screen.wait_until("SLIO 3 initialised", |t| {
        outputs_cell(&t.row(row)) == Some("2000")
    });
    lab_screen.type_keys(b"3O701");
    lab_screen.wait_until("P7 lit", |t| outputs_cell(&t.row(row)) == Some("2080"));
    lab_screen.type_keys(b"3OB01");
    lab_screen.wait_until("P11 lit", |t| outputs_cell(&t.row(row)) == Some("2880"));

    let mut command = Command::new(env!("CARGO_BIN_EXE_buslab"));
    command.args(["-q", "monican", "--bus", &url]);
    let mut user = PtyProgram::spawn(command, 24, 80, Stderr::Inherit);
    user.wait_until("the user's MoniCAN", |s| s.row(HEADER_ROW) == HEADER);
    assert_eq!(user.cells(row, OUTPUTS_COL, 4), "XXXX");
    user.type_keys("3O801");
    user.wait_until("P8 lit, confirmed by SLIO 3", |s| {
        s.cells(row, OUTPUTS_COL, 4) == "2980"
    });
    assert_eq!(user.row(OUTPUT_LOG_ROW), "ID_slio:3 Data_output:2980");
    // The lab's MoniCAN sees the SLIO's answer too: P7 and P11 still lit.
    lab_screen.wait_until("the lab's MoniCAN showing P7, P8, P11", |t| {
        outputs_cell(&t.row(row)) == Some("2980")
    });
    user.type_keys("3I0");
    user.wait_until("the pins read back", |s| {
        s.row(INPUT_LOG_ROW) == "ID_slio:3 Data input:2980"
    });
    user.type_keys("\x11");
    assert!(user.wait_exit().success());
}

/// Issue 26 (7): the loader's report waited for "any key", and Ctrl L counted: a user who
/// opened the terminal after a load and pressed Ctrl L, as docs/loader.md says, never saw it.
#[test]
fn the_loaders_report_survives_ctrl_l_on_a_terminal_opened_after_the_load() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, url) = lab(dir.path(), &["--no-devices"]);
    let record = |kind: u8, address: u32, data: &[u8]| {
        let mut body = vec![(4 + data.len() + 1) as u8];
        body.extend_from_slice(&address.to_be_bytes());
        body.extend_from_slice(data);
        let sum = !body.iter().fold(0u8, |a, b| a.wrapping_add(*b));
        let hex: String = body.iter().map(|b| format!("{b:02X}")).collect();
        format!("S{kind}{hex}{sum:02X}\n")
    };
    let program = dir.path().join("prog.s37");
    let data: Vec<u8> = (0..32).collect();
    std::fs::write(
        &program,
        record(3, 0x32000, &data) + &record(7, 0x32000, &[]),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["load", "--bus", &url])
        .arg(&program)
        .arg("--verify")
        .arg(dir.path().join("ppc.sock"))
        // Loaded, not run: MoniCAN shows the report (a program run owns the terminal).
        .arg("--no-run")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Now the user opens the terminal and redraws it, twice.
    let mut t = Terminal::open(&dir.path().join("monican"));
    for _ in 0..2 {
        t.type_keys(b"\x0c");
        t.wait_for_text("Program loaded: 32 bytes");
        t.wait_for_text(PAGE_HINT);
    }
    // Any other key goes back to the SLIO screen.
    t.type_keys(b" ");
    t.wait_until("the SLIO screen", |t| t.row(TITLE_ROW).contains(TITLE));
}

/// A frame as `buslab dump -L` and buslab's `Frame` print it (`080#0140`, `18FF0010#A5`,
/// `000#R`), from MoniCAN's "Last frame received" row; `None` for a row that is not one.
fn frame_in_row(row: &str) -> Option<String> {
    let rest = row.trim_end().strip_prefix("Last frame received : ")?;
    let tokens: Vec<&str> = rest.split(' ').collect();
    let field = |name: &str| -> Option<u32> {
        let t = tokens.iter().find_map(|t| t.strip_prefix(name))?;
        (t.len() == 2).then(|| u32::from_str_radix(t, 16).ok())?
    };
    let (id, remote) = match field("ID3:") {
        Some(id3) => {
            let id4 = field("ID4:")?;
            let raw = field("ID1:")? << 21 | field("ID2:")? << 13 | id3 << 5 | id4 >> 3;
            (format!("{raw:08X}"), id4 & 4 != 0)
        }
        None => {
            let id2 = field("ID2:")?;
            (
                format!("{:03X}", field("ID1:")? << 3 | id2 >> 5),
                id2 & 0x10 != 0,
            )
        }
    };
    if remote {
        let dlc = rest.split("remote DLC:").nth(1)?;
        return Some(if dlc == "0" {
            format!("{id}#R")
        } else {
            format!("{id}#R{dlc}")
        });
    }
    let data: String = match rest.split_once(" DATA:") {
        Some((_, bytes)) => bytes.split(' ').collect(),
        None => tokens
            .iter()
            .filter(|t| t.starts_with("DATA"))
            .map(|t| t.split_once(':').map_or("", |(_, v)| v))
            .collect(),
    };
    Some(format!("{id}#{data}"))
}

/// Issue 26 (10): the "Last frame received" row showed the identifier of one frame beside the
/// data of another in 2 of 6 captures. The served terminal handed the screen's updates to the
/// pseudo-terminal 8 bytes at a time, so whatever read it between two pieces (a terminal
/// drawing, a capture) showed half an update: 80 % of reads did. Each update now reaches the
/// terminal whole: after every read that emptied the link (shorter than the reader's buffer),
/// the row is a frame that was on the bus.
#[test]
fn the_last_frame_row_shows_only_frames_that_were_on_the_bus() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, url) = lab(dir.path(), &["--no-devices"]);
    // Every frame on the bus, from before the terminal is opened.
    let seen: Arc<Mutex<HashSet<String>>> = Arc::default();
    let mut dump = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["dump", "-L", "--bus", &url])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let lines = BufReader::new(dump.stdout.take().unwrap()).lines();
    let _dump = Lab {
        child: dump,
        log: None,
    };
    let (first_tx, first) = std::sync::mpsc::channel();
    let into = seen.clone();
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            if let Some(frame) = line.split_whitespace().nth(2) {
                into.lock().unwrap().insert(frame.to_string());
                let _ = first_tx.send(());
            }
        }
    });
    first
        .recv_timeout(CEILING)
        .expect("the dump printed nothing");
    let mut t = lab_terminal(dir.path(), &[0, 3, 10]);
    let mut shown = Vec::new();
    while shown.len() < 200 {
        if t.read_chunk() < READ_SIZE {
            shown.push(t.row(LAST_FRAME_ROW));
        }
    }
    let start = Instant::now();
    for row in &shown {
        let frame = frame_in_row(row).unwrap_or_else(|| panic!("not a frame: {row:?}"));
        while !seen.lock().unwrap().contains(&frame) {
            assert!(
                start.elapsed() < CEILING,
                "{row:?} shows {frame}, which was not on the bus"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

#[test]
fn a_row_reads_back_as_the_frame_it_shows() {
    use buslab_monican::app::last_frame_line;
    for text in [
        "080#0140",
        "0C0#0FA0003C00000000",
        "18FF0010#A5",
        "000#R",
        "29D#232980",
    ] {
        let frame: buslab_can::Frame = text.parse().unwrap();
        assert_eq!(
            frame_in_row(&last_frame_line(Some(&frame))).as_deref(),
            Some(text)
        );
    }
}

/// Issue 26 (9): docs/monican.md showed input switches 0, 5 and F that the lab did not set
/// (nothing could). With `buslab slio board` it can: after the switches and the potentiometer
/// are set as the capture says and the commands typed, the lab's terminal shows the capture
/// of docs/monican.md, row for row but row 19 (the last frame: the lab's other nodes send
/// ~220 frames a second).
#[test]
fn the_capture_in_docs_monican_md_is_what_the_lab_shows() {
    let dir = tempfile::tempdir().unwrap();
    let (_lab, url) = lab(dir.path(), &["--no-devices"]);
    let mut t = lab_terminal(dir.path(), &[0, 3, 10]);
    t.wait_until("the boards initialised", |t| {
        [0, 3, 10]
            .iter()
            .all(|&n| outputs_cell(&t.row(slio_row_of(n))) == Some("2000"))
    });
    for args in [
        &["board", "3", "switches", "0101"][..],
        &["board", "A", "switches", "1111"],
        &["board", "3", "pot", "2.5V"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .arg("slio")
            .args(args)
            .args(["--bus", &url])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let inputs = |t: &Terminal, n: u8| {
        let row = t.row(slio_row_of(n));
        row.get(INPUTS_COL as usize - 1..INPUTS_COL as usize + 3)
            .map(str::to_string)
    };
    t.type_keys(b"3I0");
    t.wait_until("SLIO 3's switches", |t| {
        inputs(t, 3).as_deref() == Some("2005")
    });
    t.type_keys(b"AI0");
    t.wait_until("SLIO A's switches", |t| {
        inputs(t, 10).as_deref() == Some("200F")
    });
    t.type_keys(b"3O701");
    t.wait_until("the LED", |t| {
        outputs_cell(&t.row(slio_row_of(3))) == Some("2080")
    });
    t.type_keys(b"3I6");
    t.wait_until("ADC2", |t| adc2(t, 3) == Some(0x80));
    t.wait_until("the command line", |t| {
        t.row(COMMAND_ROW).trim_end() == "Next command > SLIO:3 I/O:I PIN:6 VALUE:__"
    });
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../docs/monican.md"
    ))
    .unwrap();
    let block = doc
        .split_once("<!-- capture: crates/ppc/tests/bench.rs -->\n```text\n")
        .and_then(|(_, rest)| rest.split_once("\n```"))
        .map(|(block, _)| block)
        .expect("the capture in docs/monican.md");
    let screen: Vec<String> = (1..=24).map(|r| t.row(r).trim_end().to_string()).collect();
    for (k, (want, got)) in block.lines().zip(&screen).enumerate() {
        let row = k as u8 + 1;
        if row == LAST_FRAME_ROW {
            assert!(got.starts_with("Last frame received : ID1:"), "{got:?}");
            continue;
        }
        assert_eq!(
            got,
            want,
            "row {row} of the lab's screen differs from docs/monican.md:\n{}",
            screen.join("\n")
        );
    }
    assert_eq!(block.lines().count(), 24);
}
