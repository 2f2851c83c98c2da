//! Modules in the board's flash run by the kernel in virtual time: hooks, the kernel API, the
//! return convention, the limits (fuel, memory, output), errors that name what is wrong.

use buslab_cpu196::codes::{Alert, MsgCode};
use buslab_cpu196::message::*;
use buslab_cpu196::prginf::{self, ConfigSet, PRGINF_BLOCK, PTRPRG_BLOCK};
use buslab_cpu196::program::ProgramRef;
use buslab_cpu196::source::Inputs;
use buslab_cpu196::{Board, Decoder, Event, Image, Mode};
use buslab_cpu196_wasm::abi::{self, Hook};
use buslab_cpu196_wasm::layout::{self, DEFAULT_BLOCK};
use buslab_cpu196_wasm::{ModuleError, WasmRuntime};
use buslab_device::{ByteDevice, Nanos, Persistent};

const MS: Nanos = Nanos::from_millis(1);
/// The bank the tests put modules in (the default image uses banks 0 and 1).
const BANK: u8 = 2;

fn wasm(text: &str) -> Vec<u8> {
    wat::parse_str(text).unwrap()
}

/// The default image with `module` at bank 2 block 60h and bank 2's sets: 0 = bank 0's set 0
/// (four channels at 1 kHz) running the module, 1 = the module without A/D and timer 1 every
/// ms, 2 = the module at a block that holds none.
fn image_with(module: &[u8], args: [u16; 7]) -> Image {
    let mut image = Image::default();
    let sets0 = |n| {
        let a = image.flash.read(0, PRGINF_BLOCK).unwrap();
        let p = image.flash.read(0, PTRPRG_BLOCK).unwrap();
        prginf::read_config(a, p, n).unwrap()
    };
    let here = ProgramRef::Module {
        bank: BANK,
        block: DEFAULT_BLOCK,
    }
    .word()
    .unwrap();
    let mut sets: [ConfigSet; 8] = Default::default();
    sets[0] = ConfigSet {
        program: here,
        args,
        ..sets0(0)
    };
    sets[1] = ConfigSet {
        program: here,
        args,
        cycle1: 1250,
        ..Default::default()
    };
    sets[2] = ConfigSet {
        program: ProgramRef::Module {
            bank: BANK,
            block: 0x80,
        }
        .word()
        .unwrap(),
        ..Default::default()
    };
    let (a, p) = prginf::encode(&sets);
    image.flash.write(BANK, PRGINF_BLOCK, &a).unwrap();
    image.flash.write(BANK, PTRPRG_BLOCK, &p).unwrap();
    for (k, data) in layout::encode("test", module, DEFAULT_BLOCK).unwrap() {
        image.flash.write(BANK, k, &data).unwrap();
    }
    image
}

/// A board with the runtime and a PC-side decoder, in virtual time.
struct Bench {
    board: Board,
    host: Decoder,
    now: Nanos,
    seen: Vec<Message>,
}

impl Bench {
    fn new(image: Image) -> Self {
        let mut board = Board::new(image, Inputs::default(), Nanos::ZERO);
        board
            .registry_mut()
            .set_module_runtime(Box::new(WasmRuntime::new()));
        let mut b = Self {
            board,
            host: Decoder::new(),
            now: Nanos::ZERO,
            seen: Vec::new(),
        };
        b.run_for(MS);
        assert_eq!(b.take(), vec![Message::Power(Power::WasReset)]);
        b
    }

    fn with(module: &str) -> Self {
        Self::new(image_with(&wasm(module), [0; 7]))
    }

    fn run_for(&mut self, d: Nanos) {
        let t = self.now + d;
        let mut out = Vec::new();
        loop {
            let next = self
                .board
                .next_deadline()
                .filter(|&d| d <= t)
                .unwrap_or(t)
                .max(self.now);
            self.now = next;
            self.board.poll(next, &mut out);
            for b in out.drain(..) {
                match self.host.push(next, b) {
                    Some(Event::Message(m)) if m != Message::Watchdog => self.seen.push(m),
                    Some(Event::Message(_)) | None => {}
                    Some(other) => panic!("host saw {other:?}"),
                }
            }
            if next >= t {
                break;
            }
        }
    }

