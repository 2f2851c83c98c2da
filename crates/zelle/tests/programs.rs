//! User programs on the cell's 8051, through the line alone (commands 5 and 6, bytes on RxD,
//! bytes heard on TxD) and the cell's outside (RESET, power, START key, port pins), in virtual
//! time. The programs are hand-assembled; each instruction has its comment.
//!
//! The rules come from seed 003 ("Betriebssystem und Kommandos der ZELLE"); where a test
//! depends on one, its words are quoted.

use buslab_device::Nanos;
use buslab_zelle::chip::START_SP;
use buslab_zelle::rom::{EMPF, PROGRAM_RETURN, SENDE};
use buslab_zelle::timing::{BYTE_NS, KEY_HOLD_READY_NS, MS, RESET_GAP_NS};
use buslab_zelle::{Activity, BatteryRam, Cell, Mode, ProgramEnd, START_BYTE};
use proptest::prelude::*;

/// One bit at 9600 baud.
const BIT_NS: Nanos = Nanos::new(BYTE_NS.get() / 11);
/// One machine cycle at 11.0592 MHz (12 clocks), rounded down.
const CYCLE_NS: Nanos = Nanos::new(1085);

/// `LCALL addr`.
fn lcall(addr: u16) -> [u8; 3] {
    let [high, low] = addr.to_be_bytes();
    [0x12, high, low]
}

/// `LJMP addr`.
fn ljmp(addr: u16) -> [u8; 3] {
    let [high, low] = addr.to_be_bytes();
    [0x02, high, low]
}

/// A program image from 0400h out of pieces at their addresses, NOPs between them.
fn image(pieces: &[(u16, &[u8])]) -> Vec<u8> {
    let mut image = Vec::new();
    for &(addr, code) in pieces {
        let offset = usize::from(addr - 0x0400);
        assert!(image.len() <= offset, "pieces overlap at {addr:04X}h");
        image.resize(offset, 0x00);
        image.extend_from_slice(code);
    }
    image
}

/// A host on the cell's line, keeping the time each byte from the cell was heard.
struct Line {
    cell: Cell,
    /// The line's time: the last instant the cell was run to.
    t: Nanos,
    /// Bytes from the cell with the instant the host had them (a poll's time).
    heard: Vec<(Nanos, u8)>,
    /// The longest stretch between two polls: how finely arrival times are known.
    grid: Nanos,
}

impl Line {
    fn new(cell: Cell) -> Line {
        let t = cell.now();
        Line {
            cell,
            t,
            heard: Vec::new(),
            grid: Nanos::new(100_000),
        }
    }

    /// Runs the cell to `end`, polling at each of its deadlines and at least every `grid`.
    fn run_to(&mut self, end: Nanos) {
        let mut out = Vec::new();
        while self.t < end {
            let deadline = self.cell.next_deadline().filter(|&d| d > self.t);
            let at = deadline
                .unwrap_or(Nanos::MAX)
                .min(self.t + self.grid)
                .min(end);
            self.cell.poll(at, &mut out);
            self.heard.extend(out.drain(..).map(|b| (at, b)));
            self.t = at;
        }
    }

    /// Lets `ns` pass.
    fn wait(&mut self, ns: Nanos) {
        self.run_to(self.t + ns);
    }

    /// Sends bytes back to back: each arrives (its stop bits ended) one character time after
    /// the previous one.
    fn send(&mut self, bytes: &[u8]) {
        for &b in bytes {
            let at = self.t + BYTE_NS;
            self.run_to(at);
            self.cell.receive(at, b);
        }
    }

    /// Sends bytes `gap_ns` apart (from one byte's end to the next one's).
    fn send_apart(&mut self, bytes: &[u8], gap_ns: Nanos) {
        for &b in bytes {
            self.send(&[b]);
            self.wait(gap_ns);
        }
    }

    /// Everything heard so far, cleared.
    fn take(&mut self) -> Vec<u8> {
        self.heard.drain(..).map(|(_, b)| b).collect()
    }

    /// Waits until `n` bytes have been heard in all (at most `limit_ns`), then takes them.
    fn expect(&mut self, n: usize, limit_ns: Nanos) -> Vec<u8> {
        let end = self.t + limit_ns;
        while self.heard.len() < n && self.t < end {
            self.run_to((self.t + self.grid).min(end));
        }
        self.take()
    }

    /// Command 5: the program at 0400h. Before each byte the cell sends a timing byte; the host
    /// answers 1 and the byte, or 0 to end (seed: "Die Übertragung entspricht genau der beim
    /// Kommando 3").
    fn load(&mut self, program: &[u8]) {
        self.take();
        self.send(&[5]);
        for &b in program {
            let timing = self.expect(1, 10 * MS);
            assert_eq!(timing.len(), 1, "a timing byte before each program byte");
            self.send(&[1, b]);
        }
        assert_eq!(self.expect(1, 10 * MS).len(), 1, "the last timing byte");
        self.send(&[0]);
        self.wait(2 * MS);
        assert_eq!(
            self.cell.mode(),
            Mode::Program,
            "command 5 arms program mode"
        );
        assert_eq!(self.cell.activity(), Activity::Ready, "6 starts it, not 5");
    }

    /// Command 6: the program starts at 0400h. Returns the instant the command arrived.
    fn start(&mut self) -> Nanos {
        self.send(&[6]);
        assert_eq!(self.cell.activity(), Activity::ProgramRunning);
        self.t
    }

