//! `buslab lab` carries the seed's SLIO bench: three demo boards and the PowerPC node running
//! MoniCAN, whose VT100 terminal the lab serves as DIR/monican. The test is the user at that
//! terminal: it opens the link at 19200 8N1 and reads the screen back with an independent
//! VT100 emulator (the `vt100` crate).

#[path = "support/vt100_terminal.rs"]
mod vt100_terminal;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use buslab_monican::layout::*;
use buslab_slio::SlioId;
use vt100_terminal::{CEILING, Terminal};

/// The lab, stopped (SIGTERM) when the test ends.
struct Lab(Child);

impl Drop for Lab {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .status();
        let _ = self.0.wait();
    }
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
    let _lab = Lab(Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "lab",
            "-q",
            "--no-devices",
            "--listen",
            "127.0.0.1:0",
            "--dir",
        ])
        .arg(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap());
    let link = dir.path().join("monican");
    let start = Instant::now();
    while !link.exists() {
        assert!(
            start.elapsed() < CEILING,
            "the lab never linked {}",
            link.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut t = Terminal::open(&link);
    // Ctrl-L redraws the whole screen for a terminal that connects late.
    t.type_keys(b"\x0c");
    t.wait_until("the title and the three boards", |t| {
        t.row(TITLE_ROW).contains(TITLE)
            && [0, 3, 10]
                .iter()
                .all(|&n| t.row(slio_row_of(n)).starts_with('*'))
    });
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
