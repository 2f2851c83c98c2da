//! MoniCAN sans-IO: keys and frames in, frames and VT100 bytes out, the terminal read back by
//! an independent VT100 emulator (the `vt100` crate) at the cells of the seed's Fig. 4.2.

use buslab_can::{Frame, Nanos};
use buslab_monican::app::{LOADER_NOTICE, MAIL_NOTICE, PAGE_HINT};
use buslab_monican::layout::*;
use buslab_monican::mail::{END, HINT, PAGE_TITLE};
use buslab_monican::{Config, Event, MoniCan};
use buslab_slio::SlioId;
use proptest::prelude::*;

const MS: u64 = 1_000_000;

/// Counts the terminal's beeps.
#[derive(Default)]
struct Bells(usize);

impl vt100::Callbacks for Bells {
    fn audible_bell(&mut self, _: &mut vt100::Screen) {
        self.0 += 1;
    }
}

/// The terminal: what MoniCAN's bytes make of a 24 × 80 VT100.
struct Term {
    parser: vt100::Parser<Bells>,
    bytes: usize,
}

impl Term {
    fn new() -> Self {
        Self {
            parser: vt100::Parser::new_with_callbacks(24, 80, 0, Bells::default()),
            bytes: 0,
        }
    }

    /// Feeds what MoniCAN has for the terminal; returns the bytes.
    fn update(&mut self, app: &mut MoniCan) -> Vec<u8> {
        let out = app.take_screen();
        self.bytes += out.len();
        self.parser.process(&out);
        out
    }

    /// Row `row` (1-based), trailing blanks removed.
    fn row(&self, row: u8) -> String {
        let screen = self.parser.screen();
        screen
            .rows(0, 80)
            .nth(usize::from(row) - 1)
            .unwrap_or_default()
            .trim_end()
            .to_string()
    }

    /// `len` characters from (`row`, `col`), 1-based.
    fn cells(&self, row: u8, col: u8, len: u8) -> String {
        let screen = self.parser.screen();
        (0..len)
            .map(|k| {
                screen
                    .cell(u16::from(row) - 1, u16::from(col + k) - 1)
                    .map_or(String::new(), |c| c.contents().to_string())
            })
            .map(|s| if s.is_empty() { " ".to_string() } else { s })
            .collect()
    }

    fn bells(&self) -> usize {
        self.parser.callbacks().0
    }

    /// The cursor, 1-based.
    fn cursor(&self) -> (u8, u8) {
        let (r, c) = self.parser.screen().cursor_position();
        (r as u8 + 1, c as u8 + 1)
    }
}

fn slio(n: u8) -> SlioId {
    SlioId::new(n).unwrap()
}

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

/// MoniCAN at 0 ns with its start-up calibration sent, and its terminal.
fn started() -> (MoniCan, Term) {
    let mut app = MoniCan::new(Config::default(), Nanos::ZERO).unwrap();
    while app.poll_transmit(Nanos::ZERO).is_some() {}
    let mut term = Term::new();
    term.update(&mut app);
    (app, term)
}

/// The frames MoniCAN sends, handed over at `now`.
fn sent(app: &mut MoniCan, now: u64) -> Vec<String> {
    std::iter::from_fn(|| app.poll_transmit(Nanos::new(now)))
        .map(|t| t.frame.to_string())
        .collect()
}

fn keys(app: &mut MoniCan, now: u64, text: &str) {
    for b in text.bytes() {
        app.handle_key(Nanos::new(now), b);
    }
}

/// SLIO 3 signs on (switches 0011 on its ID pins), MoniCAN initialises it, and it confirms.
fn signed_on_slio3(app: &mut MoniCan) {
    app.handle_frame(Nanos::new(MS), &frame("29D#300003"));
    assert_eq!(
        sent(app, MS),
        [
            "29C#043F90",
            "29C#060000",
            "29C#070000",
            "29C#032000",
            "29C#000000"
        ]
    );
    for answer in [
        "29D#243F90",
        "29D#260000",
        "29D#270000",
        "29D#232000",
        "29D#202003",
    ] {
        app.handle_frame(Nanos::new(2 * MS), &frame(answer));
    }
}