    /// A fresh cell running `program` (loaded with 5, started with 6); the instant 6 arrived.
    fn running(program: &[u8]) -> (Line, Nanos) {
        let mut l = Line::new(Cell::default());
        l.load(program);
        let t = l.start();
        (l, t)
    }

    /// Command 18: a byte of the external RAM.
    fn peek(&mut self, addr: u16) -> u8 {
        self.take();
        let [high, low] = addr.to_be_bytes();
        self.send(&[18, high, low]);
        let got = self.expect(1, 5 * MS);
        assert_eq!(
            got.len(),
            1,
            "command 18 answers one byte (is the OS there?)"
        );
        got[0]
    }

    /// Command 13 (the START key): whether the OS answers commands, by its answer ("0" for
    /// pressed, "1" for not).
    fn os_answers(&mut self) -> bool {
        self.take();
        self.send(&[13]);
        let answer = self.expect(1, 5 * MS);
        answer == [u8::from(!self.cell.key_is_down())]
    }

    /// The seed's reset: "Eine Serie von zehn Bytes "0" holt die Zelle aus jedem Zustand in den
    /// Startzustand zurück [...] Zwischen den einzelnen "0"-Bytes sollen 2ms Wartezeit liegen".
    fn ten_zeros(&mut self) {
        self.send_apart(&[0; 10], RESET_GAP_NS);
    }
}

/// Sends a text with direct `SBUF` writes: `CLR TI`, `MOV SBUF,A`, `JNB TI,$` per byte.
const SBUF_HELLO: [u8; 25] = [
    0x90, 0x04, 0x13, // 0400 MOV DPTR,#0413h   the text
    0xE4, //             0403 CLR A             next:
    0x93, //             0404 MOVC A,@A+DPTR
    0x60, 0x0A, //       0405 JZ 0411h          the 0 ends the text
    0xC2, 0x99, //       0407 CLR TI
    0xF5, 0x99, //       0409 MOV SBUF,A
    0x30, 0x99, 0xFD, // 040B JNB TI,$
    0xA3, //             040E INC DPTR
    0x80, 0xF2, //       040F SJMP 0403h
    0x80, 0xFE, //       0411 SJMP $
    b'H', b'E', b'L', b'L', b'O', 0, // 0413 the text
];

#[test]
fn a_program_writing_sbuf_is_heard_at_9600_8n2_one_character_after_another() {
    let mut l = Line::new(Cell::default());
    l.load(&SBUF_HELLO);
    // Arrival times known to the microsecond.
    l.grid = Nanos::new(1_000);
    let t6 = l.start();
    l.wait(20 * MS);
    let heard = std::mem::take(&mut l.heard);
    let bytes: Vec<u8> = heard.iter().map(|&(_, b)| b).collect();
    assert_eq!(bytes, b"HELLO");
    // The program writes SBUF again as soon as TI says the stop bits have begun, so the bytes
    // follow each other at the line's rate: 11 bits at 9600 baud apart. An arrival is known to
    // the host's poll (the grid) and the instruction the core stops after (the 2-cycle JNB).
    let known = l.grid + 2 * CYCLE_NS;
    for pair in heard.windows(2) {
        let gap = pair[1].0 - pair[0].0;
        assert!(
            gap.abs_diff(BYTE_NS) <= known,
            "{gap} ns apart, not {BYTE_NS}"
        );
    }
    // The first byte: the 2-cycle MOV SBUF, up to one bit waiting for the baud counter's
    // rollover, 10 bits to TI (the start of the second stop bit), and the core's lag behind
    // the line (chip.rs: one character and its longest instruction, 4 cycles)...
    let first = heard[0].0 - t6;
    let earliest = 2 * BYTE_NS - BIT_NS + 6 * CYCLE_NS;
    let latest = 2 * BYTE_NS + 6 * CYCLE_NS + known;
    assert!(
        (earliest..=latest).contains(&first),
        "first byte {first} ns after command 6, not within {earliest}..={latest}"
    );
    // ...and all five in five character times.
    let all = heard[4].0 - heard[0].0;
    assert!(all.abs_diff(4 * BYTE_NS) <= known, "{all}");
    assert_eq!(l.cell.stats().unreadable_frames, 0);
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
}

/// Sends "HELLO" through the OS's `Sende` (0030h), then waits.
const SENDE_HELLO: [u8; 21] = [
    0x90, 0x04, 0x0F, // 0400 MOV DPTR,#040Fh   the text
    0xE4, //             0403 CLR A             next:
    0x93, //             0404 MOVC A,@A+DPTR
    0x60, 0x06, //       0405 JZ 040Dh          the 0 ends the text
    0x12, 0x00, 0x30, // 0407 LCALL Sende
    0xA3, //             040A INC DPTR          (Sende keeps DPTR)
    0x80, 0xF6, //       040B SJMP 0403h
    0x80, 0xFE, //       040D SJMP $
    b'H', b'E', b'L', b'L', b'O', 0, // 040F the text
];

#[test]
fn a_program_calling_sende_is_heard_byte_after_byte() {
    assert_eq!(SENDE_HELLO[7..10], lcall(SENDE));
    let (mut l, t6) = Line::running(&SENDE_HELLO);
    l.grid = Nanos::new(1_000);
    l.wait(20 * MS);
    let heard = std::mem::take(&mut l.heard);
    assert_eq!(heard.iter().map(|&(_, b)| b).collect::<Vec<_>>(), b"HELLO");
    // Sende returns when its byte has left; the next call starts the next byte within a bit
    // (the baud counter's rollover), so the bytes are 11 or 12 bits apart, never closer.
    let known = l.grid + 2 * CYCLE_NS;
    for pair in heard.windows(2) {
        let gap = pair[1].0 - pair[0].0;
        assert!(
            gap + known >= BYTE_NS && gap <= BYTE_NS + BIT_NS + known,
            "{gap} ns apart"
        );
    }
    assert!(heard[0].0 - t6 >= 2 * BYTE_NS - BIT_NS);
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    assert_eq!(l.cell.last_program_stop(), None);
}