    fn send(&mut self, m: &Message) {
        for b in m.to_bytes().unwrap() {
            self.run_for(self.board.line().byte_time());
            self.board.receive(self.now, b);
        }
    }

    fn take(&mut self) -> Vec<Message> {
        std::mem::take(&mut self.seen)
            .into_iter()
            .filter(|m| !matches!(m, Message::AdCont(_) | Message::CfgAd { .. }))
            .collect()
    }

    /// STARTs bank 2's set `n` and runs `ms`; what came back.
    fn start(&mut self, n: u8, ad: bool, ms: u64) -> Vec<Message> {
        self.send(&Message::Start(Start::run(BANK, n, ad)));
        self.run_for(ms * MS);
        self.take()
    }
}

fn text(s: &str) -> Message {
    Message::Thread(Thread::Display {
        format: DisplayFormat::Text,
        newline: true,
        data: s.as_bytes().to_vec(),
    })
}

fn texts(m: &[Message]) -> Vec<String> {
    m.iter()
        .filter_map(|m| match m {
            Message::Thread(Thread::Display {
                format: DisplayFormat::Text,
                data,
                ..
            }) => Some(String::from_utf8_lossy(data).into_owned()),
            _ => None,
        })
        .collect()
}

const COMPLETED: Message = Message::Msg(MsgCode::COMPLETED);

#[test]
fn hooks_display_count_drive_pwm_and_stop_the_lower_loop() {
    // Argument 0: stop after 5 A/D interrupts.
    let mut b = Bench::new(image_with(
        &wasm(
            r#"(module
          (import "kernel" "affiche" (func $affiche (param i32 i32 i32)))
          (import "kernel" "pwm" (func $pwm (param i32 i32)))
          (import "kernel" "arg" (func $arg (param i32) (result i32)))
          (memory (export "memory") 1)
          (data (i32.const 16) "hello from wasm")
          (global $n (mut i32) (i32.const 0))
          (func (export "init_prog") (result i32)
            (call $affiche (i32.const 15) (i32.const 8) (i32.const 16))
            (i32.const 0x8000))
          (func (export "AD_prog") (result i32)
            (global.set $n (i32.add (global.get $n) (i32.const 1)))
            (call $pwm (i32.const 1) (global.get $n))
            ;; the count as an unsigned word at 0, shown with a newline
            (i32.store16 (i32.const 0) (global.get $n))
            (if (result i32) (i32.eq (global.get $n) (call $arg (i32.const 0)))
              (then (call $affiche (i32.const 1) (i32.const 13) (i32.const 0))
                    (i32.const 0x18000))
              (else (i32.const 0x8000)))))"#,
        ),
        [5, 0, 0, 0, 0, 0, 0],
    ));
    let m = b.start(0, true, 100);
    assert_eq!(m[0], COMPLETED);
    assert_eq!(m[1], text("hello from wasm"));
    assert_eq!(
        m[2],
        Message::Thread(Thread::Display {
            format: DisplayFormat::Unsigned16,
            newline: true,
            data: vec![5, 0]
        })
    );
    assert_eq!(m.len(), 3, "{m:?}");
    assert_eq!(b.board.pwm()[1], 5);
    assert_eq!(b.board.mode(), Mode::Upper);
}

const SPIN: &str = r#"(module
  (import "kernel" "affiche" (func $affiche (param i32 i32 i32)))
  (memory (export "memory") 1)
  (data (i32.const 0) "spinning")
  (func (export "init_prog") (result i32)
    (call $affiche (i32.const 8) (i32.const 8) (i32.const 0))
    (i32.const 0x8000))
  (func (export "AD_prog") (result i32)
    (loop $forever (br $forever))
    (i32.const 0x8000))
  (func (export "fin_prog")
    (call $affiche (i32.const 8) (i32.const 8) (i32.const 0))))"#;

#[test]
fn an_endless_loop_is_stopped_by_fuel_with_an_alert_and_a_line_and_the_board_goes_on() {
    let mut b = Bench::with(SPIN);
    let m = b.start(0, true, 50);
    assert_eq!(
        m,
        vec![
            COMPLETED,
            text("spinning"),
            Message::Alert(Alert::USER_PROGRAM_STOPPED),
            text(&format!(
                "program stopped in AD_prog: ran out of fuel: more than 50 ms of CPU time ({} instructions) in one call; an endless loop?",
                abi::HOOK_FUEL
            )),
        ],
        "fin_prog of a stopped program is not called"
    );
    assert_eq!(b.board.mode(), Mode::Upper);
    // The board answers, and the same set starts again (a fresh instance).
    let again = b.start(0, true, 5);
    assert_eq!(again[..2], [COMPLETED, text("spinning")]);
}