#[test]
fn start_up_draws_the_seed_screen_and_calibrates() {
    let mut app = MoniCan::new(Config::default(), Nanos::ZERO).unwrap();
    let calibration: Vec<_> = std::iter::from_fn(|| app.poll_transmit(Nanos::ZERO)).collect();
    assert_eq!(calibration.len(), 48);
    assert!(
        calibration
            .iter()
            .all(|t| t.single_shot && t.frame.to_string() == "0AA#AA04")
    );
    let mut term = Term::new();
    let first = term.update(&mut app);
    assert!(
        first.starts_with(b"\x1b[0m\x1b[H\x1b[2J"),
        "the terminal is cleared"
    );
    assert_eq!(term.row(1), TITLE);
    assert_eq!(term.row(2), HEADER);
    for n in 0..16 {
        assert_eq!(
            term.row(3 + n),
            format!(
                "   {:X} | XXXX            | XXXX           | XX   | XX   | XX   | XX",
                n
            )
        );
    }
    assert_eq!(term.row(19), "Last frame received :");
    assert_eq!(term.row(21), "-".repeat(HEADER.len()));
    assert_eq!(term.row(24), "Next command > SLIO:_ I/O:_ PIN:_ VALUE:__");
    assert_eq!(term.cursor(), (COMMAND_ROW, SLIO_FIELD.1));
    assert!(term.update(&mut app).is_empty(), "nothing changed");
    // The periodic calibration every 5000 bit-times (40 ms at 125 kbit/s).
    assert_eq!(app.next_deadline(), Some(Nanos::new(40 * MS)));
    app.handle_timeout(Nanos::new(40 * MS));
    assert_eq!(sent(&mut app, MS), ["0AA#AA04"]);
}

#[test]
fn a_sign_on_marks_the_slio_and_its_initialisation_shows_once_confirmed() {
    let (mut app, mut term) = started();
    app.handle_frame(Nanos::new(MS), &frame("29D#300003"));
    term.update(&mut app);
    let row = slio_row(slio(3));
    assert_eq!(term.cells(row, MARK_COL, 1), "*");
    // The sign-on's inputs (the ID switches), nothing else confirmed yet.
    assert_eq!(term.cells(row, INPUTS_COL, 4), "0003");
    assert_eq!(term.cells(row, OUTPUTS_COL, 4), "XXXX");
    assert_eq!(term.cells(row, DPM1_COL, 2), "XX");
    assert_eq!(
        sent(&mut app, MS),
        [
            "29C#043F90",
            "29C#060000",
            "29C#070000",
            "29C#032000",
            "29C#000000"
        ]
    );
    for answer in [
        "29D#243F90",
        "29D#260000",
        "29D#270000",
        "29D#232000",
        "29D#202003",
    ] {
        app.handle_frame(Nanos::new(2 * MS), &frame(answer));
    }
    term.update(&mut app);
    assert_eq!(
        term.row(row),
        "*  3 | 2000            | 2003           | XX   | XX   | 00   | 00"
    );
    assert_eq!(
        term.row(LAST_FRAME_ROW),
        "Last frame received : ID1:53 ID2:A0 DATA1:20 DATA2:20 DATA3:03"
    );
    assert_eq!(term.row(INPUT_LOG_ROW), "ID_slio:3 Data input:2003");
    assert_eq!(term.row(OUTPUT_LOG_ROW), "ID_slio:3 Data_output:2000");
    assert_eq!(app.poll_event(), Some(Event::SignedOn(slio(3))));
    assert_eq!(app.present().collect::<Vec<_>>(), [slio(3)]);
}