/// Frames the host cannot read at 9600 8N2 (here mode 3 with the 9th bit, the first stop
/// bit, 0) are counted, not passed on as bytes.
#[test]
fn a_frame_with_a_stop_bit_0_is_counted_not_heard() {
    let program = [
        0xC2, 0x9B, //       0400 CLR TB8          the first stop bit 0
        0x75, 0x99, 0x41, // 0402 MOV SBUF,#'A'
        0x30, 0x99, 0xFD, // 0405 JNB TI,$
        0xC2, 0x99, //       0408 CLR TI
        0xD2, 0x9B, //       040A SETB TB8
        0x75, 0x99, 0x42, // 040C MOV SBUF,#'B'
        0x80, 0xFE, //       040F SJMP $
    ];
    let (mut l, _) = Line::running(&program);
    l.wait(10 * MS);
    assert_eq!(l.take(), b"B");
    assert_eq!(l.cell.stats().unreadable_frames, 1);
}

/// Seed 003, command 11: "Bit 0 kann low gesetzt werden, um die LED anzuschalten." A program
/// drives the same pin.
#[test]
fn the_programs_p1_0_writes_light_and_darken_the_led() {
    let program = [
        0xC2, 0x90, // 0400 CLR P1.0          LED on
        0x7E, 0x00, // 0402 MOV R6,#0
        0x7F, 0x00, // 0404 MOV R7,#0          outer:
        0xDF, 0xFE, // 0406 DJNZ R7,$          256 x 2 cycles
        0xDE, 0xFA, // 0408 DJNZ R6,0404h      256 x (1 + 512 + 2) cycles
        0xD2, 0x90, // 040A SETB P1.0          LED off, 131 842 cycles (143.06 ms) in
        0x80, 0xFE, // 040C SJMP $
    ];
    let (mut l, t6) = Line::running(&program);
    assert!(!l.cell.led_on(), "not before the program runs");
    // The core runs one character behind the line (1.15 ms).
    l.run_to(t6 + 5 * MS);
    assert!(l.cell.led_on());
    assert_eq!(l.cell.port1_latch(), 0xFE);
    l.run_to(t6 + 140 * MS);
    assert!(l.cell.led_on(), "still in the delay");
    l.run_to(t6 + 150 * MS);
    assert!(
        !l.cell.led_on(),
        "143 ms of delay loop and one character of lag are over"
    );
    assert_eq!(l.cell.port1_latch(), 0xFF);
    // The OS sees the program's port too: stopped, command 12 reads the pins.
    l.send(&[0]);
    l.wait(RESET_GAP_NS);
    l.send(&[11, 0xFE, 12]);
    assert_eq!(l.expect(1, 5 * MS), [0xFE]);
    assert!(l.cell.led_on());
}

/// Writes the SP it started with to 0900h, then calls itself for ever: the stack runs over
/// internal RAM and wraps.
const STACK_EATER: [u8; 9] = [
    0xE5, 0x81, //       0400 MOV A,SP
    0x90, 0x09, 0x00, // 0402 MOV DPTR,#0900h
    0xF0, //             0405 MOVX @DPTR,A
    0x12, 0x04, 0x06, // 0406 LCALL 0406h     itself
];

/// Seed 003: "Ein Interrupt über die Leitung RxD führt in jedem Falle in die
/// Interrupt-Serviceroutine "Inter". Hier wird die Startinformation "0" in das System-RAM
/// geschrieben und außerdem das Betriebssystem mit zurückgesetztem Stack neu gestartet. Dabei
/// werden alle Rücksprungadressen aus eventuellen Unterprogrammen vergessen, so daß eine
/// Unterbrechung aus beliebigen Programmsituationen möglich ist."
#[test]
fn byte_0_stops_a_running_program_and_the_os_answers_with_a_fresh_stack() {
    let (mut l, _) = Line::running(&STACK_EATER);
    l.wait(20 * MS);
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    let sp = l.cell.program_cpu().expect("it runs").registers.sp;
    assert_ne!(sp, START_SP, "the stack has grown");
    let t0 = l.t + BYTE_NS;
    l.send(&[0]);
    l.wait(RESET_GAP_NS);
    let stop = l.cell.last_program_stop().expect("it stopped");
    assert_eq!(stop.why, ProgramEnd::Interrupted);
    // Inter knows the byte in the middle of its first stop bit (the core one character behind).
    assert!(
        stop.cpu.at_ns < t0 && stop.cpu.at_ns > t0 - BYTE_NS,
        "stopped at {} for a byte from {} to {t0}",
        stop.cpu.at_ns,
        t0 - BYTE_NS
    );
    assert_eq!(stop.cpu.registers.pc, 0x0406, "it was calling itself");
    assert_eq!(l.cell.ram().read(START_BYTE), 0, "start byte 0");
    assert_eq!(l.cell.mode(), Mode::Ready);
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert!(l.os_answers());
    assert_eq!(l.peek(0x0900), START_SP, "the program started with SP 09h");
    // Started again ("Neustart durch das Kommando "6" ist ohne neues Laden möglich"), it gets
    // a fresh stack again, whatever the last run left.
    l.send(&[19, 0x09, 0x00, 0xEE]);
    l.start();
    l.wait(5 * MS);
    l.send(&[0]);
    l.wait(RESET_GAP_NS);
    assert_eq!(l.peek(0x0900), START_SP);
    assert!(l.cell.program_cpu().is_none(), "no program runs");
}