#[test]
fn traps_misuse_and_bad_results_stop_the_program_with_their_reason() {
    for (body, why) in [
        ("(unreachable)", "program stopped in init_prog: trapped: "),
        (
            "(call $pwm (i32.const 7) (i32.const 1)) (i32.const 0x8000)",
            "program stopped in init_prog: pwm: output 7 is out of range 0..2",
        ),
        (
            "(i32.const 0x20000)",
            "program stopped in init_prog: returned 20000h; a hook returns ContExec 8000h, StopExec 18000h or a START word (bits 17..31 zero)",
        ),
        (
            "(call $affiche (i32.const 10) (i32.const 0) (i32.const 65530)) (i32.const 0x8000)",
            "program stopped in init_prog: affiche: bytes 65530..65540 are outside the module's memory (65536 bytes)",
        ),
        (
            "(call $affiche (i32.const 1) (i32.const 1) (i32.const 0)) (i32.const 0x8000)",
            "program stopped in init_prog: affiche: format 1 is none (0 text, 2..7 numbers; +8 newline)",
        ),
        (
            "(call $alerte (i32.const 0x20)) (i32.const 0x8000)",
            "program stopped in init_prog: alerte: alert 32 is out of range 48..63",
        ),
    ] {
        let mut b = Bench::with(&format!(
            r#"(module
              (import "kernel" "affiche" (func $affiche (param i32 i32 i32)))
              (import "kernel" "pwm" (func $pwm (param i32 i32)))
              (import "kernel" "alerte" (func $alerte (param i32)))
              (memory (export "memory") 1)
              (func (export "init_prog") (result i32) {body}))"#
        ));
        let m = b.start(1, false, 50);
        assert_eq!(
            m[..2],
            [COMPLETED, Message::Alert(Alert::USER_PROGRAM_STOPPED)]
        );
        let line = &texts(&m)[0];
        assert!(line.starts_with(why), "{body}: {line}");
        assert_eq!(b.board.mode(), Mode::Upper, "{body}");
    }
}

#[test]
fn too_much_output_in_one_call_is_refused_not_queued() {
    let mut b = Bench::with(
        r#"(module
          (import "kernel" "fwrite" (func $fwrite (param i32 i32 i32)))
          (memory (export "memory") 1)
          (func (export "init_prog") (result i32)
            (loop $l (call $fwrite (i32.const 0) (i32.const 200) (i32.const 0)) (br $l))
            (i32.const 0x8000)))"#,
    );
    let m = b.start(1, false, 500);
    let writes = m
        .iter()
        .filter(|m| matches!(m, Message::Thread(Thread::Write { .. })))
        .count();
    // 4096 bytes at 205 per write: 19 writes leave, the 20th is the misuse.
    assert_eq!(writes, 19);
    assert_eq!(
        texts(&m),
        [
            "program stopped in init_prog: fwrite: more than 4096 bytes for the PC in one call (the kernel's transmit FIFO)"
        ]
    );
}

