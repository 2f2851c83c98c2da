//! Every command through the host client against the model, in virtual time.

use buslab_device::Nanos;
use buslab_zelle::analog::{Source, SourceSpec};
use buslab_zelle::client::{Client, Error, Port, Progress, SeriesParams, Transfer};
use buslab_zelle::timing::MS;
use buslab_zelle::{Activity, Cell, Mode, SimPort};
use std::time::Duration;

fn client() -> Client<SimPort<Cell>> {
    let mut c = Client::new(Cell::default().into_sim_port());
    c.reset().unwrap();
    c
}

fn source(spec: &str) -> Source {
    match SourceSpec::parse(spec).unwrap() {
        SourceSpec::Ready(s) => s,
        other => panic!("{other:?}"),
    }
}

#[test]
fn analog_reads_follow_the_inputs() {
    let mut c = client();
    let cell = c.port().device_mut();
    cell.set_analog(1, source("1V")).unwrap();
    cell.set_analog(4, source("5V")).unwrap();
    assert_eq!(c.analog(1).unwrap(), 51);
    assert_eq!(c.analog(4).unwrap(), 255);
    assert_eq!(c.analog(2).unwrap(), 0);
    assert_eq!(c.analog_repeat(&[4, 1, 1, 2]).unwrap(), [255, 51, 51, 0]);
    // Still in the ready state afterwards.
    assert!(!c.key_pressed().unwrap());
    assert!(matches!(c.analog(5), Err(Error::Channel(5))));
    assert!(matches!(c.analog(0), Err(Error::Channel(0))));
}

#[test]
fn port1_is_quasi_bidirectional() {
    let mut c = client();
    assert_eq!(c.read_port1().unwrap(), 0xFF, "all high after power-on");
    c.write_port1(0x5E).unwrap(); // LED on (bit 0 low), bits 5 and 7 low
    assert_eq!(c.read_port1().unwrap(), 0x5E);
    assert!(c.port().device().led_on());
    // An outside circuit pulls bits 4 and 5 low: only bit 4 changes, bit 5 was low already.
    c.port().device_mut().set_port1_pulled_low(0x30);
    assert_eq!(c.read_port1().unwrap(), 0x4E);
    // An analog reading leaves bits 0..3 high, the upper four as they were.
    c.analog(1).unwrap();
    assert_eq!(c.port().device().port1_latch(), 0x5F);
    assert!(!c.port().device().led_on());
}

#[test]
fn p26_key_registers_bus_and_ram() {
    let mut c = client();
    assert!(c.read_p26().unwrap());
    c.write_p26(false).unwrap();
    assert!(!c.read_p26().unwrap());
    c.write_p26(true).unwrap();
    c.port().device_mut().set_p26_pulled_low(true);
    assert!(!c.read_p26().unwrap(), "an input pulled low reads low");

    let now = c.port().now_ns();
    c.port().device_mut().key_down(now);
    assert!(c.key_pressed().unwrap());
    let now = c.port().now_ns();
    c.port().device_mut().key_up(now);
    assert!(!c.key_pressed().unwrap());

    c.write_register(0x30, 0xA5).unwrap();
    assert_eq!(c.read_register(0x30).unwrap(), 0xA5);
    assert!(matches!(
        c.write_register(128, 0),
        Err(Error::Register(128))
    ));
    // 80h..FFh read as special function registers: SP inside a command.
    assert_eq!(c.read_register(0x81).unwrap(), 0x09);

    c.bus_write(5, 0x42).unwrap();
    assert_eq!(c.port().device().bus(5), Some(0x42));
    c.port().device_mut().set_bus(6, 0x17).unwrap();
    assert_eq!(c.bus_read(6).unwrap(), 0x17);
    assert!(matches!(c.bus_write(128, 0), Err(Error::BusAddress(128))));

    c.poke(0x1234, 0x99).unwrap();
    assert_eq!(c.peek(0x1234).unwrap(), 0x99);
    assert_eq!(c.peek(0x8000).unwrap(), 0xFF, "nothing above the RAM");
}

#[test]
fn data_ram_round_trips_in_both_transfer_modes() {
    for mode in [Transfer::Pipelined, Transfer::StopAndWait] {
        let mut c = client();
        let data: Vec<u8> = (0..300u32).map(|i| (i * 7 + 3) as u8).collect();
        c.write_data(&data, mode).unwrap();
        assert_eq!(c.read_data(data.len(), mode).unwrap(), data, "{mode:?}");
        assert_eq!(c.peek(0x0800 + 299).unwrap(), data[299]);
        let stats = c.port().device().stats();
        assert_eq!(stats.lost_overrun + stats.lost_in_setup, 0, "{mode:?}");
    }
}

