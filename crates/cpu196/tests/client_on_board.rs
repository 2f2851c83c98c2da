//! The host client and the monitor session against the board model, in virtual time: every
//! exchange with the line's exact timing, as fast as the CPU allows, no PTY, no clock.

use std::time::Duration;

use buslab_cpu196::adconfig::{AdConfigError, AdRefusal};
use buslab_cpu196::codes::{Alert, MsgCode};
use buslab_cpu196::host::{Client, ClientError, CsvSamples, FileRequests, LOST_AFTER, Monitor};
use buslab_cpu196::message::*;
use buslab_cpu196::source::Inputs;
use buslab_cpu196::{Board, Image, SimPort};
use buslab_device::{LineSettings, Nanos};

const BAUD: u32 = 115_200;

fn board() -> Board {
    Board::new(Image::default(), Inputs::default(), Nanos::ZERO)
}

fn client_on(board: Board) -> Client<SimPort<Board>> {
    let line = board.line();
    let mut c = Client::new(SimPort::new(board, line, Nanos::ZERO), line.baud);
    // The boot report.
    assert_eq!(
        c.next(Duration::from_millis(10)).unwrap(),
        Some(Message::Power(Power::WasReset))
    );
    c
}

fn client() -> Client<SimPort<Board>> {
    client_on(board())
}

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[test]
fn info_names_the_board() {
    let mut c = client();
    let info = c.info().unwrap();
    assert_eq!(&info.serial, b"BL196001");
    let shown = info.to_string();
    assert!(shown.contains("serial number   BL196001"), "{shown}");
    assert!(shown.contains("quartz          20 MHz"), "{shown}");
    assert!(shown.contains("supply          7.0 V"), "{shown}");
}

#[test]
fn a_flash_bank_written_block_by_block_reads_back_identical() {
    let mut c = client();
    let mut bank = vec![0xFFu8; 65536];
    for (i, x) in bank[0x6000..0x7000].iter_mut().enumerate() {
        *x = (i * 31 % 251) as u8;
    }
    bank[0x2A00..0x2B00].fill(0x11);
    let blocks = buslab_cpu196::values::flash_blocks_to_write(&bank).unwrap();
    assert_eq!(blocks.len(), 17);
    let t0 = c.now();
    for &b in &blocks {
        let block: [u8; 256] = bank[b as usize * 256..][..256].try_into().unwrap();
        c.flash_write(3, b, &block).unwrap();
    }
    let mut progress = 0;
    let back = c.flash_read_bank(3, &mut |n| progress = n).unwrap();
    assert_eq!(back, bank);
    assert_eq!(progress, 65536);
    // Virtual time, so this is a property of the protocol: each written block crosses the
    // line twice, one exchange after the other (write, `msg_completed`, read request, data);
    // the bank read is pipelined, its requests cross while the board sends, so the line
    // carries the 256 blocks back to back.
    let byte = LineSettings::n81(BAUD).byte_time();
    let line_ns = (17 * (262 + 3 + 4 + 259) + 256 * 259) as u64 * byte;
    let took = Nanos::from(c.now() - t0);
    assert!(
        took >= line_ns && took < line_ns + line_ns / 100,
        "{took} vs {line_ns}"
    );
    assert!(matches!(
        c.flash_write(3, 0x60, &[0; 256]),
        Err(ClientError::Board(MsgCode::NOT_BLANK_ERROR))
    ));
    c.flash_erase(3).unwrap();
    assert_eq!(*c.flash_read(3, 0x60).unwrap(), [0xFF; 256]);
    assert_eq!(
        c.port().device().image().flash.read(3, 0x2A).unwrap(),
        &[0xFF; 256]
    );
}

#[test]
fn a_pic_block_write_is_acknowledged_per_256_bytes_and_reads_back() {
    let mut c = client();
    let data: [u8; 4096] = core::array::from_fn(|i| (i * 7 / 3) as u8);
    let mut acks = Vec::new();
    c.pic_write(2, &data, &mut |n| acks.push(n)).unwrap();
    assert_eq!(acks, (1..=16).map(|i| i * 256).collect::<Vec<_>>());
    assert_eq!(*c.pic_read(2).unwrap(), data);
    assert!(matches!(
        c.pic_read(0),
        Err(ClientError::Board(MsgCode::INVALID_PARAMETER_VALUE))
    ));
    c.eeprom_write(&[0x42; 256]).unwrap();
    assert_eq!(*c.eeprom_read().unwrap(), [0x42; 256]);
}

#[test]
fn an_idle_board_sends_its_watchdog_every_second() {
    let mut c = client();
    let t0 = c.now();
    assert_eq!(c.next(ms(1500)).unwrap(), Some(Message::Watchdog));
    let at = c.now() - t0;
    assert!(at >= ms(990) && at <= ms(1010), "{at:?}");
    // Answering pings is what `sync` relies on.
    c.sync().unwrap();
}

