//! The cell model byte by byte, with exact arrival times.

use buslab_device::Nanos;
use buslab_zelle::analog::Source;
use buslab_zelle::timing::{BYTE_NS, MS};
use buslab_zelle::{Activity, BatteryRam, Cell, Mode, START_BYTE, SetupRule};

/// Drives a cell like a line would: bytes back to back unless told to wait.
struct Line {
    cell: Cell,
    t: Nanos,
    out: Vec<u8>,
}

impl Line {
    fn new(cell: Cell) -> Line {
        Line {
            cell,
            t: Nanos::ZERO,
            out: Vec::new(),
        }
    }

    /// Sends bytes back to back, each arriving one character time after the previous.
    fn send(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.t += BYTE_NS;
            self.cell.receive(self.t, b);
        }
    }

    /// Lets `ns` pass on an idle line.
    fn wait(&mut self, ns: Nanos) {
        let end = self.t + ns;
        while let Some(d) = self.cell.next_deadline().filter(|&d| d <= end) {
            self.cell.poll(d, &mut self.out);
        }
        self.t = end;
        self.cell.poll(end, &mut self.out);
    }

    /// Everything the cell sent so far, cleared.
    fn take(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }
}

fn ramp_ms() -> Source {
    // 0..5 V over 255 ms: the reading is the sample time in ms (mod 255).
    Source::Ramp {
        from: 0.0,
        to: 5.0,
        period: 255 * MS,
    }
}

#[test]
fn setup_pause_after_commands_1_2_3_5_is_enforced() {
    let mut l = Line::new(Cell::default());
    // Command 2 then a request right behind it: the request's start bit falls in the set-up.
    l.send(&[2, 1]);
    l.wait(10 * MS);
    assert_eq!(l.take(), Vec::<u8>::new());
    assert_eq!(l.cell.stats().lost_in_setup, 1);
    // After the 1 ms pause the same request is answered.
    l.wait(MS);
    l.send(&[1, 1, 0]);
    l.wait(10 * MS);
    assert_eq!(l.take(), [0, 0]);
    // Commands without a set-up take their data back to back.
    l.send(&[19, 0x08, 0x00, 0x77, 18, 0x08, 0x00]);
    l.wait(5 * MS);
    assert_eq!(l.take(), [0x77]);
    assert_eq!(l.cell.stats().lost_in_setup, 1);
}

/// A host that cannot see the line's timing (a pseudo-terminal) keeps a byte sent within the
/// set-up and counts it; every command with a set-up works without the pause.
#[test]
fn a_cell_keeping_bytes_in_the_setup_counts_them_and_answers() {
    let mut cell = Cell::default();
    cell.set_setup_rule(SetupRule::Keep);
    let mut l = Line::new(cell);
    l.send(&[19, 0x08, 0x00, 0x5A]);
    // Command 2 and two requests back to back: the first request started in the set-up.
    l.send(&[2, 1, 1, 0]);
    l.wait(10 * MS);
    assert_eq!(l.take(), [0x5A, 0]);
    let stats = l.cell.stats();
    assert_eq!((stats.kept_in_setup, stats.lost_in_setup), (1, 0));
    // Command 1 and its eight parameters back to back: all of them arrive (10 cycles, ch 1).
    l.send(&[1, 0, 10, 1, 0, 0, 0, 0, 5]);
    l.wait(MS);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    assert_eq!(l.cell.stats().kept_in_setup, 2);
    assert_eq!(l.cell.stats().lost_in_setup, 0);
}

