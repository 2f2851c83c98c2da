//! CPU196 user programs: arbitrary bytes as a WebAssembly module, checked as `program flash`
//! checks it and, when accepted, stored in flash and run by the board (a set with the A/D at
//! 1 kHz, one with software timer 1 every ms, user commands and an external interrupt): no
//! panic, a refusal names its reason, every hook call ends within its fuel (libFuzzer's
//! time-out catches one that does not), the lower loop ends, and the board still answers a
//! watchdog afterwards.
#![no_main]

use std::sync::OnceLock;

use buslab_cpu196::message::{Message, Start};
use buslab_cpu196::prginf::{self, ConfigSet, PRGINF_BLOCK, PTRPRG_BLOCK};
use buslab_cpu196::program::{ProgramRef, Registry};
use buslab_cpu196::source::Inputs;
use buslab_cpu196::{Board, ByteDevice, Decoder, Event, Image, Mode};
use buslab_cpu196_wasm::WasmRuntime;
use buslab_cpu196_wasm::layout::{self, DEFAULT_BLOCK};
use buslab_device::Nanos;
use libfuzzer_sys::fuzz_target;

const BANK: u8 = 2;

/// The default image with bank 2's set 0 = bank 0's set 0 (four channels at 1 kHz) and set 1 =
/// timer 1 every ms, both running the module at 60h.
fn image_with(module: &[u8]) -> Option<Image> {
    static IMAGE: OnceLock<Image> = OnceLock::new();
    let mut image = IMAGE.get_or_init(Image::default).clone();
    let a = image.flash.read(0, PRGINF_BLOCK).ok()?;
    let p = image.flash.read(0, PTRPRG_BLOCK).ok()?;
    let set0 = prginf::read_config(a, p, 0)?;
    let word = ProgramRef::Module {
        bank: BANK,
        block: DEFAULT_BLOCK,
    }
    .word()?;
    let mut sets: [ConfigSet; 8] = Default::default();
    sets[0] = ConfigSet {
        program: word,
        args: [3; 7],
        ..set0
    };
    sets[1] = ConfigSet {
        program: word,
        cycle1: 1250,
        ..Default::default()
    };
    let (a, p) = prginf::encode(&sets);
    image.flash.write(BANK, PRGINF_BLOCK, &a).ok()?;
    image.flash.write(BANK, PTRPRG_BLOCK, &p).ok()?;
    for (k, data) in layout::encode("fuzz", module, DEFAULT_BLOCK).ok()? {
        image.flash.write(BANK, k, &data).ok()?;
    }
    Some(image)
}

fn send(board: &mut Board, now: &mut Nanos, m: &Message) {
    for b in m.to_bytes().expect("encodable") {
        *now += board.line().byte_time();
        board.receive(*now, b);
    }
}

fn run_for(board: &mut Board, now: &mut Nanos, d: Nanos, out: &mut Vec<u8>) {
    let end = *now + d;
    while let Some(t) = board.next_deadline().filter(|&t| t <= end) {
        *now = t.max(*now);
        board.poll(*now, out);
    }
    *now = end;
    board.poll(*now, out);
}

fuzz_target!(|data: &[u8]| {
    static RUNTIME: OnceLock<WasmRuntime> = OnceLock::new();
    let runtime = RUNTIME.get_or_init(WasmRuntime::new);
    if let Err(e) = runtime.check(data) {
        assert!(!e.to_string().is_empty());
        return;
    }
    let Some(image) = image_with(data) else {
        return;
    };
    let mut programs = Registry::default();
    programs.set_module_runtime(Box::new(WasmRuntime::new()));
    let mut board = Board::with_registry(image, Inputs::default(), programs, Nanos::ZERO);
    let mut now = Nanos::ZERO;
    let mut out = Vec::new();
    let ms = Nanos::from_millis(1);
    for (config, ad) in [(0, true), (1, false)] {
        send(
            &mut board,
            &mut now,
            &Message::Start(Start::run(BANK, config, ad)),
        );
        run_for(&mut board, &mut now, 2 * ms, &mut out);
        board.external_interrupt(now);
        send(
            &mut board,
            &mut now,
            &Message::User {
                cmd: 0x10,
                params: vec![],
            },
        );
        run_for(&mut board, &mut now, 3 * ms, &mut out);
        send(&mut board, &mut now, &Message::Stop);
        run_for(&mut board, &mut now, 20 * ms, &mut out);
    }
    // Whatever the program queued drains; the PC silent for 3 s ends any run (link lost).
    run_for(&mut board, &mut now, Nanos::from_secs(5), &mut out);
    assert!(
        !matches!(board.mode(), Mode::Lower { .. }),
        "the lower loop outlived the PC's silence"
    );
    // Still the kernel: a watchdog gets its answer.
    out.clear();
    send(&mut board, &mut now, &Message::Watchdog);
    run_for(&mut board, &mut now, 100 * ms, &mut out);
    let mut decoder = Decoder::new();
    let answered = out.iter().any(|&b| {
        matches!(
            decoder.push(now, b),
            Some(Event::Message(Message::Watchdog))
        )
    });
    assert!(answered, "no watchdog answer after the program ran");
});