#[test]
fn timers_files_user_commands_and_a_start_from_a_hook() {
    let mut b = Bench::with(
        r#"(module
          (import "kernel" "fopen" (func $fopen (param i32 i32 i32) (result i32)))
          (import "kernel" "fwrite" (func $fwrite (param i32 i32 i32)))
          (import "kernel" "fread" (func $fread (param i32 i32)))
          (import "kernel" "fclose" (func $fclose (param i32)))
          (import "kernel" "affiche" (func $affiche (param i32 i32 i32)))
          (import "kernel" "user_command" (func $user_command (param i32 i32)))
          (import "kernel" "event_data" (func $event_data (param i32 i32) (result i32)))
          (memory (export "memory") 1)
          (data (i32.const 0) "log.txt")
          (global $f (mut i32) (i32.const 0))
          (global $ticks (mut i32) (i32.const 0))
          (func (export "init_prog") (result i32)
            (global.set $f (call $fopen (i32.const 7) (i32.const 0) (i32.const 1)))
            (call $user_command (i32.const 0x20) (i32.const 3))
            (i32.const 0x8000))
          (func (export "pas_prog1") (result i32)
            (global.set $ticks (i32.add (global.get $ticks) (i32.const 1)))
            (call $fwrite (global.get $f) (i32.const 3) (i32.const 0))
            (call $fread (global.get $f) (i32.const 2))
            ;; after 3 ticks: stop, and START bank 2 set 1 again (a START word)
            (if (result i32) (i32.eq (global.get $ticks) (i32.const 3))
              (then (i32.const 0x10211))
              (else (i32.const 0x8000))))
          (func (export "RS_prog") (param $cmd i32) (param $n i32)
            (drop (call $event_data (i32.const 100) (i32.const 16)))
            (call $affiche (local.get $n) (i32.const 10) (i32.const 100)))
          (func (export "Main_Fread") (param $f i32) (param $n i32)
            (drop (call $event_data (i32.const 200) (local.get $n)))
            (call $affiche (local.get $n) (i32.const 8) (i32.const 200)))
          (func (export "fin_prog") (call $fclose (global.get $f))))"#,
    );
    b.send(&Message::Start(Start::run(BANK, 1, false)));
    b.run_for(MS / 2);
    // A user command with the 3 parameters the module declared.
    b.send(&Message::User {
        cmd: 0x20,
        params: vec![7, 8, 9],
    });
    // The PC's answer to a read request.
    b.send(&Message::Thread(Thread::ReadData {
        data: b"ok".to_vec(),
        file: 0,
    }));
    b.run_for(50 * MS);
    let m = b.take();
    assert_eq!(m[0], COMPLETED);
    assert_eq!(
        m[1],
        Message::Thread(Thread::Open {
            mode: FileMode::Write,
            name: b"log.txt".to_vec(),
            file: 0
        })
    );
    assert!(
        m.contains(&Message::Thread(Thread::Display {
            format: DisplayFormat::Hex8,
            newline: true,
            data: vec![7, 8, 9]
        })),
        "{m:?} {:?}",
        b.board.take_log()
    );
    assert!(m.contains(&text("ok")));
    let writes = m
        .iter()
        .filter(|m| {
            **m == Message::Thread(Thread::Write {
                data: b"log".to_vec(),
                file: 0,
            })
        })
        .count();
    // Three ticks, then the hook's START (0211h: bank 2 set 1 again, with a new file handle):
    // fin_prog closed file 0, the new run opened file 1 and ticks on.
    assert!(writes >= 3, "{m:?}");
    assert!(m.contains(&Message::Thread(Thread::Close { file: 0 })));
    assert!(m.contains(&Message::Thread(Thread::Open {
        mode: FileMode::Write,
        name: b"log.txt".to_vec(),
        file: 1
    })));
    assert_eq!(
        b.board.mode(),
        Mode::Lower {
            bank: BANK,
            config: 1
        }
    );
}

#[test]
fn a_set_naming_no_module_or_an_erased_one_is_refused_with_the_reason_on_the_display() {
    let mut b = Bench::with(SPIN);
    let m = b.start(2, false, 50);
    assert_eq!(
        m,
        [
            text(
                "configuration 2: the module at bank 2 block 80h: no module starts at bank 2 block 80h (its first bytes are [FF, FF, FF, FF], not `W196`); flash one with `buslab cpu196 program flash`"
            ),
            Message::Msg(MsgCode::INVALID_PARAMETER_VALUE)
        ]
    );
    // F5 03: the bank erased, the module with it.
    b.send(&Message::FlashErase { bank: BANK });
    b.run_for(5 * MS);
    assert_eq!(b.take(), [COMPLETED]);
    let m = b.start(1, false, 50);
    assert_eq!(m, [Message::Msg(MsgCode::INVALID_PARAMETER_VALUE)]);
    assert!(
        b.board
            .take_log()
            .iter()
            .any(|l| l.contains("bank 2 holds no valid configuration table"))
    );
}