#[test]
fn a_typed_command_changes_the_screen_only_when_the_slio_answers() {
    let (mut app, mut term) = started();
    signed_on_slio3(&mut app);
    term.update(&mut app);
    let row = slio_row(slio(3));
    keys(&mut app, 3 * MS, "3O7");
    term.update(&mut app);
    assert_eq!(
        term.row(COMMAND_ROW),
        "Next command > SLIO:3 I/O:O PIN:7 VALUE:__"
    );
    assert_eq!(term.cursor(), (COMMAND_ROW, VALUE_FIELD.1));
    keys(&mut app, 3 * MS, "01");
    assert_eq!(sent(&mut app, MS), ["29C#032080"]);
    term.update(&mut app);
    assert_eq!(
        term.row(COMMAND_ROW),
        "Next command > SLIO:3 I/O:O PIN:7 VALUE:01"
    );
    assert_eq!(
        term.cells(row, OUTPUTS_COL, 4),
        "2000",
        "not before the answer"
    );
    // A second LED before the first is confirmed builds on it.
    keys(&mut app, 3 * MS, "3o801");
    assert_eq!(sent(&mut app, MS), ["29C#032180"]);
    app.handle_frame(Nanos::new(4 * MS), &frame("29D#232080"));
    let update = term.update(&mut app);
    assert_eq!(term.cells(row, OUTPUTS_COL, 4), "2080");
    assert!(
        !update.windows(4).any(|w| w == b"\x1b[2J"),
        "an answer updates cells, it does not clear the screen"
    );
    // 2000 -> 2080: one cell, row 6 (SLIO 3) column 10, addressed directly.
    let text = String::from_utf8_lossy(&update);
    assert!(text.starts_with("\x1b[6;10H8\x1b["), "{text:?}");
    assert!(update.len() < 80, "{text:?}");
    app.handle_frame(Nanos::new(5 * MS), &frame("29D#232180"));
    term.update(&mut app);
    assert_eq!(term.cells(row, OUTPUTS_COL, 4), "2180");
    // Switching one off again starts from what the SLIO confirmed.
    keys(&mut app, 6 * MS, "3O700");
    assert_eq!(sent(&mut app, MS), ["29C#032100"]);
}

/// Issue 26 (5): `buslab monican` beside the lab, after `3I0` (`Data input:2880`), sent
/// `3O801` as DATA_OUTPUT `2100`: it built on its sign-on value for a SLIO it never saw sign
/// on, and the lab MoniCAN's LEDs on P7 and P11 went off. The outputs the SLIO told (here the
/// levels DATA_INPUT read back) are kept.
#[test]
fn an_led_command_keeps_the_leds_another_monican_lit() {
    let (mut app, mut term) = started();
    keys(&mut app, MS, "3I0");
    assert_eq!(sent(&mut app, MS), ["29C#000000"]);
    // P13 (the input select), P11 and P7 high: the lab's MoniCAN set them.
    app.handle_frame(Nanos::new(2 * MS), &frame("29D#202880"));
    keys(&mut app, 3 * MS, "3O801");
    assert_eq!(
        sent(&mut app, 3 * MS),
        ["29C#032980"],
        "P8 on, the others kept"
    );
    term.update(&mut app);
    assert_eq!(
        term.cells(slio_row(slio(3)), OUTPUTS_COL, 4),
        "XXXX",
        "shown once the SLIO confirms"
    );
    app.handle_frame(Nanos::new(4 * MS), &frame("29D#232980"));
    term.update(&mut app);
    assert_eq!(term.cells(slio_row(slio(3)), OUTPUTS_COL, 4), "2980");
}

/// An LED command for a SLIO whose outputs MoniCAN never heard of reads them first
/// (DATA_INPUT: outputs read back their levels) and writes once the SLIO answered; commands
/// typed meanwhile join it. It never writes pins it does not know.
#[test]
fn an_led_command_for_unknown_outputs_reads_them_first() {
    let (mut app, _term) = started();
    keys(&mut app, MS, "3O801");
    assert_eq!(sent(&mut app, MS), ["29C#000000"], "a read, no write yet");
    keys(&mut app, MS, "3O901");
    keys(&mut app, MS, "3OB00");
    assert!(sent(&mut app, MS).is_empty(), "one read for all of them");
    // The input switches (P0, P2) and LEDs P7, P11 high.
    app.handle_frame(Nanos::new(2 * MS), &frame("29D#202885"));
    assert_eq!(
        sent(&mut app, 2 * MS),
        ["29C#032380"],
        "P8 and P9 on, P11 off, P7 and P13 kept; input pins not driven"
    );
    // Learned from another host's write too: its DATA_OUTPUT answer.
    let (mut app, _term) = started();
    app.handle_frame(Nanos::new(MS), &frame("29D#233080"));
    keys(&mut app, 2 * MS, "3O700");
    assert_eq!(sent(&mut app, 2 * MS), ["29C#033000"]);
}