/// Seed 003: "Fast alle Kommandos dürfen mit der maximal möglichen Geschwindigkeit zusammen
/// mit den erforderlichen Daten gesendet werden, da die zugehörigen Funktionen innerhalb der
/// Zeit für zwei Stoppbits beendet sind." Command 4 is not among the exceptions (1, 2, 3, 5).
#[test]
fn command_4_takes_its_channel_bytes_at_full_line_speed() {
    let mut l = Line::new(Cell::default());
    for (channel, volts) in [(1, 1.0), (2, 2.0), (3, 3.0), (4, 4.0)] {
        l.cell.set_analog(channel, Source::Constant(volts)).unwrap();
    }
    let code = |v: f64| (v / 5.0 * 255.0).round() as u8;
    // Back to back: one answer per channel byte, nothing lost.
    l.send(&[4, 1, 2, 3, 4, 0]);
    l.wait(10 * MS);
    assert_eq!(l.take(), [code(1.0), code(2.0), code(3.0), code(4.0)]);
    assert_eq!(l.cell.stats().lost_overrun, 0);
    // The closing 0 is taken too: the next command is a command, not a channel number.
    l.send(&[4, 1, 2, 3, 0, 13]);
    l.wait(10 * MS);
    assert_eq!(
        l.take(),
        [code(1.0), code(2.0), code(3.0), 1],
        "13: key not pressed"
    );
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert_eq!(l.cell.stats().lost_overrun, 0);
}

#[test]
fn a_byte_arriving_while_the_previous_one_is_unread_is_lost() {
    // The 8051 has one receive buffer: while a block is measured the OS reads nothing, so a
    // START (9) waits in the buffer and the next byte behind it is an overrun.
    let mut l = Line::new(Cell::default());
    l.send(&[1]);
    l.wait(MS);
    // 100 cycles of channel 1, every 11 ms: the block lasts 1.1 s.
    l.send(&[0, 100, 1, 0, 0, 0, 0, 10]);
    l.send(&[9]);
    assert_eq!(l.cell.activity(), Activity::Measuring);
    l.send(&[9, 9]);
    assert_eq!(l.cell.stats().lost_overrun, 1);
}

#[test]
fn replies_take_the_documented_time() {
    let mut l = Line::new(Cell::default());
    l.send(&[18, 0x03]);
    let t_last = l.t + BYTE_NS;
    l.send(&[0xFF]);
    // The reply's stop bits end one character after the last address byte arrived.
    assert_eq!(l.cell.next_deadline(), Some(t_last + BYTE_NS));
    // Command 7: the conversion hides in the channel byte's stop bits; the reply follows.
    l.wait(5 * MS);
    l.take();
    l.send(&[7, 2]);
    assert_eq!(l.cell.next_deadline(), Some(l.t + BYTE_NS));
}

#[test]
fn series_converts_channels_1ms_apart_and_cycles_every_interval() {
    let mut l = Line::new(Cell::default());
    l.cell.set_analog(1, ramp_ms()).unwrap();
    l.cell.set_analog(3, ramp_ms()).unwrap();
    // 4 cycles, channels 3 and 1, interval 20 ms → 18 ms after the two conversions.
    l.send(&[1]);
    l.wait(MS);
    l.send(&[0, 4, 3, 0, 1, 0, 0, 18]);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    assert_eq!(l.cell.mode(), Mode::Measure);
    l.wait(100 * MS);
    assert_eq!(l.cell.value_count(), 0, "nothing before START");
    l.send(&[9]);
    let start_ms = (l.t / MS) as i64;
    assert_eq!(l.cell.activity(), Activity::Measuring);
    l.wait(200 * MS);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    assert_eq!(l.cell.value_count(), 8);
    let ram = l.cell.ram();
    assert_eq!(
        (0..8).map(|i| ram.read(0x0800 + i)).collect::<Vec<_>>(),
        [0, 4, 3, 0, 1, 0, 0, 18]
    );
    let values: Vec<i64> = (0..8).map(|i| i64::from(ram.read(0x0808 + i))).collect();
    for (i, v) in values.iter().enumerate() {
        let expected = (start_ms + (i as i64 / 2) * 20 + (i as i64 % 2)) % 255;
        assert!((v - expected).abs() <= 1, "value {i}: {v} vs {expected}");
    }
    // A second START appends the next block.
    l.send(&[9]);
    l.wait(200 * MS);
    assert_eq!(l.cell.value_count(), 16);
    // Stop; the count stays readable with command 16 (R6:R7).
    l.send(&[0]);
    assert_eq!(l.cell.activity(), Activity::Ready);
    l.wait(3 * MS);
    l.send(&[16, 6, 16, 7]);
    l.wait(10 * MS);
    assert_eq!(l.take(), [0, 16]);
}