#[test]
fn cpuformat_new_serial_erases_the_module_with_all_flash() {
    let mut b = Bench::with(SPIN);
    let nsc = buslab_cpu196::image::encrypt_serial(&b.board.image().serial);
    b.send(&Message::Format(Format::NewSerial {
        nsc,
        new: *b"NEW00002",
    }));
    b.run_for(5 * MS);
    assert_eq!(b.take(), [COMPLETED]);
    let flash = &b.board.image().flash;
    assert!(flash.is_blank(BANK, DEFAULT_BLOCK));
    assert!(matches!(
        layout::read(flash, BANK, DEFAULT_BLOCK),
        Err(layout::LayoutError::NoModule { .. })
    ));
    assert_eq!(
        b.start(1, false, 5),
        [Message::Msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
}

#[test]
fn a_board_without_the_runtime_says_so() {
    let mut board = Board::new(
        image_with(&wasm(SPIN), [0; 7]),
        Inputs::default(),
        Nanos::ZERO,
    );
    for b in Message::Start(Start::run(BANK, 1, false))
        .to_bytes()
        .unwrap()
    {
        board.receive(Nanos::ZERO, b);
    }
    assert!(
        board
            .take_log()
            .iter()
            .any(|l| l.ends_with("cannot run: this board has no module runtime"))
    );
}

#[test]
fn the_image_file_keeps_the_module() {
    let image = image_with(&wasm(SPIN), [0; 7]);
    let text = String::from_utf8(Board::file_bytes(&image)).unwrap();
    let back = Image::from_toml(&text).unwrap();
    let mut b = Bench::new(back);
    assert_eq!(
        b.start(1, false, 5)[..2],
        [COMPLETED, self::text("spinning")]
    );
}

#[test]
fn modules_are_checked_against_the_contract_with_errors_naming_the_fault() {
    let rt = WasmRuntime::new();
    let check = |t: &str| rt.check(&wasm(t)).map(|i| i.hooks);
    assert_eq!(
        check(r#"(module (func (export "AD_prog") (result i32) (i32.const 0x8000)))"#),
        Ok(vec![Hook::Ad])
    );
    let err = |t: &str| check(t).unwrap_err().to_string();
    assert_eq!(
        err(r#"(module (import "env" "printf" (func)) (func (export "fin_prog")))"#),
        "imports `env.printf`: the kernel API is the import module `kernel` (docs/cpu196.md)"
    );
    assert!(
        err(r#"(module (import "kernel" "printf" (func)) (func (export "fin_prog")))"#)
            .starts_with(
                "imports `kernel.printf`, which is no kernel service (known: affiche, fopen,"
            )
    );
    assert_eq!(
        err(r#"(module (import "kernel" "pwm" (func (param i32))) (func (export "fin_prog")))"#),
        "imports `kernel.pwm` as (i32); it is (i32, i32)"
    );
    assert_eq!(
        err(r#"(module (func (export "AD_Prog") (result i32) (i32.const 0)))"#),
        "exports the function `AD_Prog`, which is no hook (hooks: init_prog, user_prog, RS_prog, pic_prog, pas_prog1, pas_prog2, AD_prog, fin_prog, Main_Fread)"
    );
    assert_eq!(
        err(r#"(module (func (export "AD_prog")))"#),
        "exports the hook `AD_prog` as (); it is () -> i32"
    );
    assert!(err("(module)").starts_with("exports no hook"));
    assert_eq!(
        err(r#"(module (memory (export "memory") 5) (func (export "fin_prog")))"#),
        "asks for 5 pages of memory at start; at most 4 (64 KiB each)"
    );
    assert_eq!(
        err(r#"(module (memory (export "mem") 1) (func (export "fin_prog")))"#),
        "exports its memory as `mem`; the kernel reads and writes it only under the name `memory`"
    );
    assert_eq!(
        err(
            r#"(module (import "kernel" "affiche" (func (param i32 i32 i32))) (func (export "fin_prog")))"#
        ),
        "imports `kernel.affiche`, which reads or writes the module's memory, but exports no `memory`"
    );
    // A memory not exported is checked at instantiation.
    assert!(
        err(r#"(module (memory 9) (func (export "fin_prog")))"#)
            .starts_with("cannot be instantiated"),
    );
    assert!(matches!(
        rt.check(b"\0asm\x01\0\0\0garbage"),
        Err(ModuleError::Invalid(_))
    ));
    assert_eq!(
        rt.check(&vec![0; layout::MAX_MODULE + 1]),
        Err(ModuleError::TooLarge(layout::MAX_MODULE + 1))
    );
}

#[test]
fn every_kernel_service_of_the_table_is_defined_with_its_signature() {
    let rt = WasmRuntime::new();
    let ty = |t: &[abi::Ty]| {
        t.iter()
            .map(|t| match t {
                abi::Ty::I32 => "i32",
                abi::Ty::I64 => "i64",
            })
            .collect::<Vec<_>>()
            .join(" ")
    };
    for s in abi::IMPORTS {
        let module = format!(
            r#"(module (import "kernel" "{}" (func (param {}) (result {}))) (memory (export "memory") 1) (func (export "fin_prog")))"#,
            s.name,
            ty(s.params),
            ty(s.results)
        );
        rt.check(&wasm(&module))
            .unwrap_or_else(|e| panic!("{}: {e}", s.name));
    }
}

#[test]
fn memory_grows_only_to_the_limit() {
    let mut b = Bench::with(
        r#"(module
          (import "kernel" "affiche" (func $affiche (param i32 i32 i32)))
          (memory (export "memory") 1)
          (func (export "init_prog") (result i32)
            (i32.store16 (i32.const 0) (memory.grow (i32.const 3)))
            (i32.store16 (i32.const 2) (memory.grow (i32.const 1)))
            (call $affiche (i32.const 2) (i32.const 15) (i32.const 0))
            (i32.const 0x8000)))"#,
    );
    let m = b.start(1, false, 5);
    // 1 + 3 pages: granted (the old size, 1); one more: refused (-1).
    assert_eq!(
        m[1],
        Message::Thread(Thread::Display {
            format: DisplayFormat::Signed16,
            newline: true,
            data: vec![1, 0, 0xFF, 0xFF]
        })
    );
}

#[test]
fn the_client_reports_why_the_board_refused_a_start() {
    use buslab_cpu196::host::{Client, ClientError};
    use buslab_device::SimPort;
    let mut board = Board::new(
        image_with(&wasm(SPIN), [0; 7]),
        Inputs::default(),
        Nanos::ZERO,
    );
    board
        .registry_mut()
        .set_module_runtime(Box::new(WasmRuntime::new()));
    let line = board.line();
    let mut c = Client::new(SimPort::new(board, line, Nanos::ZERO), line.baud);
    match c.start(Start::run(BANK, 2, false)) {
        Err(e @ ClientError::StartRefused { .. }) => assert_eq!(
            e.to_string(),
            "the board answered msg_invalid_parameter_value: the module at bank 2 block 80h: no module starts at bank 2 block 80h (its first bytes are [FF, FF, FF, FF], not `W196`); flash one with `buslab cpu196 program flash`"
        ),
        other => panic!("{other:?}"),
    }
    // The line was the reason, not traffic left for later.
    assert!(
        !c.take_backlog()
            .iter()
            .any(|m| matches!(m, Message::Thread(_)))
    );
    c.start(Start::run(BANK, 1, false)).unwrap();
}

/// wasmi 2.0.0's translator asserts (a debug assertion) that its control stack is not empty
/// when it meters the fuel of an operator; an operator after a function's final `end` reached
/// it before validation refused the body (found by the cpu196_wasm fuzz target).
#[test]
fn regression_an_operator_after_a_functions_end_is_refused_not_a_panic() {
    let module = [
        &b"\0asm\x01\0\0\0"[..],
        // type section: () -> i32
        &[0x01, 0x05, 0x01, 0x60, 0x00, 0x01, 0x7F],
        // function section: one function of type 0
        &[0x03, 0x02, 0x01, 0x00],
        // export section: "AD_prog" func 0
        &[0x07, 0x0B, 0x01, 0x07],
        b"AD_prog",
        &[0x00, 0x00],
        // code section: no locals; i32.const 0, end, local.get 0, end
        &[
            0x0A, 0x08, 0x01, 0x06, 0x00, 0x41, 0x00, 0x0B, 0x20, 0x00, 0x0B,
        ],
    ]
    .concat();
    let e = WasmRuntime::new().check(&module).unwrap_err();
    assert!(matches!(e, ModuleError::Invalid(_)), "{e}");
    let fuzzed =
        include_bytes!("../../../fuzz/corpus/cpu196_wasm/regression-operator-after-function-end");
    assert!(matches!(
        WasmRuntime::new().check(fuzzed),
        Err(ModuleError::Invalid(_))
    ));
}