/// Echoes each byte `Empf` returns, plus one, through `Sende`.
const ECHO_PLUS_ONE: [u8; 9] = [
    0x12, 0x00, 0x33, // 0400 LCALL Empf
    0x04, //             0403 INC A
    0x12, 0x00, 0x30, // 0404 LCALL Sende
    0x80, 0xF7, //       0407 SJMP 0400h
];

/// Seed 003: "Wird vom Betriebssystem oder von einem User-Programm die serielle Schnittstelle
/// benutzt (Unterprogramme Empf oder Sende), dann wird für die Zeit des seriellen
/// Datenaustauschs der Interrupt gesperrt. Dies kann aber dazu führen, daß ein nachgeladenes
/// Programm, das die serielle Schnittstelle verwendet, nicht mehr ohne weiteres abgebrochen
/// werden kann. Für diesen Fall wurde eine zweite Art zum zwangsweisen Einschalten des
/// Befehlsmodus vorgesehen: Wird nach einem Reset für ca. 5s die Starttaste gedrückt, befindet
/// sich das System wieder im Grundzustand."
#[test]
fn byte_0_inside_empf_is_data_and_only_the_start_key_stops_such_a_program() {
    assert_eq!(ECHO_PLUS_ONE[..3], lcall(EMPF));
    let (mut l, _) = Line::running(&ECHO_PLUS_ONE);
    l.wait(2 * MS);
    assert_eq!(l.cell.program_routine(), Some("Empf"));
    l.send_apart(&[5, 0, 7, 0xFF], 5 * MS);
    assert_eq!(l.take(), [6, 1, 8, 0]);
    // Not even the ten zeros: each is Empf's data.
    l.ten_zeros();
    assert_eq!(l.expect(10, 5 * MS), [1; 10]);
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    assert_eq!(l.cell.last_program_stop(), None);
    assert_eq!(l.cell.mode(), Mode::Program);
    // RESET with the START key held about 5 s: the ready state.
    let t = l.t;
    l.cell.key_down(t);
    l.cell.reset(t);
    assert_eq!(l.cell.activity(), Activity::TimingKey);
    l.wait(KEY_HOLD_READY_NS + MS);
    l.cell.key_up(l.t);
    assert_eq!(
        l.cell.last_program_stop().map(|s| s.why),
        Some(ProgramEnd::Reset)
    );
    assert_eq!(l.cell.mode(), Mode::Ready);
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert!(l.os_answers());
}

/// Sends 'A' through `Sende` for ever: nearly all its time is in Sende's wait.
const SENDE_FOREVER: [u8; 7] = [
    0x74, 0x41, //       0400 MOV A,#'A'
    0x12, 0x00, 0x30, // 0402 LCALL Sende
    0x80, 0xF9, //       0405 SJMP 0400h
];

/// A 0 whose start bit comes while `Sende` waits is not lost: INT0 is edge-triggered, its
/// request waits while Sende masks it, and "Inter" stops the program as soon as Sende has
/// sent its byte whole and returned.
#[test]
fn an_interrupt_held_off_by_sende_is_taken_before_the_programs_next_instruction() {
    let (mut l, _) = Line::running(&SENDE_FOREVER);
    l.wait(10 * MS);
    let sent = l.take().len();
    assert!(sent >= 7, "{sent} bytes in 10 ms");
    assert_eq!(l.cell.program_routine(), Some("Sende"));
    l.send(&[0]);
    l.wait(2 * BYTE_NS);
    let stop = l.cell.last_program_stop().expect("stopped");
    assert_eq!(stop.why, ProgramEnd::Interrupted);
    assert_eq!(stop.cpu.registers.pc, 0x0405, "right after LCALL Sende");
    // Every byte the program started was sent whole, and nothing after the stop.
    assert!(l.take().iter().all(|&b| b == b'A'));
    assert_eq!(l.cell.stats().unreadable_frames, 0);
    l.wait(10 * MS);
    assert!(l.take().is_empty());
    assert!(l.os_answers());
}

/// Sums with carries over 8192 steps (about 44 ms), then sends A and the carry through Sende.
const CHECKSUM: [u8; 22] = [
    0xE4, //             0400 CLR A
    0x7E, 0x20, //       0401 MOV R6,#32
    0x7F, 0x00, //       0403 MOV R7,#0        outer:
    0x3F, //             0405 ADDC A,R7        inner:
    0x33, //             0406 RLC A
    0x6E, //             0407 XRL A,R6
    0xDF, 0xFB, //       0408 DJNZ R7,0405h
    0xDE, 0xF7, //       040A DJNZ R6,0403h
    0x12, 0x00, 0x30, // 040C LCALL Sende      A
    0xE4, //             040F CLR A
    0x33, //             0410 RLC A            A = CY
    0x12, 0x00, 0x30, // 0411 LCALL Sende      the carry
    0x80, 0xFE, //       0414 SJMP $
];