#[test]
fn an_led_command_whose_levels_get_no_answer_writes_nothing() {
    let (mut app, mut term) = started();
    keys(&mut app, MS, "5O701");
    assert_eq!(sent(&mut app, MS), ["2AC#000000"]);
    let mut now = MS;
    while now < 100 * MS {
        now = (app.next_deadline().unwrap().max(Nanos::new(now + 1))).get();
        app.handle_timeout(Nanos::new(now));
        for t in std::iter::from_fn(|| app.poll_transmit(Nanos::new(now))) {
            assert_eq!(t.frame.to_string(), "0AA#AA04", "only calibration");
        }
    }
    term.update(&mut app);
    assert_eq!(
        term.row(NOTICE_ROW),
        "SLIO 5 did not answer (pin levels for an LED command)"
    );
    // A late answer does not send the forgotten command.
    app.handle_frame(Nanos::new(now), &frame("2AD#202000"));
    assert!(sent(&mut app, now).is_empty());
}

#[test]
fn conversions_fill_their_adc_column_and_dpm_values_are_scaled() {
    let (mut app, mut term) = started();
    signed_on_slio3(&mut app);
    let row = slio_row(slio(3));
    keys(&mut app, 3 * MS, "3I6");
    assert_eq!(sent(&mut app, MS), ["29C#0500C0"]);
    app.handle_frame(Nanos::new(4 * MS), &frame("29D#280200"));
    keys(&mut app, 5 * MS, "3I5");
    assert_eq!(sent(&mut app, MS), ["29C#0500E0"]);
    term.update(&mut app);
    assert_eq!(term.cells(row, ADC2_COL, 2), "80");
    assert_eq!(term.cells(row, ADC1_COL, 2), "XX", "ADC1 not converted yet");
    app.handle_frame(Nanos::new(6 * MS), &frame("29D#2803FF"));
    keys(&mut app, 7 * MS, "3OA80");
    keys(&mut app, 7 * MS, "3O4FF");
    assert_eq!(sent(&mut app, MS), ["29C#060200", "29C#0703FC"]);
    app.handle_frame(Nanos::new(8 * MS), &frame("29D#260200"));
    app.handle_frame(Nanos::new(8 * MS), &frame("29D#2703FC"));
    term.update(&mut app);
    assert_eq!(term.cells(row, ADC1_COL, 2), "FF");
    assert_eq!(term.cells(row, ADC2_COL, 2), "80");
    assert_eq!(term.cells(row, DPM1_COL, 2), "80");
    assert_eq!(term.cells(row, DPM2_COL, 2), "FF");
    assert_eq!(term.row(INPUT_LOG_ROW), "ID_slio:3 ADC1:03FF");
    assert_eq!(term.row(OUTPUT_LOG_ROW), "ID_slio:3 DPM2:03FC");
    keys(&mut app, 9 * MS, "3I2");
    assert_eq!(sent(&mut app, MS), ["29C#000000"]);
}

