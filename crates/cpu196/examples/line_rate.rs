//! Line-rate benchmark over a real pseudo-terminal: flash bank read, PIC block write and read,
//! and A/D streaming at the highest rate the line allows. Prints a table.
//!
//! `cargo run --release -p buslab-cpu196 --example line_rate [-- --seconds S]`

use std::time::{Duration, Instant};

use buslab_cpu196::adconfig::{AdConfig, SampleFormat};
use buslab_cpu196::board::MAX_LINE_SHARE;
use buslab_cpu196::host::Client;
use buslab_cpu196::image::{Image, demo_sets};
use buslab_cpu196::message::{Message, Start};
use buslab_cpu196::source::Inputs;
use buslab_cpu196::{Board, prginf};
use buslab_device::Nanos;
use buslab_link::{LineSettings, SerialLine, Serve, Served};

fn connect(s: &Served<Board>, baud: u32) -> Client<SerialLine> {
    let port = SerialLine::open(s.path(), LineSettings::n81(baud)).unwrap();
    let mut c = Client::new(port, baud);
    while c.next(Duration::from_millis(30)).unwrap().is_some() {}
    c
}

/// Payload bytes per second as a share of the line's character rate (8N1: baud / 10).
fn share(bytes: usize, secs: f64, baud: u32) -> f64 {
    100.0 * bytes as f64 / secs / (baud as f64 / 10.0)
}

/// The fastest acquisition the kernel accepts at `baud`: 16-bit samples, 16 scans per `FA`
/// frame, as many channels as fit (8, 4, 2, 1) with the shortest time base T.
fn fastest(baud: u32) -> AdConfig {
    let byte_ns = LineSettings::n81(baud).byte_time().get() as f64;
    for channels in [8u8, 4, 2, 1] {
        let list: Vec<u8> = (0..channels).collect();
        for t in 0..=255u8 {
            let cfg = AdConfig::simple(&list, SampleFormat::Bits16, t, 4);
            let frame_bytes = (cfg.frame_data_len().unwrap() + 3) as f64;
            if frame_bytes * byte_ns / (cfg.period_ns() * 16).get() as f64 <= MAX_LINE_SHARE {
                return cfg;
            }
        }
    }
    unreachable!("one channel at T = 255 fits any offered rate")
}

fn main() {
    let seconds: f64 = std::env::args()
        .skip_while(|a| a != "--seconds")
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(5.0);
    println!("| baud | operation | payload | time | payload rate | % of line rate |");
    println!("|---|---|---|---|---|---|");
    for baud in [115_200u32, 250_000] {
        let mut image = Image::default();
        let mut sets = demo_sets();
        let cfg = fastest(baud);
        sets[0].ad_init = cfg.encode();
        let (a, p) = prginf::encode(&sets);
        // Bank 1 ships with a demo set; the benchmark's sets replace it.
        image.flash.erase(1).unwrap();
        image.flash.write(1, prginf::PRGINF_BLOCK, &a).unwrap();
        image.flash.write(1, prginf::PTRPRG_BLOCK, &p).unwrap();
        for block in 0x60..=0xFF {
            image.flash.write(2, block, &[block; 256]).unwrap();
        }
        let mut board = Board::new(image, Inputs::default(), Nanos::ZERO);
        board.set_baud(baud);
        let line = board.line();
        let served = Serve::new(board, line).name("cpu196").spawn().unwrap();
        let mut c = connect(&served, baud);
        let row = |op: &str, bytes: usize, secs: f64| {
            println!(
                "| {baud} | {op} | {bytes} B | {:.3} s | {:.0} B/s | {:.1} % |",
                secs,
                bytes as f64 / secs,
                share(bytes, secs, baud)
            );
        };

        let t = Instant::now();
        let bank = c.flash_read_bank(2, &mut |_| {}).unwrap();
        row(
            "flash bank read (256 blocks)",
            bank.len(),
            t.elapsed().as_secs_f64(),
        );
        assert_eq!(bank[0x6000], 0x60);

        let pic: [u8; 4096] = core::array::from_fn(|i| i as u8);
        let t = Instant::now();
        // The write alone (16 × msg_completed), then the read-back separately.
        c.send(&Message::PicWrite {
            block: 1,
            data: Box::new(pic),
        })
        .unwrap();
        let mut done = 0;
        while done < 16 {
            if let Some(Message::Msg(_)) = c.next(Duration::from_secs(2)).unwrap() {
                done += 1;
            }
        }
        row("PIC block write (4096 B)", 4096, t.elapsed().as_secs_f64());
        let t = Instant::now();
        let back = c.pic_read(1).unwrap();
        row("PIC block read (4096 B)", 4096, t.elapsed().as_secs_f64());
        assert_eq!(*back, pic);

        // Streaming.
        c.start(Start::run(1, 0, true)).unwrap();
        let t = Instant::now();
        let (mut frames, mut bytes) = (0u64, 0usize);
        let mut last_ping = Instant::now();
        while t.elapsed().as_secs_f64() < seconds {
            if last_ping.elapsed() > Duration::from_millis(500) {
                c.send(&Message::Watchdog).unwrap();
                last_ping = Instant::now();
            }
            if let Some(Message::AdCont(d)) = c.next(Duration::from_millis(20)).unwrap() {
                frames += 1;
                bytes += d.len();
            }
        }
        let secs = t.elapsed().as_secs_f64();
        c.stop().unwrap();
        for m in c.take_backlog() {
            if let Message::AdCont(d) = m {
                frames += 1;
                bytes += d.len();
            }
        }
        let stats = served.with(|b, _| b.stats()).unwrap();
        let rate = 1e9 / cfg.period_ns().get() as f64;
        row(
            &format!(
                "A/D stream, {} ch × 16 bit at {rate:.0} scans/s (T = {}): {frames} frames, board sent {}, dropped {}, damaged {}",
                cfg.sequence.len(),
                cfg.time_base,
                stats.fa_sent,
                stats.fa_dropped,
                c.frame_errors.count()
            ),
            bytes,
            secs,
        );
        assert_eq!(stats.fa_dropped, 0);
        assert_eq!(frames, stats.fa_sent, "frames lost between board and host");
        assert!(c.frame_errors.is_empty(), "{:?}", c.frame_errors);
    }
}