/// What [`CHECKSUM`] computes, the 8051's way.
fn checksum() -> [u8; 2] {
    let (mut a, mut cy) = (0u8, false);
    for r6 in (1..=32u8).rev() {
        let mut r7 = 0u8;
        loop {
            let sum = u16::from(a) + u16::from(r7) + u16::from(cy);
            (a, cy) = (sum as u8, sum > 0xFF);
            (a, cy) = (a << 1 | u8::from(cy), a & 0x80 != 0);
            a ^= r6;
            r7 = r7.wrapping_sub(1);
            if r7 == 0 {
                break;
            }
        }
    }
    [a, u8::from(cy)]
}

/// RxD is wired to INT0: every start bit enters "Inter". A byte other than 0 makes it return
/// (RETI) with the program's registers and flags as they were.
#[test]
fn bytes_other_than_0_leave_the_program_running_and_its_state_intact() {
    let (mut quiet, _) = Line::running(&CHECKSUM);
    quiet.wait(100 * MS);
    assert_eq!(quiet.take(), checksum());

    let (mut l, _) = Line::running(&CHECKSUM);
    let junk = [0xFF, 1, 0x80, 0x55, 9, 6, 13, 0xFE];
    l.send_apart(&junk, 4 * MS);
    assert!(l.heard.is_empty(), "the junk came while it computed");
    l.wait(100 * MS);
    assert_eq!(l.take(), checksum());
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    assert_eq!(l.cell.last_program_stop(), None);
}

/// Sends 'R' through Sende once, then waits.
const SAY_R: [u8; 7] = [
    0x74, 0x52, //       0400 MOV A,#'R'
    0x12, 0x00, 0x30, // 0402 LCALL Sende
    0x80, 0xFE, //       0405 SJMP $
];

/// Seed 003: "Genauso kann ein Userprogramm geladen werden, wobei die Zelle in den
/// Programm-Modus gelangt. Das Programm läuft dann nach jedem Einschalten oder nach einem
/// Reset erneut ab." Command 6: "Es läuft zunächst nur einmal ab, kann aber durch die
/// RESET-Taste erneut gestartet werden."
#[test]
fn program_mode_survives_reset_and_power_cycles_and_runs_from_0400h() {
    let (mut l, _) = Line::running(&SAY_R);
    assert_eq!(l.expect(1, 5 * MS), b"R");
    l.wait(5 * MS);
    assert!(l.take().is_empty(), "once");

    let t = l.t;
    l.cell.reset(t);
    assert_eq!(
        l.cell.last_program_stop().map(|s| s.why),
        Some(ProgramEnd::Reset)
    );
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    assert_eq!(l.expect(1, 5 * MS), b"R", "again after RESET");

    let t = l.t;
    l.cell.power_off(t);
    assert_eq!(
        l.cell.last_program_stop().map(|s| s.why),
        Some(ProgramEnd::PowerOff)
    );
    l.wait(100 * MS);
    let t = l.t;
    l.cell.power_on(t);
    assert_eq!(l.expect(1, 5 * MS), b"R", "again after a power cycle");

    // Through the state file (only the battery-backed RAM survives).
    let file = l.cell.ram().to_state_file();
    let mut l = Line::new(Cell::new(BatteryRam::from_state_file(&file).unwrap()));
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    assert_eq!(l.expect(1, 5 * MS), b"R", "a new cell from the state file");

    // Stopped with 0, the cell stays in the command loop through RESET...
    l.send(&[0]);
    l.wait(RESET_GAP_NS);
    let t = l.t;
    l.cell.reset(t);
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert!(l.os_answers());
    // ...until the START key, held about 3 s after a reset, selects program mode ("mit drei
    // Sekunden in den Programmodus").
    let t = l.t;
    l.cell.press_key_for(t, 3_300 * MS);
    l.cell.reset(t);
    l.wait(3_300 * MS + 5 * MS);
    assert_eq!(l.cell.mode(), Mode::Program);
    assert_eq!(l.take(), b"R");
}

/// The OS starts a program with its return address on the stack (0040h): a RET from the
/// outermost level is back in the command loop, program mode kept.
#[test]
fn ret_from_the_outermost_level_returns_to_the_os_in_program_mode() {
    let program = [
        0x75, 0x90, 0xF0, // 0400 MOV P1,#0F0h
        0x22, //             0403 RET
    ];
    let (mut l, _) = Line::running(&program);
    l.wait(2 * BYTE_NS);
    let stop = l.cell.last_program_stop().expect("returned");
    assert_eq!(stop.why, ProgramEnd::Returned);
    assert_eq!(stop.cpu.registers.pc, PROGRAM_RETURN);
    assert_eq!(stop.cpu.instructions, 2);
    assert_eq!(l.cell.activity(), Activity::Ready);
    assert_eq!(l.cell.mode(), Mode::Program, "the start byte stays 130");
    l.send(&[12]);
    assert_eq!(
        l.expect(1, 5 * MS),
        [0xF0],
        "the port as the program left it"
    );
}

/// A jump to 0000h is the OS's start: it resumes the stored mode, program mode, so the program
/// runs again.
#[test]
fn ljmp_0_restarts_the_os_which_runs_the_program_again() {
    let program = [
        0x90, 0x09, 0x00, // 0400 MOV DPTR,#0900h
        0xE0, //             0403 MOVX A,@DPTR
        0x04, //             0404 INC A            runs counted at 0900h
        0xF0, //             0405 MOVX @DPTR,A
        0xDF, 0xFE, //       0406 DJNZ R7,$         256 x 2 cycles (0.56 ms)
        0x02, 0x00, 0x00, // 0408 LJMP 0
    ];
    let (mut l, t6) = Line::running(&program);
    l.run_to(t6 + 10 * MS);
    assert_eq!(
        l.cell.last_program_stop().map(|s| s.why),
        Some(ProgramEnd::Restarted)
    );
    assert_eq!(l.cell.activity(), Activity::ProgramRunning);
    l.send(&[0]);
    l.wait(RESET_GAP_NS);
    // About 10 ms / 0.56 ms runs.
    let runs = l.peek(0x0900);
    assert!((15..=18).contains(&runs), "{runs} runs");
}