#[test]
fn keys_that_do_not_fit_ring_the_bell_and_leave_the_line() {
    let (mut app, mut term) = started();
    keys(&mut app, MS, "G3Z");
    term.update(&mut app);
    assert_eq!(term.bells(), 2);
    assert_eq!(
        term.row(COMMAND_ROW),
        "Next command > SLIO:3 I/O:_ PIN:_ VALUE:__"
    );
    // An arrow key's sequence is swallowed (Escape clears the command), no bell.
    keys(&mut app, MS, "\x1b[A");
    term.update(&mut app);
    assert_eq!(term.bells(), 2);
    assert_eq!(term.row(COMMAND_ROW), blank_command_line());
    keys(&mut app, MS, "3O");
    keys(&mut app, MS, "\x7f");
    term.update(&mut app);
    assert_eq!(
        term.row(COMMAND_ROW),
        "Next command > SLIO:3 I/O:_ PIN:_ VALUE:__"
    );
    // Ctrl R without mail, Enter: bells.
    keys(&mut app, MS, "\x12\r");
    term.update(&mut app);
    assert_eq!(term.bells(), 4);
    assert!(sent(&mut app, MS).is_empty());
}

#[test]
fn an_unanswered_request_is_said_on_the_notice_line() {
    let (mut app, mut term) = started();
    keys(&mut app, MS, "5I0");
    assert_eq!(sent(&mut app, MS), ["2AC#000000"]);
    let deadline = app.next_deadline().unwrap();
    let mut now = MS;
    while now < 100 * MS {
        now = (app.next_deadline().unwrap().max(Nanos::new(now + 1))).get();
        app.handle_timeout(Nanos::new(now));
        while app.poll_transmit(Nanos::new(now)).is_some() {}
    }
    assert!(deadline > Nanos::new(MS));
    term.update(&mut app);
    assert_eq!(term.row(NOTICE_ROW), "SLIO 5 did not answer (inputs)");
    assert_eq!(term.cells(slio_row(slio(5)), INPUTS_COL, 4), "XXXX");
    assert!(std::iter::from_fn(|| app.poll_event()).any(|e| e == Event::NoAnswer(slio(5))));
}

#[test]
fn mail_is_announced_read_with_ctrl_r_and_any_key_goes_back() {
    let (mut app, mut term) = started();
    signed_on_slio3(&mut app);
    app.handle_frame(Nanos::new(3 * MS), &frame("700#01"));
    term.update(&mut app);
    assert_eq!(term.row(NOTICE_ROW), MAIL_NOTICE);
    app.handle_key(Nanos::new(4 * MS), 0x12);
    assert_eq!(sent(&mut app, MS), ["700#R"]);
    let page = term.update(&mut app);
    assert!(
        page.windows(4).any(|w| w == b"\x1b[2J"),
        "the SLIO screen is cleared"
    );
    assert_eq!(term.row(1), PAGE_TITLE);
    assert!(app.reading_mail());
    let text = b"Hello from the supervisor.\nThe bench closes at 6 pm.";
    for f in buslab_can::file::frames(buslab_can::Id::standard(0x700).unwrap(), text) {
        // SLIO frames go on meanwhile; they do not show on this page.
        app.handle_frame(Nanos::new(5 * MS), &frame("29D#232080"));
        app.handle_frame(Nanos::new(5 * MS), &f);
    }
    term.update(&mut app);
    assert_eq!(term.row(3), "Hello from the supervisor.");
    assert_eq!(term.row(4), "The bench closes at 6 pm.");
    assert_eq!(term.row(23), END);
    assert_eq!(term.row(24), HINT);
    app.handle_key(Nanos::new(6 * MS), b'x');
    term.update(&mut app);
    assert!(!app.reading_mail());
    assert_eq!(term.row(1), TITLE);
    assert_eq!(term.row(NOTICE_ROW), "");
    // Redrawn from what is known, including what arrived meanwhile.
    assert_eq!(term.cells(slio_row(slio(3)), OUTPUTS_COL, 4), "2080");
    assert_eq!(
        term.row(COMMAND_ROW),
        blank_command_line(),
        "the key was not a command"
    );
    assert!(std::iter::from_fn(|| app.poll_event()).any(|e| e == Event::MailRequested));
}

