//! The kernel model in virtual time: every command, the lower loop, acquisition, hooks, errors.

use buslab_cpu196::acquisition::{LogTable, decode_frame};
use buslab_cpu196::adconfig::{AdConfig, SampleFormat};
use buslab_cpu196::codes::{Alert, MsgCode};
use buslab_cpu196::message::*;
use buslab_cpu196::source::{Inputs, Shape, Source};
use buslab_cpu196::wire;
use buslab_cpu196::{Board, Decoder, Event, FrameError, Image, Mode};
use buslab_device::{ByteDevice, Nanos};

const MS: Nanos = Nanos::from_millis(1);

/// A board and a PC-side decoder, driven in virtual time.
struct Bench {
    board: Board,
    host: Decoder,
    now: Nanos,
    /// Events with the time their last byte arrived.
    seen: Vec<(Nanos, Event)>,
}

impl Bench {
    fn new() -> Self {
        Self::with(Image::default(), Inputs::default())
    }

    fn with(image: Image, inputs: Inputs) -> Self {
        let mut b = Self {
            board: Board::new(image, inputs, Nanos::ZERO),
            host: Decoder::new(),
            now: Nanos::ZERO,
            seen: Vec::new(),
        };
        b.run_for(MS);
        assert_eq!(b.take(), vec![Message::Power(Power::WasReset)]);
        b
    }

    fn byte_ns(&self) -> Nanos {
        self.board.line().byte_time()
    }

    fn run_until(&mut self, t: Nanos) {
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
                if let Some(e) = self.host.push(next, b) {
                    self.seen.push((next, e));
                }
            }
            if next >= t {
                break;
            }
        }
    }

    fn run_for(&mut self, d: Nanos) {
        self.run_until(self.now + d);
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.run_for(self.byte_ns());
            self.board.receive(self.now, b);
        }
    }

    fn send(&mut self, m: &Message) {
        self.write(&m.to_bytes().unwrap());
    }

    /// Sends `m`, waits `ms`, returns the messages that came back.
    fn ask(&mut self, m: &Message, ms: u64) -> Vec<Message> {
        self.send(m);
        self.run_for(ms * MS);
        self.take()
    }

    fn take(&mut self) -> Vec<Message> {
        self.seen
            .drain(..)
            .map(|(_, e)| match e {
                Event::Message(m) => m,
                Event::Error(e) => panic!("host saw a frame error: {e}"),
                other => panic!("the board sent {other:?}"),
            })
            .filter(|m| *m != Message::Watchdog)
            .collect()
    }
}

fn msg(c: MsgCode) -> Message {
    Message::Msg(c)
}

#[test]
fn cpuinf_reports_the_identity() {
    let mut b = Bench::new();
    let r = b.ask(&Message::CpuInfoRequest, 10);
    let [Message::CpuInfo(info)] = &r[..] else {
        panic!("{r:?}")
    };
    assert_eq!(&info.serial, b"BL196001");
    assert_eq!(info.quartz, 20);
    assert_eq!(info.supply, 70); // PIC channel 0 at 3.5 V through the 1:2 divider
}