#[test]
fn pipelined_dump_runs_at_line_rate() {
    let mut c = client();
    let t0 = c.port().now_ns();
    c.read_data(1000, Transfer::Pipelined).unwrap();
    let pipelined = c.port().now_ns() - t0;
    let t0 = c.port().now_ns();
    c.read_data(1000, Transfer::StopAndWait).unwrap();
    let stop_and_wait = c.port().now_ns() - t0;
    let line = 1000 * buslab_zelle::timing::BYTE_NS;
    // The host's pause after command 2, before the first request.
    let setup = Nanos::from(buslab_zelle::client::SETUP_PAUSE);
    // Virtual time, so these are exact properties of the protocol, not of the machine.
    assert!(
        pipelined < setup + line + line / 50,
        "{pipelined} vs {line}"
    );
    assert!(stop_and_wait > 2 * line - line / 50, "{stop_and_wait}");
}

#[test]
fn program_load_arms_program_mode_and_runs_after_reset() {
    let mut c = client();
    c.load_program(&[0x74, 0x01, 0x80, 0xFE], Transfer::Pipelined)
        .unwrap();
    assert_eq!(c.peek(0x0402).unwrap(), 0x80);
    assert_eq!(c.port().device().mode(), Mode::Program);
    assert_eq!(
        c.port().device().activity(),
        Activity::Ready,
        "6 starts it, not 5"
    );
    let now = c.port().now_ns();
    c.port().device_mut().reset(now);
    assert_eq!(c.port().device().activity(), Activity::ProgramRunning);
    c.reset().unwrap();
    assert_eq!(c.port().device().mode(), Mode::Ready);
    c.run_program().unwrap();
    c.port().pause(Duration::from_millis(5));
    assert_eq!(c.port().device().activity(), Activity::ProgramRunning);
    c.interrupt().unwrap();
    assert_eq!(c.port().device().activity(), Activity::Ready);
}

#[test]
fn a_program_deaf_to_the_line_fails_the_reset_naming_the_start_key() {
    let mut c = client();
    // CLR EA; SJMP $: "Inter" can no longer run.
    c.load_program(&[0xC2, 0xAF, 0x80, 0xFE], Transfer::Pipelined)
        .unwrap();
    c.run_program().unwrap();
    let err = c.reset().unwrap_err();
    assert!(matches!(err, Error::ResetUnanswered { .. }), "{err:?}");
    assert!(err.to_string().contains("START key about 5 s"), "{err}");
    // The seed's way out: START held about 5 s after a RESET.
    let now = c.port().now_ns();
    c.port().device_mut().key_down(now);
    c.port().device_mut().reset(now);
    c.port().pause(Duration::from_millis(5_200));
    let now = c.port().now_ns();
    c.port().device_mut().key_up(now);
    c.reset().unwrap();
    assert_eq!(c.port().device().mode(), Mode::Ready);
}

#[test]
fn measure_produces_a_sine_on_two_channels() {
    let mut c = client();
    c.port()
        .device_mut()
        .set_analog(1, source("sine:5Hz:2V:2.5V"))
        .unwrap();
    c.port().device_mut().set_analog(2, source("3V")).unwrap();
    let params = SeriesParams::new(&[1, 2], 100, 10).unwrap();
    let mut progressed = 0;
    let m = c
        .measure(&params, 2, |p| {
            if matches!(p, Progress::Measuring { .. }) {
                progressed += 1
            }
        })
        .unwrap();
    assert!(progressed > 0);
    assert_eq!(m.channels, [1, 2]);
    assert_eq!(m.rows.len(), 200);
    // A 5 Hz sine sampled every 10 ms: 20 samples a period, spanning 2.5 V ± 2 V.
    let ch1: Vec<u8> = m.rows.iter().map(|r| r.values[0]).collect();
    let max = *ch1.iter().max().unwrap();
    let min = *ch1.iter().min().unwrap();
    assert!(max >= 225 && min <= 30, "{min}..{max}");
    for (a, b) in ch1.iter().zip(&ch1[20..100]) {
        assert!(a.abs_diff(*b) <= 1, "one period later the same value");
    }
    assert!(m.rows.iter().all(|r| r.values[1] == 153));
    assert_eq!(m.rows[1].time_ns - m.rows[0].time_ns, 10 * MS);
    // The cell is left ready.
    assert_eq!(c.port().device().mode(), Mode::Ready);
}

#[test]
fn timeouts_are_errors_naming_what_was_awaited() {
    let mut c = client();
    let now = c.port().now_ns();
    c.port().device_mut().power_off(now);
    let err = c.peek(0x0800).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Timeout {
                got: 0,
                wanted: 1,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("reading a RAM address"), "{err}");
    let err = c.read_data(10, Transfer::Pipelined).unwrap_err();
    assert!(err.to_string().contains("reading data RAM"), "{err}");
}