#[test]
fn a_remote_frame_on_the_mail_identifier_announces_mail() {
    // Seed §5.4.5: the notifier sends a remote frame with `idmail`; MoniCAN answers with the
    // same remote frame once Ctrl R is pressed.
    let (mut app, mut term) = started();
    app.handle_frame(Nanos::new(3 * MS), &frame("700#R"));
    term.update(&mut app);
    assert_eq!(term.row(NOTICE_ROW), MAIL_NOTICE);
    app.handle_key(Nanos::new(4 * MS), 0x12);
    assert_eq!(sent(&mut app, MS), ["700#R"]);
    // A new announcement while the page is open: the notice comes back once it is left.
    app.handle_frame(Nanos::new(5 * MS), &frame("700#R"));
    app.handle_key(Nanos::new(6 * MS), b' ');
    term.update(&mut app);
    assert_eq!(term.row(NOTICE_ROW), MAIL_NOTICE);
}

#[test]
fn a_page_of_text_stays_until_a_key() {
    let (mut app, mut term) = started();
    term.update(&mut app);
    let lines: Vec<String> = (1..=25).map(|i| format!("line {i}")).collect();
    app.show_page("*** report ***", lines);
    assert!(app.showing_page());
    let page = term.update(&mut app);
    assert!(page.windows(4).any(|w| w == b"\x1b[2J"));
    assert_eq!(term.row(1), "*** report ***");
    assert_eq!(term.row(3), "line 1");
    assert_eq!(term.row(22), "line 20", "what does not fit is cut");
    assert_eq!(term.row(24), PAGE_HINT);
    // MoniCAN goes on underneath: a SLIO's frame is taken in.
    app.handle_frame(Nanos::new(MS), &frame("29D#232080"));
    app.handle_key(Nanos::new(2 * MS), b'3');
    term.update(&mut app);
    assert!(!app.showing_page());
    assert_eq!(term.row(1), TITLE);
    assert_eq!(
        term.row(COMMAND_ROW),
        blank_command_line(),
        "the key only left the page"
    );
}

#[test]
fn the_loader_request_is_announced_and_monican_goes_on() {
    let (mut app, mut term) = started();
    app.handle_frame(Nanos::new(MS), &frame("000#R2"));
    assert_eq!(
        app.poll_event(),
        None,
        "only a remote frame with DLC 0 asks for the loader"
    );
    app.handle_frame(Nanos::new(MS), &frame("000#R"));
    term.update(&mut app);
    assert_eq!(term.row(NOTICE_ROW), LOADER_NOTICE);
    assert_eq!(app.poll_event(), Some(Event::LoaderRequested));
    keys(&mut app, 2 * MS, "3I0");
    assert_eq!(sent(&mut app, MS), ["29C#000000"]);
}

#[test]
fn a_busy_bus_costs_one_screen_update_not_one_per_frame() {
    let (mut app, mut term) = started();
    term.update(&mut app);
    for k in 0..10_000u32 {
        let f = Frame::data(
            buslab_can::Id::standard((k % 0x700) as u16).unwrap(),
            &k.to_be_bytes(),
        )
        .unwrap();
        app.handle_frame(Nanos::new(MS + u64::from(k)), &f);
    }
    let update = term.update(&mut app);
    assert!(update.len() < 200, "{} bytes", update.len());
    assert_eq!(
        term.row(LAST_FRAME_ROW),
        "Last frame received : ID1:81 ID2:E0 DATA1:00 DATA2:00 DATA3:27 DATA4:0F"
    );
}

/// Issue 26 (7): the loader's report waited for "any key", and Ctrl L counted: a user who
/// connected after a load and pressed Ctrl L, as docs/loader.md says, never saw it.
#[test]
fn ctrl_l_redraws_the_loaders_report_and_keeps_it() {
    let (mut app, mut term) = started();
    app.show_page(
        "*** CAN loader (loadcan) ***",
        vec!["Program loaded: 2048 bytes".to_string()],
    );
    app.take_screen(); // drawn for nobody: the terminal connects later
    let mut late = Term::new();
    app.handle_key(Nanos::new(MS), 0x0C);
    let all = late.update(&mut app);
    assert!(all.starts_with(b"\x1b[0m\x1b[H\x1b[2J"), "redrawn whole");
    assert!(app.showing_page());
    assert_eq!(late.row(1), "*** CAN loader (loadcan) ***");
    assert_eq!(late.row(3), "Program loaded: 2048 bytes");
    assert_eq!(late.row(24), PAGE_HINT);
    // Any other key goes back.
    app.handle_key(Nanos::new(2 * MS), b' ');
    late.update(&mut app);
    assert_eq!(late.row(1), TITLE);
    // The mail page too: Ctrl L redraws it.
    app.handle_frame(Nanos::new(3 * MS), &frame("700#01"));
    app.handle_key(Nanos::new(3 * MS), 0x12);
    assert!(app.reading_mail());
    app.handle_key(Nanos::new(4 * MS), 0x0C);
    assert!(app.reading_mail());
    term.update(&mut app);
    assert_eq!(term.row(1), PAGE_TITLE);
}