#[test]
fn a_powered_down_board_is_lost_and_the_monitor_says_so_then_sees_it_back() {
    let mut c = client();
    c.power_down().unwrap();
    c.timeout = ms(500);
    let err = c.info().unwrap_err();
    assert!(matches!(err, ClientError::Lost { .. }), "{err}");
    let text = err.to_string();
    assert!(text.contains("board lost?"), "{text}");
    assert!(text.contains("115200 8N1"), "{text}");

    let mut monitor = Monitor::<CsvSamples<Vec<u8>>>::new(None, None, c.now());
    let mut out = String::new();
    let t0 = c.now();
    while !monitor.board_lost() {
        assert!(c.now() - t0 < ms(10_000), "never reported lost: {out}");
        monitor.turn(&mut c, ms(50), &mut out).unwrap();
    }
    let after = c.now() - t0;
    assert!(
        after > LOST_AFTER && after < LOST_AFTER + ms(200),
        "{after:?}"
    );
    assert_eq!(out, "board lost: nothing heard for 3.00 s\n");
    // The power button: the board boots and reports.
    let now = c.port().now_ns();
    c.port().device_mut().power_button(now);
    out.clear();
    while monitor.board_lost() {
        monitor.turn(&mut c, ms(50), &mut out).unwrap();
    }
    assert_eq!(out, "board is back\nPOWER: WasReset\n");
}

#[test]
fn the_monitor_keeps_a_run_alive_and_a_silent_pc_loses_it() {
    // The watchdog is on in the default image: a run stops after 3 s without a byte.
    let mut c = client();
    c.start(Start::run(0, 0, true)).unwrap();
    let mut seen_link_lost = false;
    let t0 = c.now();
    while c.now() - t0 < ms(4000) {
        if let Some(Message::Alert(Alert::LINK_LOST)) = c.next(ms(100)).unwrap() {
            seen_link_lost = true;
            break;
        }
    }
    assert!(seen_link_lost, "no alert_link_lost from a silent PC");
    let at = c.now() - t0;
    assert!(at >= ms(3000) && at < ms(3100), "{at:?}");

    // The monitor pings every 500 ms: ten seconds of streaming, no alert.
    let mut c = client();
    let mut monitor = Monitor::<CsvSamples<Vec<u8>>>::new(None, None, c.now());
    let mut out = String::new();
    monitor.start(&mut c, Start::run(0, 0, true)).unwrap();
    let t0 = c.now();
    while c.now() - t0 < ms(10_000) {
        monitor.turn(&mut c, ms(50), &mut out).unwrap();
    }
    assert!(!out.contains("ALERT"), "{out}");
    assert!(!monitor.board_lost());
    monitor.stop(&mut c, &mut out).unwrap();
}

#[test]
fn a_refused_acquisition_says_why_and_the_monitor_starts_such_a_set_without_it() {
    let mut c = client();
    // Set 4 (the pulse train) has no 80C196 A/D sequence.
    let err = c.start(Start::run(0, 4, true)).unwrap_err();
    assert!(
        matches!(
            err,
            ClientError::AdConfig {
                bank: 0,
                config: 4,
                why: Some(AdRefusal::Config(AdConfigError::EmptySequence(_)))
            }
        ),
        "{err:?}"
    );
    assert!(
        err.to_string().starts_with(
            "the board answered msg_ad_config_error: the conversion sequence is empty"
        ),
        "{err}"
    );
    let mut monitor = Monitor::<CsvSamples<Vec<u8>>>::new(None, None, c.now());
    let mut out = String::new();
    let started = monitor.start(&mut c, Start::run(0, 4, true)).unwrap();
    assert_eq!(started, Start::run(0, 4, false));
    let t0 = c.now();
    while !out.contains("pulse-train: 10 pulses") {
        assert!(c.now() - t0 < ms(2000), "{out}");
        monitor.turn(&mut c, ms(50), &mut out).unwrap();
    }
}

#[test]
fn a_client_at_the_wrong_rate_gets_no_answer_and_a_hint() {
    let b = board();
    let line = b.line();
    let port = SimPort::new(b, line, Nanos::ZERO).with_client_line(LineSettings::n81(9600));
    let mut c = Client::new(port, 9600);
    c.timeout = ms(300);
    let err = c.info().unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, ClientError::Lost { .. }), "{text}");
    assert!(
        text.contains("is it switched on, and at 9600 8N1 like this client?"),
        "{text}"
    );
}

/// Files kept in memory: what the board wrote, by name.
#[derive(Default)]
struct MemoryFiles {
    open: Vec<(u8, String)>,
    written: std::collections::BTreeMap<String, Vec<u8>>,
}

impl FileRequests for MemoryFiles {
    fn handle(&mut self, request: &Thread) -> (Vec<Message>, Option<String>) {
        match request {
            Thread::Open { name, file, .. } => {
                let name = String::from_utf8_lossy(name).into_owned();
                self.open.push((*file, name.clone()));
                self.written.entry(name).or_default();
                (
                    vec![Message::Msg(MsgCode::NO_ERROR)],
                    Some(format!("opened {file}")),
                )
            }
            Thread::Write { data, file } => {
                let name = &self.open.iter().find(|(f, _)| f == file).unwrap().1;
                self.written.get_mut(name).unwrap().extend_from_slice(data);
                (Vec::new(), None)
            }
            _ => (Vec::new(), None),
        }
    }
}