#[test]
fn byte_0_interrupts_a_block_but_not_a_parameter_exchange() {
    let mut l = Line::new(Cell::default());
    l.send(&[1]);
    l.wait(MS);
    // Zeros inside the 8 parameters are data: the serial routine masks the interrupt.
    l.send(&[0, 200, 1, 0, 0, 0, 0, 10]);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    l.send(&[9]);
    l.wait(55 * MS);
    l.send(&[0]);
    let count = l.cell.value_count();
    assert!((5..=7).contains(&count), "{count}");
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert_eq!(l.cell.ram().read(START_BYTE), 0);
    l.wait(100 * MS);
    assert_eq!(l.cell.value_count(), count, "stopped at once");
    // Other bytes do not interrupt: only 9 starts a block, the rest are ignored.
    l.send(&[10]);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    l.send(&[5, 1, 2]);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    assert_eq!(l.cell.value_count(), 0, "command 10 starts a new series");
}

#[test]
fn start_key_starts_blocks_and_9_does_nothing_when_ready() {
    let mut l = Line::new(Cell::default());
    l.send(&[9, 13]);
    l.wait(5 * MS);
    assert_eq!(l.take(), [1], "9 ignored, then the key reads not pressed");
    l.send(&[1]);
    l.wait(MS);
    l.send(&[0, 3, 2, 0, 0, 0, 0, 4]);
    let t = l.t;
    l.cell.press_key_for(t, 200 * MS);
    assert_eq!(l.cell.activity(), Activity::Measuring);
    l.wait(300 * MS);
    assert_eq!(l.cell.value_count(), 3);
}

#[test]
fn armed_series_resumes_after_a_power_cycle_through_the_state_file() {
    let mut l = Line::new(Cell::default());
    l.cell.set_analog(2, Source::Constant(2.5)).unwrap();
    l.send(&[1]);
    l.wait(MS);
    l.send(&[0, 2, 2, 0, 0, 0, 0, 9]);
    l.wait(5 * MS);
    let t = l.t;
    l.cell.power_off(t);
    assert_eq!(l.cell.activity(), Activity::Off);
    // Only the battery-backed RAM survives, here through its file form.
    let file = l.cell.ram().to_state_file();
    let mut l = Line::new(Cell::new(BatteryRam::from_state_file(&file).unwrap()));
    l.cell.set_analog(2, Source::Constant(2.5)).unwrap();
    assert_eq!(l.cell.mode(), Mode::Measure);
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    l.send(&[9]);
    l.wait(50 * MS);
    assert_eq!(l.cell.value_count(), 2);
    assert_eq!(l.cell.ram().read(0x0808), 128);
    // Power-cycling the same cell resumes too.
    let t = l.t;
    l.cell.power_off(t);
    l.cell.power_on(t + 1000 * MS);
    l.t = t + 1000 * MS;
    assert_eq!(l.cell.activity(), Activity::MeasureWaiting);
    assert_eq!(l.cell.value_count(), 0, "a resumed series starts over");
}

#[test]
fn start_key_held_at_power_on_selects_the_mode() {
    let cases = [
        (500, Mode::Measure),  // too short: the stored mode stays
        (1200, Mode::Measure), // ~1 s
        (3300, Mode::Program), // ~3 s
        (5200, Mode::Ready),   // ~5 s
        (60_000, Mode::Ready), // held on: ready at 5 s
    ];
    for (hold_ms, mode) in cases {
        let mut ram = BatteryRam::default();
        ram.write(START_BYTE, 129);
        let mut cell = Cell::new(ram);
        cell.power_off(MS);
        cell.press_key_for(2 * MS, hold_ms * MS);
        cell.power_on(3 * MS);
        assert_eq!(cell.activity(), Activity::TimingKey);
        let mut out = Vec::new();
        cell.receive(4 * MS, 13); // ignored while the key is timed
        cell.poll(10_000 * MS, &mut out);
        assert_eq!(cell.mode(), mode, "held {hold_ms} ms");
        assert_ne!(cell.activity(), Activity::TimingKey);
        assert!(out.is_empty());
    }
}