#[test]
fn flash_write_read_not_blank_forbidden_erase() {
    let mut b = Bench::new();
    let data: Box<[u8; 256]> = Box::new(core::array::from_fn(|i| i as u8));
    let write = Message::FlashWrite {
        bank: 2,
        block: 0x80,
        data: data.clone(),
    };
    assert_eq!(b.ask(&write, 50), vec![msg(MsgCode::COMPLETED)]);
    assert_eq!(
        b.ask(
            &Message::FlashReadRequest {
                bank: 2,
                block: 0x80
            },
            50
        ),
        vec![Message::FlashData(data.clone())]
    );
    assert_eq!(b.ask(&write, 50), vec![msg(MsgCode::NOT_BLANK_ERROR)]);
    let forbidden = Message::FlashWrite {
        bank: 2,
        block: 0x03,
        data: data.clone(),
    };
    assert_eq!(
        b.ask(&forbidden, 50),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    assert_eq!(
        b.ask(&Message::FlashReadRequest { bank: 9, block: 0 }, 50),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    assert_eq!(
        b.ask(&Message::FlashErase { bank: 2 }, 50),
        vec![msg(MsgCode::COMPLETED)]
    );
    assert_eq!(b.ask(&write, 50), vec![msg(MsgCode::COMPLETED)]);
    assert!(b.board.take_dirty());
    assert_eq!(b.board.image().flash.read(2, 0x80).unwrap(), &data[..]);
}

#[test]
fn pic_program_blocks_and_eeprom() {
    let mut b = Bench::new();
    let data: Box<[u8; 4096]> = Box::new(core::array::from_fn(|i| (i * 7) as u8));
    let r = b.ask(
        &Message::PicWrite {
            block: 2,
            data: data.clone(),
        },
        100,
    );
    assert_eq!(r, vec![msg(MsgCode::COMPLETED); 16]);
    assert_eq!(
        b.ask(&Message::PicReadRequest { block: 2 }, 500),
        vec![Message::PicData(data)]
    );
    assert_eq!(
        b.ask(&Message::PicReadRequest { block: 0 }, 10),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    let ee: Box<[u8; 256]> = Box::new([0x42; 256]);
    assert_eq!(
        b.ask(&Message::EepromWrite(ee.clone()), 50),
        vec![msg(MsgCode::COMPLETED)]
    );
    assert_eq!(
        b.ask(&Message::EepromReadRequest, 50),
        vec![Message::EepromData(ee)]
    );
}

/// Seed 000, F6 `02`: "écriture du N° bloc de 1k, réponse d'un message msg_completed tous les
/// 256 octets (16 fois)". The acknowledgements are flow control: each comes as its 256 bytes
/// are in, and a host that waits for it before sending more gets it.
#[test]
fn a_pic_block_write_is_acknowledged_every_256_bytes_as_the_data_arrives() {
    let mut b = Bench::new();
    let data: Box<[u8; 4096]> = Box::new(core::array::from_fn(|i| (i * 7) as u8));
    let bytes = Message::PicWrite {
        block: 3,
        data: data.clone(),
    }
    .to_bytes()
    .unwrap();
    // Command, complement, sub-code, block, then 16 × 256 data bytes.
    let (head, body) = bytes.split_at(4);
    b.write(head);
    for (i, chunk) in body.chunks(256).enumerate() {
        b.write(chunk);
        // The host waits for the acknowledgement (3 bytes) before the next chunk.
        b.run_for(4 * b.byte_ns());
        assert_eq!(b.take(), vec![msg(MsgCode::COMPLETED)], "chunk {i}");
        // Written already: a kill now keeps what was acknowledged.
        let at = 2 * 4096 + i * 256;
        assert_eq!(
            b.board.pic().program[at..at + 256],
            data[i * 256..(i + 1) * 256]
        );
    }
    b.run_for(300 * MS);
    assert_eq!(
        b.take(),
        vec![],
        "nothing more: no time-out, no reception error"
    );
    assert_eq!(
        b.ask(&Message::PicReadRequest { block: 3 }, 500),
        vec![Message::PicData(data.clone())]
    );
    // A block out of range is refused at once, and only once.
    let bad = Message::PicWrite { block: 4, data };
    assert_eq!(
        b.ask(&bad, 500),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    // In the lower loop, PRGPIC is refused once, not 16 times.
    b.ask(&Message::Start(Start::run(0, 0, false)), 5);
    let write = Message::PicWrite {
        block: 1,
        data: Box::new([0; 4096]),
    };
    let replies: Vec<_> = b
        .ask(&write, 500)
        .into_iter()
        .filter(|m| matches!(m, Message::Msg(_)))
        .collect();
    assert!(matches!(b.board.mode(), Mode::Lower { .. }));
    assert_eq!(replies, vec![msg(MsgCode::INVALID_COMMAND)]);
}

#[test]
fn lower_loop_refuses_nine_commands_and_stop_leaves_it() {
    let mut b = Bench::new();
    let r = b.ask(&Message::Start(Start::run(0, 4, false)), 5);
    assert_eq!(r, vec![msg(MsgCode::COMPLETED)]);
    assert_eq!(b.board.mode(), Mode::Lower { bank: 0, config: 4 });
    let refused = [
        Message::CpuInfoRequest,
        Message::Start(Start::run(0, 0, false)),
        Message::Power(Power::Reset),
        Message::FlashReadRequest {
            bank: 0,
            block: 0x60,
        },
        Message::EepromReadRequest,
        Message::Format(Format::EraseBoot),
        Message::CfgAdRequest { bank: 0, config: 0 },
    ];
    for m in refused {
        assert_eq!(b.ask(&m, 1), vec![msg(MsgCode::INVALID_COMMAND)], "{m:?}");
    }
    // FA/FB from a PC are refused too (the decoder cannot delimit FA: reported as such).
    assert_eq!(
        b.ask(
            &Message::AdSample(AdSample::Pic {
                channel: 0,
                value: 1
            }),
            1
        ),
        vec![msg(MsgCode::INVALID_COMMAND)]
    );
    assert_eq!(b.ask(&Message::Stop, 1), vec![msg(MsgCode::COMPLETED)]);
    assert_eq!(b.board.mode(), Mode::Upper);
    assert!(matches!(
        b.ask(&Message::CpuInfoRequest, 5)[..],
        [Message::CpuInfo(_)]
    ));
    assert_eq!(buslab_cpu196::board::INVALID_IN_LOWER_LOOP.len(), 9);
}

#[test]
fn line_errors_get_the_kernel_messages_and_the_link_recovers() {
    let mut b = Bench::new();
    // Wrong complement.
    b.write(&[wire::CPUINF, 0x00]);
    b.run_for(5 * MS);
    assert_eq!(b.take(), vec![msg(MsgCode::RECEPTION_ERROR)]);
    // The stray 00h waits for its complement and times out.
    b.run_for(300 * MS);
    assert_eq!(b.take(), vec![msg(MsgCode::TIME_OUT)]);
    // A truncated flash write times out and writes nothing.
    let full = Message::FlashWrite {
        bank: 1,
        block: 0x70,
        data: Box::new([9; 256]),
    }
    .to_bytes()
    .unwrap();
    b.write(&full[..100]);
    b.run_for(300 * MS);
    assert_eq!(b.take(), vec![msg(MsgCode::TIME_OUT)]);
    assert!(b.board.image().flash.is_blank(1, 0x70));
    // Random bytes, then a pause: no crash, and the next command works.
    b.write(&[0x13, 0x99, 0xF5, 0xF5, 0x42, 0x00, 0xAB]);
    b.run_for(300 * MS);
    assert!(!b.take().is_empty());
    assert!(matches!(
        b.ask(&Message::CpuInfoRequest, 10)[..],
        [Message::CpuInfo(_)]
    ));
    // An unknown sub-code.
    b.write(&[wire::PRGFLASH, !wire::PRGFLASH, 0x09]);
    b.run_for(5 * MS);
    assert_eq!(b.take(), vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]);
}

#[test]
fn streamed_samples_match_the_sources_within_resolution() {
    let mut inputs = Inputs::default();
    inputs.c196[0] = Source::Wave {
        shape: Shape::Sine,
        offset: 2.5,
        amplitude: 2.0,
        hz: 5.0,
    };
    inputs.c196[1] = Source::Ramp {
        from: 0.0,
        to: 5.0,
        period: Nanos::from_millis(500),
    };
    inputs.c196[2] = Source::Constant(1.25);
    inputs.c196[3] = Source::Constant(3.0);
    let mut b = Bench::with(Image::default(), inputs.clone());
    // Config 5: ch0 16-bit, ch1 10-bit, ch2 8-bit, ch3 log8, 1 kHz, 4 scans per frame.
    b.send(&Message::Start(Start::run(0, 5, true)));
    let t0 = b.now;
    b.run_for(400 * MS);
    let msgs = b.take();
    assert_eq!(msgs[0], msg(MsgCode::COMPLETED));
    let Message::CfgAd { c196, .. } = &msgs[1] else {
        panic!("{:?}", msgs[1])
    };
    let cfg = AdConfig::parse(c196).unwrap();
    let table = LogTable::default();
    let mut scan_no = 0u64;
    for m in &msgs[2..] {
        let Message::AdCont(data) = m else {
            panic!("{m:?}")
        };
        for scan in decode_frame(&cfg, data, &table) {
            scan_no += 1;
            let t = t0 + scan_no * cfg.period_ns();
            for (ch, v) in scan {
                let want = inputs.c196[ch as usize].volts(t) * 1023.0 / 5.0;
                let tol = match cfg.channels[ch as usize].format {
                    SampleFormat::Bits16 | SampleFormat::Bits10 => 0.5,
                    SampleFormat::Bits8 => 4.0,
                    SampleFormat::Log8 => 1023.0 * 0.05,
                };
                assert!(
                    (v - want).abs() <= tol,
                    "scan {scan_no} ch {ch}: {v} vs {want}"
                );
            }
        }
    }
    // 400 ms at 1 kHz, minus the frame still being filled.
    assert!((396..=400).contains(&scan_no), "{scan_no}");
}

#[test]
fn too_fast_acquisition_is_refused() {
    let mut img = Image::default();
    let mut sets = buslab_cpu196::image::demo_sets();
    sets[0].ad_init =
        AdConfig::simple(&[0, 1, 2, 3, 4, 5, 6, 7], SampleFormat::Bits16, 0, 4).encode();
    let (a, p) = buslab_cpu196::prginf::encode(&sets);
    img.flash.erase(0).unwrap();
    img.flash.write(0, 0x28, &a).unwrap();
    img.flash.write(0, 0x29, &p).unwrap();
    let mut b = Bench::with(img, Inputs::default());
    assert_eq!(
        b.ask(&Message::Start(Start::run(0, 0, true)), 5),
        vec![msg(MsgCode::AD_CONFIG_ERROR)]
    );
    assert_eq!(b.board.mode(), Mode::Upper);
}

#[test]
fn watchdog_both_ways() {
    let mut b = Bench::new();
    b.run_for(1500 * MS);
    assert!(
        b.seen
            .iter()
            .any(|(_, e)| *e == Event::Message(Message::Watchdog))
    );
    b.seen.clear();
    assert_eq!(
        b.ask(&Message::Start(Start::run(0, 4, false)), 1),
        vec![msg(MsgCode::COMPLETED)]
    );
    // Keep the link alive for a while: still running.
    for _ in 0..5 {
        b.send(&Message::Watchdog);
        b.run_for(900 * MS);
    }
    assert!(matches!(b.board.mode(), Mode::Lower { .. }) || b.board.pwm() == [0; 3]);
    // Pulse train finished by itself after 10 pulses of 1 ms; start a long-running config.
    b.take();
    assert_eq!(
        b.ask(&Message::Start(Start::run(0, 0, true)), 1)[0],
        msg(MsgCode::COMPLETED)
    );
    b.run_for(3100 * MS);
    let got = b.take();
    assert!(
        got.contains(&Message::Alert(Alert::LINK_LOST)),
        "{:?}",
        &got[got.len().saturating_sub(3)..]
    );
    assert_eq!(b.board.mode(), Mode::Upper);
}

#[test]
fn battery_thresholds_raise_alerts() {
    let mut b = Bench::new();
    b.board.inputs.pic[0] = Source::Constant(2.5); // 8-bit 127: between 100 and 140
    b.run_for(200 * MS);
    assert_eq!(b.take(), vec![Message::Alert(Alert::BATTERY_LOW)]);
    b.board.inputs.pic[0] = Source::Constant(0.5);
    b.run_for(200 * MS);
    assert_eq!(b.take(), vec![Message::Alert(Alert::BATTERY_DISCHARGED)]);
    b.board.inputs.pic[0] = Source::Constant(4.9);
    b.run_for(200 * MS);
    assert_eq!(b.take(), vec![Message::Alert(Alert::BATTERY_MAINS)]);
}

#[test]
fn shipped_programs_run_on_their_hooks() {
    let mut inputs = Inputs::default();
    inputs.c196[0] = Source::Ramp {
        from: 0.0,
        to: 5.0,
        period: Nanos::from_secs(1),
    };
    inputs.c196[1] = Source::Constant(1.0);
    let mut b = Bench::with(Image::default(), inputs);
    // Logger: THREAD text, file open, writes.
    b.send(&Message::Start(Start::run(0, 1, true)));
    b.run_for(2500 * MS);
    b.send(&Message::Stop);
    b.run_for(20 * MS);
    let m = b.take();
    assert!(m.contains(&Message::Thread(Thread::Display {
        format: DisplayFormat::Text,
        newline: true,
        data: b"logger: writing ad.csv".to_vec()
    })));
    assert!(m.iter().any(|x| matches!(x, Message::Thread(Thread::Open { mode: FileMode::Write, name, .. }) if name == b"ad.csv")));
    let writes = m
        .iter()
        .filter(|x| matches!(x, Message::Thread(Thread::Write { .. })))
        .count();
    assert_eq!(
        writes,
        1 + 3,
        "header + one line per 100 interrupts of 8 ms"
    );
    assert!(
        m.iter()
            .any(|x| matches!(x, Message::Thread(Thread::Close { .. })))
    );
    // Threshold alarm on channel 0 > 900.
    b.send(&Message::Start(Start::run(0, 2, true)));
    b.run_for(1000 * MS);
    assert!(b.take().contains(&Message::Alert(Alert::USER_ALARM)));
    // Its user command (2 parameter bytes) and the acknowledge button.
    b.send(&Message::User {
        cmd: 0x10,
        params: vec![0x01, 0x2C],
    });
    b.run_for(5 * MS);
    let text = |t: &str| {
        Message::Thread(Thread::Display {
            format: DisplayFormat::Text,
            newline: true,
            data: t.as_bytes().to_vec(),
        })
    };
    let got = b.take();
    assert!(
        got.contains(&text("threshold = 300")),
        "{got:?} {:?} {:?}",
        b.board.mode(),
        b.board.take_log()
    );
    b.board.external_interrupt(b.now);
    b.run_for(5 * MS);
    assert!(b.take().contains(&text("alarm acknowledged")));
    b.send(&Message::Stop);
    b.run_for(10 * MS);
    b.take();
    // Outside the program, 10h has no parameters again: 01h would be a new command.
    assert_eq!(
        b.ask(
            &Message::User {
                cmd: 0x10,
                params: vec![]
            },
            5
        ),
        vec![msg(MsgCode::INVALID_COMMAND)]
    );
    // Virtual channels.
    b.send(&Message::Start(Start::run(0, 3, true)));
    b.run_for(50 * MS);
    b.send(&Message::Stop);
    b.run_for(10 * MS);
    let v: Vec<_> = b
        .take()
        .into_iter()
        .filter_map(|m| match m {
            Message::AdSample(AdSample::Virtual { channel: 1, value }) => Some(value),
            _ => None,
        })
        .collect();
    assert!(!v.is_empty());
    // Pulse train: PWM 0 toggles on timer 1, stops after 10 pulses.
    b.send(&Message::Start(Start::run(0, 4, false)));
    b.run_for(MS / 2 + MS);
    assert_eq!(b.board.pwm()[0], 128);
    b.run_for(25 * MS);
    assert_eq!(b.board.mode(), Mode::Upper);
    assert_eq!(b.board.pwm()[0], 0);
    assert!(b.take().iter().any(|m| matches!(m, Message::Thread(Thread::Display { data, .. }) if data == b"pulse-train: 10 pulses")));
}

#[test]
fn pic_channels_stream_as_fb_samples() {
    let mut b = Bench::new();
    b.board.inputs.pic[1] = Source::Constant(5.0);
    let s = Start::new(false, true, 0, 7, 0, false, false, false);
    b.send(&Message::Start(s));
    b.run_for(300 * MS);
    let m = b.take();
    assert!(m.contains(&Message::AdSample(AdSample::Pic {
        channel: 1,
        value: 1023
    })));
    assert!(m.contains(&Message::AdSample(AdSample::Pic {
        channel: 0,
        value: 716
    })));
}

#[test]
fn power_down_reset_and_the_power_button() {
    let mut b = Bench::new();
    assert_eq!(
        b.ask(&Message::Power(Power::Reset), 5),
        vec![Message::Power(Power::WasReset)]
    );
    assert_eq!(
        b.ask(&Message::Power(Power::PowerDown), 5),
        vec![Message::Power(Power::PoweredDown)]
    );
    assert_eq!(b.board.mode(), Mode::PoweredDown);
    assert_eq!(b.ask(&Message::CpuInfoRequest, 5), vec![]);
    b.board.power_button(b.now);
    b.run_for(5 * MS);
    assert_eq!(b.take(), vec![Message::Power(Power::WasReset)]);
}

#[test]
fn pwm_bridge_format_and_user_commands() {
    let mut b = Bench::new();
    assert_eq!(
        b.ask(
            &Message::Pwm(Pwm::Set {
                n: 1,
                low: 0,
                value: 77
            }),
            2
        ),
        vec![]
    );
    assert_eq!(b.board.pwm(), [0, 77, 0]);
    b.ask(
        &Message::Pwm(Pwm::Set {
            n: 3,
            low: 2,
            value: 0x80,
        }),
        2,
    );
    assert_eq!(b.board.pic().pwm[0], 0x202);
    assert_eq!(
        b.ask(&Message::Pwm(Pwm::Dac(40)), 2),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    assert_eq!(
        b.ask(&Message::Bridge(Bridge::SpiSend(0x5A)), 2),
        vec![Message::Bridge(Bridge::SpiReceived(0x5A))]
    );
    assert_eq!(
        b.ask(&Message::Bridge(Bridge::SciSend(0x41)), 2),
        vec![Message::Bridge(Bridge::SciReceived(0x41))]
    );
    b.ask(&Message::Bridge(Bridge::ParallelAddress(0x00)), 2);
    b.ask(&Message::Bridge(Bridge::ParallelWrite(0xC3)), 2);
    assert_eq!(
        b.ask(&Message::Bridge(Bridge::ParallelReadRequest), 2),
        vec![Message::Bridge(Bridge::ParallelRead(0xC3))]
    );
    assert_eq!(
        b.ask(
            &Message::User {
                cmd: 0x20,
                params: vec![]
            },
            2
        ),
        vec![msg(MsgCode::INVALID_COMMAND)]
    );
    assert_eq!(
        b.ask(&Message::CfgAdRequest { bank: 3, config: 0 }, 2),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    let r = b.ask(&Message::CfgAdRequest { bank: 0, config: 1 }, 5);
    assert!(matches!(r[..], [Message::CfgAd { .. }]));
    let _ = FrameError::TimeOut {
        cmd: 0,
        received: 0,
    };
}

#[test]
fn cpuformat_is_guarded_and_edits_boot_flash_pic_kernel_and_serial() {
    use buslab_cpu196::image::{BootConfig, encrypt_serial};
    let mut b = Bench::new();
    let nsc = encrypt_serial(b"BL196001");
    let wrong = [0u8; 8];
    assert_eq!(
        b.ask(&Message::Format(Format::ReadPicKernel { nsc: wrong }), 5),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    let kernel: Box<[u8; 4096]> = Box::new(core::array::from_fn(|i| (i % 7) as u8));
    let r = b.ask(
        &Message::Format(Format::WritePicKernel {
            nsc,
            data: kernel.clone(),
        }),
        300,
    );
    assert_eq!(r, vec![msg(MsgCode::COMPLETED); 16]);
    assert_eq!(
        b.ask(&Message::Format(Format::ReadPicKernel { nsc }), 500),
        vec![Message::Format(Format::PicKernel(kernel))]
    );
    // Boot block 5 is the boot configuration.
    let r = b.ask(&Message::Format(Format::ReadBootBlock { block: 5 }), 50);
    let [Message::Format(Format::BootBlock(block))] = &r[..] else {
        panic!("{r:?}")
    };
    let (mut boot, user) = BootConfig::from_csboot(block).unwrap();
    assert_eq!(boot, BootConfig::default());
    assert_eq!(
        b.ask(&Message::Format(Format::ReadBootBlock { block: 4 }), 5),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
    boot.battery_thresholds = [10, 20, 30];
    boot.baud = 9600;
    let new = Box::new(boot.to_csboot(&user));
    assert_eq!(
        b.ask(&Message::Format(Format::WriteBootBlock(new.clone())), 50),
        vec![msg(MsgCode::NOT_BLANK_ERROR)]
    );
    assert_eq!(
        b.ask(&Message::Format(Format::EraseBoot), 5),
        vec![msg(MsgCode::COMPLETED)]
    );
    assert_eq!(
        b.ask(&Message::Format(Format::WriteBootBlock(new)), 50),
        vec![msg(MsgCode::COMPLETED)]
    );
    assert_eq!(b.board.image().boot, boot);
    // New serial number: everything erased, the old NSC no longer opens anything.
    let r = b.ask(
        &Message::Format(Format::NewSerial {
            nsc,
            new: *b"NEW00002",
        }),
        5,
    );
    assert_eq!(r, vec![msg(MsgCode::COMPLETED)]);
    assert_eq!(&b.board.image().serial, b"NEW00002");
    assert!(b.board.image().flash.is_blank(0, 0x28));
    assert_eq!(
        b.ask(&Message::Format(Format::ReadPicKernel { nsc }), 5),
        vec![msg(MsgCode::INVALID_PARAMETER_VALUE)]
    );
}

#[test]
fn emergency_erase_only_right_after_a_reset() {
    let mut b = Bench::new();
    b.run_for(200 * MS);
    let erase = Message::Format(Format::Emergency { xy: 0x03 });
    assert_eq!(b.ask(&erase, 5), vec![msg(MsgCode::INVALID_COMMAND)]);
    assert!(!b.board.image().flash.is_blank(0, 0x28));
    b.send(&Message::Power(Power::Reset));
    b.run_for(MS);
    assert_eq!(b.take(), vec![Message::Power(Power::WasReset)]);
    assert_eq!(b.ask(&erase, 5), vec![msg(MsgCode::COMPLETED)]);
    assert!(b.board.image().flash.is_blank(0, 0x28));
    b.send(&Message::Power(Power::Reset));
    b.run_for(MS);
    b.take();
    let r = b.ask(&Message::Format(Format::Emergency { xy: 0xA0 }), 5);
    assert_eq!(
        r,
        vec![msg(MsgCode::COMPLETED), Message::Power(Power::PoweredDown)]
    );
    assert_eq!(b.board.mode(), Mode::PoweredDown);
}

#[test]
fn pwm_playback_reads_its_pattern_through_the_file_service() {
    let mut b = Bench::new();
    b.send(&Message::Start(Start::run(1, 0, false)));
    b.run_for(5 * MS);
    let m = b.take();
    assert_eq!(m[0], msg(MsgCode::COMPLETED));
    let Message::Thread(Thread::Open {
        mode: FileMode::Read,
        name,
        file,
    }) = &m[1]
    else {
        panic!("{m:?}")
    };
    assert_eq!(name, b"pattern.bin");
    let file = *file;
    assert_eq!(m[2], Message::Thread(Thread::ReadRequest { len: 64, file }));
    // The PC serves the file: 100 bytes, then the end of the file, one answer per request.
    let pattern: Vec<u8> = (0..100).map(|i| (i * 2) as u8).collect();
    b.send(&Message::Msg(MsgCode::NO_ERROR));
    let mut offset = 0;
    let mut requests = 1;
    let answer = |b: &mut Bench, offset: &mut usize| {
        let end = (*offset + 64).min(pattern.len());
        b.send(&Message::Thread(Thread::ReadData {
            data: pattern[*offset..end].to_vec(),
            file,
        }));
        *offset = end;
    };
    answer(&mut b, &mut offset);
    let mut seen = vec![b.board.pwm()[0]];
    let mut rest = Vec::new();
    for _ in 0..300 {
        b.run_for(MS / 2);
        if seen.last() != Some(&b.board.pwm()[0]) {
            seen.push(b.board.pwm()[0]);
        }
        for m in b.take() {
            if m == (Message::Thread(Thread::ReadRequest { len: 64, file })) {
                requests += 1;
                answer(&mut b, &mut offset);
            } else {
                rest.push(m);
            }
        }
    }
    assert_eq!(
        requests, 3,
        "64 + 36 bytes, then the empty read that says end of file"
    );
    let m = rest;
    assert_eq!(b.board.mode(), Mode::Upper);
    assert!(
        m.contains(&Message::Thread(Thread::Close { file })),
        "{m:?}"
    );
    assert!(m.iter().any(|x| matches!(x, Message::Thread(Thread::Display { data, .. }) if data == b"pwm-playback: 100 samples played")), "{m:?}");
    // What PWM 0 showed between our steps is the pattern, in order, up to its last value (the
    // output returns to 0 at the end). All 100 were counted above.
    let played: Vec<u8> = seen.into_iter().filter(|&v| v != 0).collect();
    assert!(played.len() > 50, "{played:?}");
    assert!(played.windows(2).all(|w| w[1] == w[0] + 2), "{played:?}");
    assert_eq!(played.last(), pattern.last());
}

#[test]
fn the_kernel_log_stays_bounded_when_nobody_reads_it() {
    // A served board in `buslab lab` never has its log drained: user commands without a
    // program (each refused and noted) must not grow it without end.
    let mut b = Bench::new();
    for _ in 0..1200 {
        b.write(&[0x10, !0x10]);
    }
    b.run_for(10 * MS);
    let log = b.board.take_log();
    assert!(log.len() <= 1000, "{} log lines kept", log.len());
    assert!(log.last().unwrap().contains("user command 10h"), "{log:?}");
}

#[test]
fn a_pc_flooding_large_requests_does_not_grow_the_reply_queue_without_end() {
    // Each 4-byte PIC block read asks for 4100 bytes: back to back, replies pile up 1000
    // times faster than they leave.
    let mut b = Bench::new();
    let request = Message::PicReadRequest { block: 1 }.to_bytes().unwrap();
    for _ in 0..40 {
        b.write(&request);
    }
    b.run_for(20_000 * MS);
    let blocks = b
        .seen
        .drain(..)
        .filter(|(_, e)| matches!(e, Event::Message(Message::PicData(_))))
        .count();
    assert!(blocks < 40, "all {blocks} replies were queued");
    assert!(blocks >= 10, "only {blocks} replies");
    assert!(b.board.stats().rx_lost > 0);
    // Once the replies have left, the kernel listens again.
    let r = b.ask(&Message::CpuInfoRequest, 10);
    assert!(r.iter().any(|m| matches!(m, Message::CpuInfo(_))), "{r:?}");
}

/// Asks, on entering the lower loop, for a START of its own configuration set.
struct Restarter;

impl buslab_cpu196::program::UserProgram for Restarter {
    fn name(&self) -> &'static str {
        "restarter"
    }
    fn init(&mut self, k: &mut buslab_cpu196::program::Api) -> buslab_cpu196::program::Flow {
        k.display_text("again", true);
        buslab_cpu196::program::Flow {
            stop: false,
            start: Some(Start::run(0, 1, false)),
        }
    }
}

#[test]
fn a_program_that_starts_itself_from_init_does_not_recurse_without_end() {
    // Set 1 of bank 0 runs program 1: make that a program whose init STARTs set 1 again.
    let mut b = Bench::new();
    b.board
        .registry_mut()
        .register(1, "restarter", Box::new(|_| Box::new(Restarter)));
    let r = b.ask(&Message::Start(Start::run(0, 1, false)), 5);
    assert!(r.contains(&msg(MsgCode::COMPLETED)), "{r:?}");
    // It keeps restarting (once per kernel pass), and the kernel still serves the line.
    assert!(r.len() > 3, "{r:?}");
    let r = b.ask(&Message::Stop, 5);
    assert!(r.contains(&msg(MsgCode::COMPLETED)), "{r:?}");
    assert_eq!(b.board.mode(), Mode::Upper);
}

mod garbage {
    use super::*;
    use proptest::prelude::*;

    /// Sends `m` and returns what came back, ignoring frame errors (the host may have joined
    /// the board's stream mid-frame).
    fn ask_tolerant(b: &mut Bench, m: &Message, ms: u64) -> Vec<Message> {
        b.send(m);
        b.run_for(ms * MS);
        b.seen
            .drain(..)
            .filter_map(|(_, e)| match e {
                Event::Message(m) => Some(m),
                _ => None,
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Whatever arrives on the line, in either loop, the kernel neither panics nor hangs,
        /// and after a pause it answers CPUINF again (unless the garbage happened to power it
        /// down).
        #[test]
        fn random_bytes_never_break_the_kernel(
            bytes in proptest::collection::vec(any::<u8>(), 0..1500),
            gaps in proptest::collection::vec(0u64..3, 0..1500),
            lower in any::<bool>(),
        ) {
            let mut b = Bench::new();
            if lower {
                ask_tolerant(&mut b, &Message::Start(Start::run(0, 0, true)), 2);
            }
            let mut out = Vec::new();
            for (i, &byte) in bytes.iter().enumerate() {
                let gap = Nanos::new(gaps.get(i).copied().unwrap_or(0) * 50_000);
                b.now += b.byte_ns() + gap;
                b.board.poll(b.now, &mut out);
                for x in out.drain(..) {
                    let _ = b.host.push(b.now, x);
                }
                b.board.receive(b.now, byte);
            }
            b.run_for(300 * MS);
            // Error replies on top of a stream can fill the transmit FIFO (4 KiB, 0.36 s at
            // 115200): give it time to drain.
            ask_tolerant(&mut b, &Message::Stop, 600);
            if b.board.mode() == Mode::Upper {
                let r = ask_tolerant(&mut b, &Message::CpuInfoRequest, 10);
                prop_assert!(r.iter().any(|m| matches!(m, Message::CpuInfo(_))), "{:?}", r);
            }
        }
    }
}

#[test]
fn image_changes_replayed_over_the_old_image_give_the_new_one() {
    use buslab_cpu196::{Changes, Persistent};
    let before = Image::default();
    let mut b = Bench::with(before.clone(), Inputs::default());
    b.board.take_changes();
    let data: Box<[u8; 256]> = Box::new(core::array::from_fn(|i| i as u8));
    for block in [0x60, 0x61] {
        b.ask(
            &Message::FlashWrite {
                bank: 3,
                block,
                data: data.clone(),
            },
            50,
        );
    }
    b.ask(&Message::FlashErase { bank: 4 }, 50);
    b.ask(
        &Message::PicWrite {
            block: 1,
            data: Box::new([0x5A; 4096]),
        },
        500,
    );
    b.ask(&Message::EepromWrite(Box::new([7; 256])), 50);
    let Changes::Records(records) = b.board.take_changes() else {
        panic!("these changes are records");
    };
    assert_eq!(records.len(), 2 + 1 + 16 + 1);
    let mut replayed = before;
    for r in &records {
        Board::replay(&mut replayed, r).unwrap();
    }
    assert_eq!(&replayed, b.board.image());
    // A change no record describes asks for the whole image.
    b.ask(&Message::Format(Format::EraseBoot), 50);
    assert_eq!(b.board.take_changes(), Changes::Snapshot);
    assert!(Board::replay(&mut replayed, b"Z").is_err());
}