#[test]
fn the_monitor_serves_the_loggers_file_and_shows_its_text() {
    let mut c = client();
    let files = std::rc::Rc::new(std::cell::RefCell::new(MemoryFiles::default()));
    struct Shared(std::rc::Rc<std::cell::RefCell<MemoryFiles>>);
    impl FileRequests for Shared {
        fn handle(&mut self, request: &Thread) -> (Vec<Message>, Option<String>) {
            self.0.borrow_mut().handle(request)
        }
    }
    let mut monitor =
        Monitor::<CsvSamples<Vec<u8>>>::new(Some(Box::new(Shared(files.clone()))), None, c.now());
    let mut out = String::new();
    monitor.start(&mut c, Start::run(0, 1, true)).unwrap();
    let t0 = c.now();
    while c.now() - t0 < ms(1000) {
        monitor.turn(&mut c, ms(50), &mut out).unwrap();
    }
    monitor.stop(&mut c, &mut out).unwrap();
    assert!(out.contains("THREAD: logger: writing ad.csv\n"), "{out}");
    assert!(out.contains("FILE: opened "), "{out}");
    let csv = String::from_utf8(files.borrow().written["ad.csv"].clone()).unwrap();
    assert!(csv.starts_with("ms,ch0,ch1\n"), "{csv}");
    let lines = csv.lines().count() - 1;
    assert!(lines >= 1, "{csv}");
    assert!(
        out.contains(&format!(
            "THREAD: logger: done, lines written: {lines}\nTHREAD: {lines:04X}\n"
        )),
        "{out}"
    );
}

/// The board's port, with the host away (descheduled on a loaded machine) for `stall` just
/// before its `stall_at`-th write.
struct StallBeforeSend {
    inner: SimPort<Board>,
    sends: usize,
    stall_at: usize,
    stall: Duration,
    /// What the board sent before a discard still comes after it (a host that got to the
    /// line late, on a loaded machine).
    late_input: bool,
}

impl buslab_device::Port for StallBeforeSend {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.sends += 1;
        if self.sends == self.stall_at {
            self.inner.pause(self.stall);
        }
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.inner.recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        self.inner.now()
    }
    fn pause(&mut self, d: Duration) {
        self.inner.pause(d)
    }
    fn drain(&mut self) -> std::io::Result<()> {
        self.inner.drain()
    }
    fn discard_input(&mut self) -> std::io::Result<()> {
        if self.late_input {
            return Ok(());
        }
        self.inner.discard_input()
    }
}

#[test]
fn a_host_stall_inside_a_pic_block_write_times_out_and_the_block_is_written_again() {
    // The stress run's failure: the host was away for more than the board's 200 ms between
    // two chunks of a PIC block (after the first acknowledgement), the board answered
    // msg_time_out, and the rest of the block arrived as garbage.
    let b = board();
    let line = b.line();
    let port = StallBeforeSend {
        inner: SimPort::new(b, line, Nanos::ZERO),
        sends: 0,
        // The head with the first chunk, then the second chunk: the host stalls before it.
        stall_at: 2,
        stall: ms(300),
        late_input: false,
    };
    let mut c = Client::new(port, line.baud);
    assert_eq!(
        c.next(ms(10)).unwrap(),
        Some(Message::Power(Power::WasReset))
    );
    let data: [u8; 4096] = core::array::from_fn(|i| (i * 7 / 5) as u8);
    let mut acks = Vec::new();
    c.pic_write(2, &data, &mut |n| acks.push(n)).unwrap();
    assert_eq!(acks, (1..=16).map(|k| k * 256).collect::<Vec<_>>());
    assert_eq!(*c.pic_read(2).unwrap(), data);
    assert!(
        c.port().sends > 20,
        "written once only: {} writes",
        c.port().sends
    );
}

#[test]
fn the_garbage_a_stall_made_of_a_pic_block_is_answered_late_and_the_block_still_goes_through() {
    // The stress run's second failure: after the stall, the board's answers to the rest of the
    // block (msg_reception_error, read as garbage frames) reached the host after it had
    // discarded its input, and the resync took them for the answer to its watchdog.
    let b = board();
    let line = b.line();
    let port = StallBeforeSend {
        inner: SimPort::new(b, line, Nanos::ZERO),
        sends: 0,
        stall_at: 2,
        stall: ms(300),
        late_input: true,
    };
    let mut c = Client::new(port, line.baud);
    assert_eq!(
        c.next(ms(10)).unwrap(),
        Some(Message::Power(Power::WasReset))
    );
    let data: [u8; 4096] = core::array::from_fn(|i| (i * 3) as u8);
    let mut acks = Vec::new();
    c.pic_write(3, &data, &mut |n| acks.push(n)).unwrap();
    assert_eq!(acks, (1..=16).map(|k| k * 256).collect::<Vec<_>>());
    assert_eq!(*c.pic_read(3).unwrap(), data);
}