#[test]
fn full_data_area_ends_the_series_in_the_ready_state() {
    let mut l = Line::new(Cell::default());
    // 65535 cycles of 4 channels would need 262140 bytes; 30712 fit.
    l.send(&[1]);
    l.wait(MS);
    l.send(&[0xFF, 0xFF, 1, 2, 3, 4, 0, 0]);
    l.send(&[9]);
    l.wait(40_000 * MS);
    assert_eq!(l.cell.value_count(), 0x8000 - 0x0808);
    assert_eq!(l.cell.mode(), Mode::Ready);
    assert_eq!(l.cell.activity(), Activity::Ready);
    // Nothing was written past the RAM; the parameters are intact.
    assert_eq!(l.cell.ram().read(0x0800), 0xFF);
    assert_eq!(l.cell.ram().read(0x0806), 0);
}

#[test]
fn power_off_cuts_a_reply_and_drops_bytes() {
    let mut l = Line::new(Cell::default());
    l.send(&[12]);
    let t = l.t + BYTE_NS / 2;
    l.cell.power_off(t);
    l.wait(5 * MS);
    assert!(l.take().is_empty());
    l.send(&[12]);
    assert_eq!(l.cell.stats().lost_off, 1);
    let t = l.t;
    l.cell.power_on(t);
    l.send(&[12]);
    l.wait(5 * MS);
    assert_eq!(l.take(), [0xFF]);
}

#[test]
fn upload_sends_a_timing_byte_before_each_byte() {
    let mut l = Line::new(Cell::default());
    l.send(&[3]);
    l.wait(3 * MS);
    assert_eq!(l.take().len(), 1, "first timing byte after the set-up");
    l.send(&[1, 0xAB]);
    l.wait(3 * MS);
    assert_eq!(l.take().len(), 1);
    l.send(&[7, 0xCD, 0]); // any nonzero flag means "a byte follows"
    l.wait(3 * MS);
    assert_eq!(l.take().len(), 1);
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert_eq!(l.cell.ram().read(0x0800), 0xAB);
    assert_eq!(l.cell.ram().read(0x0801), 0xCD);
    assert_eq!(
        l.cell.mode(),
        Mode::Ready,
        "command 3 does not arm program mode"
    );
}

#[test]
fn writes_p26_from_bit_0_and_reads_registers_above_127_as_ff() {
    let mut l = Line::new(Cell::default());
    l.send(&[14, 0xFE, 15, 14, 0x03, 15, 16, 200, 8, 0x85]);
    l.wait(10 * MS);
    assert_eq!(l.take(), [0, 1, 0xFF, 0xFF]);
}

#[test]
fn channel_bytes_select_the_multiplexer_by_their_low_bits_and_0_answers_nothing() {
    let mut l = Line::new(Cell::default());
    l.cell.set_analog(1, Source::Constant(1.0)).unwrap();
    l.cell.set_analog(2, Source::Constant(2.0)).unwrap();
    // 5 → input 1, 6 → input 2 ((n - 1) & 3); channel 0 ends command 7 without a reading.
    l.send(&[7, 5]);
    l.wait(5 * MS);
    l.send(&[7, 6]);
    l.wait(5 * MS);
    l.send(&[7, 0, 13]);
    l.wait(5 * MS);
    assert_eq!(l.take(), [51, 102, 1]);
}

#[test]
fn internal_ram_is_cleared_by_power_on_but_kept_by_reset() {
    let mut l = Line::new(Cell::default());
    l.send(&[17, 0x20, 0x99]);
    l.wait(2 * MS);
    let t = l.t;
    l.cell.reset(t);
    assert_eq!(l.cell.internal_ram()[0x20], 0x99);
    l.cell.power_off(t);
    l.cell.power_on(t + MS);
    assert_eq!(l.cell.internal_ram()[0x20], 0);
}