/// A jump anywhere else in the OS area is a fault where it landed (not at 0001h, where the
/// stand-in EPROM's filler led before): the OS starts over as after "Inter".
#[test]
fn a_jump_into_the_os_area_is_a_fault_at_the_address_it_reached() {
    for target in [0x0005u16, 0x0047, 0x00FF, 0x0200, 0x03F3] {
        let (mut l, _) = Line::running(&ljmp(target));
        l.wait(2 * BYTE_NS);
        let stop = l.cell.last_program_stop().expect("stopped");
        assert_eq!(stop.why, ProgramEnd::Fault { pc: target });
        assert_eq!(l.cell.mode(), Mode::Ready, "start byte 0");
        assert!(l.os_answers());
    }
}

/// Timer 0 counts at 30h the interrupts it took, at 32h those that came while the program
/// waited in the OS (the waits are at 03F4h..03FFh); Sende and Empf are each timed.
fn timer_program() -> Vec<u8> {
    image(&[
        (0x0400, &ljmp(0x0430)),
        (
            0x040B, // timer 0 (the OS's vector at 000Bh jumps here)
            &[
                0xC0, 0xD0, //       040B PUSH PSW
                0xA8, 0x81, //       040D MOV R0,SP
                0x18, //             040F DEC R0          the return address's high byte
                0xB6, 0x03, 0x02, // 0410 CJNE @R0,#03h,0415h
                0x05, 0x32, //       0413 INC 32h         taken inside the OS's wait
                0x05, 0x30, //       0415 INC 30h
                0xD0, 0xD0, //       0417 POP PSW
                0x32, //             0419 RETI
            ],
        ),
        (
            0x0430,
            &[
                0x43, 0x89, 0x02, // 0430 ORL TMOD,#02h   timer 0: 8-bit auto-reload
                0x75, 0x8C, 0x00, // 0433 MOV TH0,#0      every 256 cycles (277.8 us)
                0x75, 0x8A, 0x00, // 0436 MOV TL0,#0
                0x75, 0x30, 0x00, // 0439 MOV 30h,#0
                0x75, 0x32, 0x00, // 043C MOV 32h,#0
                0xD2, 0xA9, //       043F SETB ET0
                0xD2, 0x8C, //       0441 SETB TR0
                0x74, 0x55, //       0443 MOV A,#55h
                0x12, 0x00, 0x30, // 0445 LCALL Sende     timed
                0xC2, 0x8C, //       0448 CLR TR0
                0xE5, 0x32, //       044A MOV A,32h
                0x12, 0x00, 0x30, // 044C LCALL Sende
                0xE5, 0x30, //       044F MOV A,30h
                0x12, 0x00, 0x30, // 0451 LCALL Sende
                0x75, 0x30, 0x00, // 0454 MOV 30h,#0
                0x75, 0x32, 0x00, // 0457 MOV 32h,#0
                0xD2, 0x8C, //       045A SETB TR0
                0x12, 0x00, 0x33, // 045C LCALL Empf      timed
                0xC2, 0x8C, //       045F CLR TR0
                0xF5, 0x33, //       0461 MOV 33h,A
                0xE5, 0x32, //       0463 MOV A,32h
                0x12, 0x00, 0x30, // 0465 LCALL Sende
                0xE5, 0x30, //       0468 MOV A,30h
                0x12, 0x00, 0x30, // 046A LCALL Sende
                0xE5, 0x33, //       046D MOV A,33h
                0x12, 0x00, 0x30, // 046F LCALL Sende
                0x80, 0xFE, //       0472 SJMP $
            ],
        ),
    ])
}

/// The OS's vectors lead into the program area (000Bh → 040Bh) and the waits of Sende and
/// Empf are loops with interrupts on (only INT0 masked), so a program's timer keeps being
/// served while it sends or waits for a byte.
#[test]
fn timer_0_interrupts_are_served_while_the_program_waits_in_sende_and_empf() {
    let (mut l, _) = Line::running(&timer_program());
    let heard = l.expect(3, 10 * MS);
    assert_eq!(heard[0], 0x55);
    // Sende takes 10 to 11 bits (960..1056 cycles) and some 14 cycles of its own: 3 or 4
    // overflows every 256 cycles, all of them inside the wait.
    let (inside, all) = (heard[1], heard[2]);
    assert!((3..=4).contains(&all), "{all} timer interrupts in Sende");
    assert_eq!(inside, all, "taken in Sende's wait loop");
    // Empf waits for the host's byte, sent 20 ms after the counts were heard.
    let t_heard = l.t;
    l.wait(20 * MS);
    l.send(&[0x3C]);
    let t_arrived = l.t;
    let heard = l.expect(3, 10 * MS);
    let (inside, all, byte) = (heard[0], heard[1], heard[2]);
    assert_eq!(byte, 0x3C);
    assert_eq!(inside, all, "taken in Empf's wait loop");
    // The timer ran from the last count sent (heard one character late) to the byte's
    // arrival, give or take a character: overflows every 256 cycles.
    let period_ns = Nanos::new(256 * 12 * 1_000_000_000 / 11_059_200);
    let span = t_arrived - t_heard;
    let (low, high) = (
        (span - BYTE_NS) / period_ns,
        (span + BYTE_NS) / period_ns + 1,
    );
    assert!(
        (low..=high).contains(&u64::from(all)),
        "{all} overflows, not {low}..={high}"
    );
}