#[test]
fn ctrl_l_redraws_everything() {
    let (mut app, mut term) = started();
    app.handle_key(Nanos::new(MS), 0x0C);
    let all = term.update(&mut app);
    assert!(all.starts_with(b"\x1b[0m\x1b[H\x1b[2J"));
    assert_eq!(term.row(2), HEADER);
    assert_eq!(term.bells(), 0);
}

proptest! {
    /// Whatever the terminal sends, MoniCAN neither panics nor leaves its screen: the
    /// command line is always there, and no frame goes out that is not a SLIO command.
    #[test]
    fn garbage_keys_keep_the_screen(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let (mut app, mut term) = started();
        for (k, b) in bytes.iter().enumerate() {
            app.handle_key(Nanos::new(k as u64 * MS), *b);
            if k % 16 == 0 {
                term.update(&mut app);
            }
        }
        // Leave a mail page or an escape sequence, then look.
        app.handle_key(Nanos::new(1000 * MS), b'\x1b');
        app.handle_key(Nanos::new(1000 * MS), b'\x1b');
        term.update(&mut app);
        prop_assert!(term.row(COMMAND_ROW).starts_with("Next command > SLIO:"));
        prop_assert_eq!(term.row(HEADER_ROW), HEADER);
        for t in std::iter::from_fn(|| app.poll_transmit(Nanos::new(1000 * MS))) {
            // A second without a look at the clock reads as a host that did not run: the
            // SLIOs are calibrated again first.
            if t.frame == buslab_slio::calibration_frame() {
                continue;
            }
            prop_assert!(SlioId::from_id(t.frame.id()).is_some(), "{}", t.frame);
            // Every frame to a SLIO has 3 bytes (seed §2.1.2.1).
            prop_assert!(!t.frame.is_remote() && t.frame.payload().len() == 3, "{}", t.frame);
        }
    }

    /// Whatever frames arrive, MoniCAN neither panics nor shows a value no SLIO sent with a
    /// register frame of the right shape.
    #[test]
    fn garbage_frames_show_nothing_unconfirmed(
        frames in proptest::collection::vec(
            (0u32..0x2000_0000, any::<bool>(), any::<bool>(), proptest::collection::vec(any::<u8>(), 0..=8)),
            0..100,
        )
    ) {
        let (mut app, mut term) = started();
        for (k, (raw, extended, remote, data)) in frames.iter().enumerate() {
            let id = if *extended {
                buslab_can::Id::extended(*raw).unwrap()
            } else {
                buslab_can::Id::standard((*raw & 0x7FF) as u16).unwrap()
            };
            let f = if *remote {
                Frame::remote(id, data.len() as u8).unwrap()
            } else {
                Frame::data(id, data).unwrap()
            };
            app.handle_frame(Nanos::new(k as u64 * MS), &f);
        }
        term.update(&mut app);
        prop_assert_eq!(term.row(TITLE_ROW), TITLE);
        for n in 0..16 {
            let s = slio(n);
            let shown = term.cells(slio_row(s), OUTPUTS_COL, 4);
            let confirmed = app.master().known(s).and_then(|k| k.registers[3]);
            match confirmed {
                Some(v) => prop_assert_eq!(shown, format!("{v:04X}")),
                None => prop_assert_eq!(shown, "XXXX"),
            }
        }
    }
}