/// Seed 003, command 16: "Die Zelle erwartet die gewünschte Adresse und antwortet mit dem
/// Inhalt der Adresse" (any address; command 17 alone is limited to 0..127). 80h..FFh are the
/// 8051's special function registers.
#[test]
fn command_16_reads_the_special_function_registers() {
    use buslab_zelle::sfr;
    let mut l = Line::new(Cell::default());
    let read = |l: &mut Line, addr: u8| {
        l.send(&[16, addr]);
        l.wait(5 * MS);
        let got = l.take();
        assert_eq!(got.len(), 1, "one answer for {addr:#04x}");
        got[0]
    };
    // Port 1 with the LED on (P1.0 low) and P1.7 pulled low from outside.
    l.send(&[11, 0xFE]);
    l.wait(5 * MS);
    l.cell.set_port1_pulled_low(0x80);
    assert_eq!(read(&mut l, sfr::P1), 0x7E);
    // Port 3: lines idle high; the START key on INT1 (P3.3) reads low while pressed.
    assert_eq!(read(&mut l, sfr::P3), 0xFF);
    l.cell.key_down(l.t);
    assert_eq!(read(&mut l, sfr::P3), 0xF7);
    l.cell.key_up(l.t);
    // P2.6 cleared by command 14.
    l.send(&[14, 0]);
    l.wait(5 * MS);
    assert_eq!(read(&mut l, sfr::P2), 0xBF);
    // The data pointer is the last RAM address the OS used (command 18 reads 1234h).
    l.send(&[18, 0x12, 0x34]);
    l.wait(5 * MS);
    l.take();
    assert_eq!(read(&mut l, sfr::DPH), 0x12);
    assert_eq!(read(&mut l, sfr::DPL), 0x34);
    // The accumulator holds the address just received; PSW its parity; SP one call deep.
    assert_eq!(read(&mut l, sfr::ACC), 0xE0);
    assert_eq!(read(&mut l, sfr::PSW), 0x01);
    assert_eq!(read(&mut l, sfr::SP), 0x09);
    assert_eq!(read(&mut l, sfr::B), 0x00);
    // The UART: mode 3 for 8N2, timer 1 reloading FDh for 9600 baud.
    assert_eq!(read(&mut l, sfr::SCON), 0xDC);
    assert_eq!(read(&mut l, sfr::TH1), 0xFD);
    assert_eq!(read(&mut l, sfr::TMOD), 0x20);
    // Internal RAM below 80h as before.
    l.send(&[17, 0x30, 0x5A]);
    l.wait(5 * MS);
    assert_eq!(read(&mut l, 0x30), 0x5A);
}

#[test]
fn ram_changes_replayed_over_the_old_ram_give_the_new_one() {
    use buslab_zelle::{Changes, Persistent};
    let before = BatteryRam::default();
    let mut l = Line::new(Cell::new(before.clone()));
    l.cell.set_analog(1, ramp_ms()).unwrap();
    // Pokes, an upload, a series and its values, a stop (start byte).
    l.send(&[19, 0x10, 0x00, 0xAB, 19, 0x10, 0x01, 0xCD]);
    l.send(&[3]);
    l.wait(2 * MS);
    for b in [1u8, 0x11, 1, 0x22] {
        l.send(&[b]);
        l.wait(3 * MS);
    }
    l.send(&[0, 1]);
    l.wait(2 * MS);
    l.send(&[0, 5, 1, 0, 0, 0, 0, 2, 9]);
    l.wait(100 * MS);
    l.send(&[0]);
    l.wait(5 * MS);
    let Changes::Records(records) = l.cell.take_changes() else {
        panic!("a few changes fit in records");
    };
    assert!(!records.is_empty());
    let mut replayed = before;
    for r in &records {
        Cell::replay(&mut replayed, r).unwrap();
    }
    assert_eq!(&replayed, l.cell.ram());
    // Contiguous writes share a record: far fewer records than bytes written.
    assert!(records.len() < 12, "{} records", records.len());
    assert!(Cell::replay(&mut replayed, &[0x10]).is_err());
}