/// Stores 8 bytes from Empf at 0900h, answers '*' and returns to the OS.
const RECEIVE_8: [u8; 18] = [
    0x90, 0x09, 0x00, // 0400 MOV DPTR,#0900h
    0x7F, 0x08, //       0403 MOV R7,#8
    0x12, 0x00, 0x33, // 0405 LCALL Empf       next:
    0xF0, //             0408 MOVX @DPTR,A
    0xA3, //             0409 INC DPTR
    0xDF, 0xF9, //       040A DJNZ R7,0405h
    0x74, 0x2A, //       040C MOV A,#'*'
    0x12, 0x00, 0x30, // 040E LCALL Sende
    0x22, //             0411 RET
];

#[test]
fn empf_receives_host_bytes_in_order_even_back_to_back() {
    let (mut l, _) = Line::running(&RECEIVE_8);
    l.wait(2 * MS);
    let bytes = [0x10, 0, 0xFF, 0, 0x42, 7, 0, 1];
    l.send(&bytes);
    assert_eq!(l.expect(1, 5 * MS), b"*");
    l.wait(2 * BYTE_NS);
    assert_eq!(
        l.cell.last_program_stop().map(|s| s.why),
        Some(ProgramEnd::Returned)
    );
    let stored: Vec<u8> = (0..8).map(|i| l.peek(0x0900 + i)).collect();
    assert_eq!(stored, bytes);
    assert_eq!(l.cell.stats().lost_overrun, 0);
}

#[test]
fn a_byte_sent_right_behind_command_6_reaches_the_program_whole() {
    // Found by the echo example on a loaded machine (zelle_programs::echo: 0x41 answered with
    // 0xD1 in 1 of 15 runs beside 3 busy loops, 0 of 25 since): a byte on the line when the
    // program started met a receiver switched on mid-frame, which took a 0 data bit for its
    // start bit (0x41 read as 0xD0). The OS's UART now receives all along, as on the cell.
    // This sweep pins the behaviour in virtual time for every start-bit instant.
    let echo_plus_one = image(&[(
        0x0400,
        &[
            &lcall(EMPF)[..],
            &[0x04], // INC A
            &lcall(SENDE)[..],
            &[0x80, 0xF7], // SJMP 0400h
        ]
        .concat(),
    )]);
    // The byte's start bit anywhere from right behind the 6 to two characters later.
    for gap in (0..=44).map(|half_bits| half_bits * BIT_NS / 2) {
        for byte in [0x41u8, 0x55, 0x01, 0xFE] {
            let mut l = Line::new(Cell::new(BatteryRam::default()));
            l.load(&echo_plus_one);
            l.take();
            l.send(&[6]);
            l.wait(gap);
            l.send(&[byte]);
            assert_eq!(
                l.expect(1, 10 * MS),
                [byte.wrapping_add(1)],
                "sent {byte:#04x} {gap} ns after the 6"
            );
        }
    }
}

/// A piece of a well-behaved program (it leaves INT0's enable, priority and edge mode alone,
/// and the line's baud rate).
#[derive(Clone, Debug)]
enum Piece {
    /// `MOV A,#x`, `LCALL Sende`.
    Send(u8),
    /// `LCALL Empf`.
    Receive,
    /// `MOV P1,#x`.
    Port(u8),
    /// `CPL P1.0`.
    ToggleLed,
    /// `MOV R7,#n`, `DJNZ R7,$`.
    Delay(u8),
    /// `MOV DPTR,#09xxh`, `MOVX @DPTR,A`.
    Store(u8),
    /// Timer 0 in mode 2, its interrupt on.
    TimerOn,
    /// The serial interrupt on (its routine clears nothing, so it keeps coming back).
    SerialIrqOn,
    /// `ADD A,#x`, `MUL AB`, `DIV AB`.
    Arith(u8),
    /// `LCALL` a subroutine that pushes and pops.
    Call,
    /// `ORL PCON,#01h`: IDLE until an interrupt.
    Idle,
}

/// How the program ends.
#[derive(Clone, Copy, Debug)]
enum End {
    /// `SJMP $`.
    Halt,
    /// `RET` to the OS.
    Return,
    /// `LJMP 0`: the OS starts over, in program mode.
    Restart,
    /// `LJMP` back to the start of its main part.
    Loop,
}

impl Piece {
    fn code(&self) -> Vec<u8> {
        match *self {
            Piece::Send(x) => [&[0x74, x][..], &lcall(SENDE)].concat(),
            Piece::Receive => lcall(EMPF).to_vec(),
            Piece::Port(x) => vec![0x75, 0x90, x],
            Piece::ToggleLed => vec![0xB2, 0x90],
            Piece::Delay(n) => vec![0x7F, n, 0xDF, 0xFE],
            Piece::Store(x) => vec![0x90, 0x09, x, 0xF0],
            Piece::TimerOn => vec![0x43, 0x89, 0x02, 0xD2, 0xA9, 0xD2, 0x8C],
            Piece::SerialIrqOn => vec![0xD2, 0xAC],
            Piece::Arith(x) => vec![0x24, x, 0xA4, 0x84],
            Piece::Call => lcall(0x0426).to_vec(),
            Piece::Idle => vec![0x43, 0x87, 0x01],
        }
    }
}