#[test]
fn transfers_past_the_end_of_ram_are_refused_naming_the_sizes() {
    let mut c = client();
    let err = c
        .write_data(&vec![0; 0x7801], Transfer::Pipelined)
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "30721 bytes from 0800h do not fit below the end of RAM at 8000h"
    );
    assert!(matches!(
        c.read_data(0x7801, Transfer::Pipelined),
        Err(Error::TooLong { .. })
    ));
    // Nothing went on the line: the cell still answers.
    assert!(!c.key_pressed().unwrap());
}

/// Takes the first `room` bytes written, then fails every write.
struct FillingPort {
    room: usize,
    now: Duration,
}

impl Port for FillingPort {
    fn send(&mut self, buf: &[u8]) -> std::io::Result<()> {
        if self.room < buf.len() {
            return Err(std::io::ErrorKind::BrokenPipe.into());
        }
        self.room -= buf.len();
        Ok(())
    }
    fn recv(&mut self, _: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.now += timeout;
        Ok(0)
    }
    fn now(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, d: Duration) {
        self.now += d;
    }
    fn drain(&mut self) -> std::io::Result<()> {
        Ok(())
    }
    fn discard_input(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn the_longest_series_times_the_most_blocks_does_not_overflow() {
    // 65535 cycles of 65.539 s, u32::MAX blocks: the total time overflows u64 nanoseconds.
    let params = SeriesParams::new(&[1, 2, 3, 4], u16::MAX, 65_539).unwrap();
    // The series is armed (9 bytes), then the first START fails: an error, not a panic.
    let mut c = Client::new(FillingPort {
        room: 9,
        now: Duration::ZERO,
    });
    let err = c.measure(&params, u32::MAX, |_| {}).unwrap_err();
    assert!(matches!(err, Error::Io(_)), "{err}");
}

/// A host whose START reaches the cell `late` (a busy PTY server or USB adapter) while its
/// later bytes are on time: the cell's block starts and ends `late` after the host thinks.
struct LateStart<P> {
    inner: P,
    late: Duration,
    owed: Duration,
}

impl<P: Port> Port for LateStart<P> {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        if bytes == [9] {
            self.inner.pause(self.late);
            self.owed += self.late;
        }
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.inner.recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        self.inner.now()
    }
    fn pause(&mut self, duration: Duration) {
        let cut = self.owed.min(duration);
        self.owed -= cut;
        self.inner.pause(duration - cut);
    }
    fn drain(&mut self) -> std::io::Result<()> {
        self.inner.drain()
    }
    fn discard_input(&mut self) -> std::io::Result<()> {
        self.inner.discard_input()
    }
}

#[test]
fn a_block_cut_short_by_a_late_start_is_counted_not_hidden() {
    let params = SeriesParams::new(&[1], 50, 2).unwrap();
    let late = Duration::from_millis(30);
    let run = |margin: Duration| {
        let mut cell = Cell::default().into_sim_port();
        Client::new(&mut cell).reset().unwrap();
        let mut c = Client::new(LateStart {
            inner: cell,
            late,
            owed: Duration::ZERO,
        });
        c.set_block_margin(margin);
        c.measure(&params, 2, |_| {}).unwrap()
    };
    // The stop comes 10 ms after the block's planned end, 20 ms before its real end.
    let cut = run(Duration::from_millis(10));
    assert!(cut.missing_values() > 0, "{} rows", cut.rows.len());
    assert_eq!(cut.expected_values, 100);
    // A margin longer than the lateness keeps every reading.
    let whole = run(Duration::from_millis(50));
    assert_eq!(whole.missing_values(), 0);
    assert_eq!(whole.rows.len(), 100);
}

/// The cell's port, where what the cell sent before a discard still comes after it (a host
/// that got to the line late, on a loaded machine).
struct LateInput(SimPort<Cell>);

impl Port for LateInput {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.0.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.0.recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        self.0.now()
    }
    fn pause(&mut self, d: Duration) {
        self.0.pause(d)
    }
    fn drain(&mut self) -> std::io::Result<()> {
        self.0.drain()
    }
    fn discard_input(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_reply_to_garbage_that_comes_after_the_reset_is_not_taken_for_an_answer() {
    // The stress run's failure: an answer to the garbage before a reset reached the host only
    // after the reset had thrown its input away, and `key_pressed` read it.
    let mut cell = Cell::default();
    cell.set_analog(1, source("2.5V")).unwrap();
    let mut c = Client::new(LateInput(cell.into_sim_port()));
    // Analog readings nobody reads, and a command 7 whose channel is the reset's first zero.
    c.port().send(&[7, 1, 7, 2, 7]).unwrap();
    c.reset().unwrap();
    assert!(!c.key_pressed().unwrap());
    assert_eq!(c.analog(1).unwrap(), 128);
}