/// The program: its vectors, a subroutine, then the pieces from 0430h and the end.
fn assemble(pieces: &[Piece], end: End) -> Vec<u8> {
    let mut main: Vec<u8> = pieces.iter().flat_map(Piece::code).collect();
    main.extend_from_slice(match end {
        End::Halt => &[0x80, 0xFE],
        End::Return => &[0x22],
        End::Restart => &[0x02, 0x00, 0x00],
        End::Loop => &[0x02, 0x04, 0x30],
    });
    image(&[
        (0x0400, &ljmp(0x0430)),
        (0x040B, &[0x05, 0x30, 0x32]), // timer 0: INC 30h, RETI
        (0x0413, &[0x32]),             // INT1: RETI
        (0x041B, &[0x32]),             // timer 1: RETI
        (0x0423, &[0x32]),             // serial: RETI
        (0x0426, &[0xC0, 0xE0, 0x04, 0xD0, 0xE0, 0x22]), // PUSH ACC, INC A, POP ACC, RET
        (0x0430, &main),
    ])
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        any::<u8>().prop_map(Piece::Send),
        Just(Piece::Receive),
        any::<u8>().prop_map(Piece::Port),
        Just(Piece::ToggleLed),
        any::<u8>().prop_map(Piece::Delay),
        any::<u8>().prop_map(Piece::Store),
        Just(Piece::TimerOn),
        Just(Piece::SerialIrqOn),
        any::<u8>().prop_map(Piece::Arith),
        Just(Piece::Call),
        Just(Piece::Idle),
    ]
}

/// A program: at most three `Empf` calls, and none in one that runs for ever through them
/// (each would take a 0 as its data: the seed's program that "nicht mehr ohne weiteres
/// abgebrochen werden kann").
fn program() -> impl Strategy<Value = (Vec<Piece>, End)> {
    let end = prop_oneof![
        Just(End::Halt),
        Just(End::Return),
        Just(End::Restart),
        Just(End::Loop)
    ];
    (prop::collection::vec(piece(), 0..12), end).prop_filter(
        "Empf at most three times, never in a loop",
        |(pieces, end)| {
            let receives = pieces
                .iter()
                .filter(|p| matches!(p, Piece::Receive))
                .count();
            receives <= 3 && (receives == 0 || matches!(end, End::Halt | End::Return))
        },
    )
}

/// What happens on the line and outside before the ten zeros.
#[derive(Clone, Debug)]
enum Before {
    /// A byte, after a pause of this many microseconds. Not 5, 6 or 19, which would change or
    /// start the program behind the property's back.
    Byte(u8, u16),
    Reset,
    PowerCycle,
    /// The START key pressed for this many milliseconds (under 1 s: no mode change).
    Key(u16),
}

fn before() -> impl Strategy<Value = Vec<Before>> {
    let byte = any::<u8>().prop_map(|b| if matches!(b, 5 | 6 | 19) { b + 100 } else { b });
    let one = prop_oneof![
        8 => (byte, 0u16..5000).prop_map(|(b, gap)| Before::Byte(b, gap)),
        1 => Just(Before::Reset),
        1 => Just(Before::PowerCycle),
        1 => (1u16..900).prop_map(Before::Key),
    ];
    prop::collection::vec(one, 0..12)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Seed 003: "Eine Serie von zehn Bytes "0" holt die Zelle aus jedem Zustand in den
    /// Startzustand zurück, also auch dann, wenn sich das System durch Fehlbedienung in einem
    /// falschen Zustand befindet. Zwischen den einzelnen "0"-Bytes sollen 2ms Wartezeit
    /// liegen, weil dies die maximale Bearbeitungszeit zufällig noch aktiver Funktionen sicher
    /// überschreitet."
    #[test]
    fn ten_zeros_2ms_apart_bring_any_running_program_back_to_ready(
        program in program(),
        before in before(),
        run_us in 0u32..20_000,
    ) {
        let (mut l, _) = Line::running(&assemble(&program.0, program.1));
        l.wait(Nanos::from_micros(u64::from(run_us)));
        for event in before {
            let t = l.t;
            match event {
                Before::Byte(b, gap_us) => {
                    l.wait(Nanos::from_micros(u64::from(gap_us)));
                    l.send(&[b]);
                }
                Before::Reset => l.cell.reset(t),
                Before::PowerCycle => {
                    l.cell.power_off(t);
                    l.wait(MS);
                    let t = l.t;
                    l.cell.power_on(t);
                }
                Before::Key(ms) => l.cell.press_key_for(t, u64::from(ms) * MS),
            }
        }
        // The OS loses bytes while it times a key held at a reset: the zeros come after.
        l.wait(MS);
        if l.cell.key_is_down() {
            l.wait(1_000 * MS);
        }
        l.ten_zeros();
        prop_assert_eq!(l.cell.activity(), Activity::Ready);
        prop_assert!(l.os_answers(), "the OS answers command 13");
        // A program that returned to the OS left program mode armed (the start byte 130); the
        // zeros then reach the command loop, which ignores them. Any other way, the start byte
        // is 0.
        let returned = l.cell.last_program_stop().map(|s| s.why) == Some(ProgramEnd::Returned);
        prop_assert!(l.cell.mode() == Mode::Ready || returned, "{:?}", l.cell.mode());
    }
}
