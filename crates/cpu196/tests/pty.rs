//! The model served on a real pseudo-terminal, driven by the host client through a serial port.
//! Wall-clock time: every wait is for an event, with deadlines far above the work's line time.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use buslab_cpu196::codes::MsgCode;
use buslab_cpu196::host::{Client, ClientError, Recorder};
use buslab_cpu196::message::*;
use buslab_cpu196::source::{Inputs, Source};
use buslab_cpu196::{Board, Image, wire};
use buslab_device::Nanos;
use buslab_link::{LineSettings, SerialLine, Serve, Served};

const BAUD: u32 = 250_000;

/// How long a reply may take beyond its time on the line: far more than any scheduling delay
/// on a loaded machine. Only tests that expect silence wait for less.
const ALLOWANCE: Duration = Duration::from_secs(30);

fn board(image: Image) -> Board {
    let mut b = Board::new(image, Inputs::default(), Nanos::ZERO);
    b.set_baud(BAUD);
    b
}

fn serve(board: Board, image: Option<PathBuf>) -> Served<Board> {
    let line = board.line();
    Serve::new(board, line)
        .name("cpu196")
        .persist(image, "image", Duration::from_millis(200))
        .spawn()
        .unwrap()
}

fn connect(s: &Served<Board>) -> Client<SerialLine> {
    let port = SerialLine::open(s.path(), LineSettings::n81(BAUD)).unwrap();
    let mut c = Client::new(port, BAUD);
    c.timeout = ALLOWANCE;
    // The boot report (F4 03) may or may not reach the client, and a loaded machine may take
    // any time to deliver it: a watchdog round trip puts whatever came before it behind us.
    c.sync().unwrap();
    c.take_backlog();
    c
}

#[test]
fn info_flash_pic_eeprom_over_a_pty() {
    let s = serve(board(Image::default()), None);
    let mut c = connect(&s);
    assert_eq!(&c.info().unwrap().serial, b"BL196001");
    let data: [u8; 256] = core::array::from_fn(|i| (i as u8) ^ 0x5A);
    c.flash_write(3, 0x60, &data).unwrap();
    assert!(matches!(
        c.flash_write(3, 0x60, &data),
        Err(ClientError::Board(MsgCode::NOT_BLANK_ERROR))
    ));
    assert!(matches!(
        c.flash_write(3, 0x10, &data),
        Err(ClientError::Board(MsgCode::INVALID_PARAMETER_VALUE))
    ));
    c.flash_erase(3).unwrap();
    assert_eq!(*c.flash_read(3, 0x60).unwrap(), [0xFF; 256]);
    let pic: [u8; 4096] = core::array::from_fn(|i| (i / 16) as u8);
    let mut steps = 0;
    c.pic_write(1, &pic, &mut |_| steps += 1).unwrap();
    assert_eq!(steps, 16);
    c.eeprom_write(&[7; 256]).unwrap();
    assert_eq!(*c.eeprom_read().unwrap(), [7; 256]);
    assert_eq!(
        c.log_table().unwrap(),
        buslab_cpu196::acquisition::LogTable::default()
    );
    let (c196, _) = c.cfgad(0, 0).unwrap();
    assert!(buslab_cpu196::adconfig::AdConfig::parse(&c196).is_ok());
    c.command(&Message::Pwm(Pwm::Set {
        n: 2,
        low: 0,
        value: 99,
    }))
    .unwrap();
    assert!(matches!(
        c.command(&Message::Pwm(Pwm::Dac(99))),
        Err(ClientError::Board(MsgCode::INVALID_PARAMETER_VALUE))
    ));
    assert_eq!(s.with(|b, _| b.pwm()).unwrap(), [0, 0, 99]);
    assert_eq!(
        c.bridge(Bridge::SpiSend(0x33)).unwrap(),
        Some(Bridge::SpiReceived(0x33))
    );
    // Set 0 without the A/D: no program that ends the run on its own (set 4's pulse train
    // stops after 20 ms, which a loaded machine can take before the next request).
    assert!(matches!(c.start(Start::run(0, 0, false)), Ok(())));
    assert!(matches!(
        c.info(),
        Err(ClientError::Board(MsgCode::INVALID_COMMAND))
    ));
    c.stop().unwrap();
    c.reset().unwrap();
    c.power_down().unwrap();
    // A powered-down board stays silent: no need to wait long for that.
    c.timeout = Duration::from_millis(300);
    assert!(matches!(c.info(), Err(ClientError::Lost { .. })));
}

#[test]
fn corruption_on_the_line_gets_kernel_messages_and_never_corrupts_flash() {
    let s = serve(board(Image::default()), None);
    let mut c = connect(&s);
    let expect_msg = |c: &mut Client<_>, code: MsgCode| {
        let m = c.next(ALLOWANCE).unwrap();
        assert_eq!(m, Some(Message::Msg(code)));
    };
    // A wrong complement.
    c.send_raw(&[wire::CPUINF, 0x12]).unwrap();
    expect_msg(&mut c, MsgCode::RECEPTION_ERROR);
    expect_msg(&mut c, MsgCode::TIME_OUT); // the 12h waited for its complement
    // A truncated frame (a dropped tail).
    let block = Message::FlashWrite {
        bank: 4,
        block: 0x70,
        data: Box::new([0xA5; 256]),
    }
    .to_bytes()
    .unwrap();
    c.send_raw(&block[..200]).unwrap();
    expect_msg(&mut c, MsgCode::TIME_OUT);
    assert_eq!(*c.flash_read(4, 0x70).unwrap(), [0xFF; 256]);
    // A dropped byte inside a block, then the next command: the write completes with a
    // wrong byte, but the client's read-back catches it (no silent corruption).
    let mut dropped = block.clone();
    dropped.remove(100);
    c.send_raw(&dropped).unwrap();
    let r = c.flash_write(4, 0x71, &[1; 256]);
    assert!(r.is_err(), "{r:?}");
    // Random bytes injected between commands: the link recovers. The kernel answers the
    // garbage (and the tail of the broken block) with one error message per bad byte, and
    // the replies still on their way come too, all before the answer to a request sent now.
    c.send_raw(&[0x00, 0x13, 0x77, 0xF5, 0xF5, 0x31]).unwrap();
    c.send(&Message::CpuInfoRequest).unwrap();
    let info = loop {
        match c.next(ALLOWANCE).unwrap() {
            Some(Message::CpuInfo(info)) => break info,
            Some(_) => {}
            None => panic!("no CPUINF answer within {ALLOWANCE:?}"),
        }
    };
    assert_eq!(&info.serial, b"BL196001");
    c.flash_write(5, 0x80, &[3; 256]).unwrap();
}

#[test]
fn flash_survives_a_restart_from_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("board.toml");
    let data: [u8; 256] = core::array::from_fn(|i| i as u8);
    {
        let s = serve(board(Image::default()), Some(path.clone()));
        let mut c = connect(&s);
        c.flash_write(6, 0x90, &data).unwrap();
        s.stop().unwrap();
    }
    let image = Image::from_toml(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let s = serve(board(image), Some(path));
    let mut c = connect(&s);
    assert_eq!(*c.flash_read(6, 0x90).unwrap(), data);
    assert!(matches!(
        c.flash_write(6, 0x90, &data),
        Err(ClientError::Board(MsgCode::NOT_BLANK_ERROR))
    ));
}

#[test]
fn recorded_samples_match_the_sources() {
    let mut b = board(Image::default());
    b.inputs.c196[0] = Source::Constant(4.0);
    b.inputs.c196[1] = Source::Constant(1.0);
    let s = serve(b, None);
    let mut c = connect(&s);
    c.start(Start::run(0, 1, true)).unwrap();
    let mut rec = Recorder::csv(Vec::new(), c.now()).unwrap();
    // 20 frames take 160 ms at 1 kHz with 8 scans a frame; wait for them, however long a
    // loaded machine takes.
    let until = Instant::now() + ALLOWANCE;
    while rec.frames < 20 {
        assert!(
            Instant::now() < until,
            "{} frames in {ALLOWANCE:?}",
            rec.frames
        );
        if let Some(m) = c.next(Duration::from_millis(20)).unwrap() {
            rec.record(&m, c.now()).unwrap();
        }
    }
    c.stop().unwrap();
    let csv = String::from_utf8(rec.finish().unwrap().into_inner()).unwrap();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let volts: f64 = f[4].parse().unwrap();
        let want = if f[2] == "0" { 4.0 } else { 1.0 };
        assert!((volts - want).abs() < 5.0 / 1023.0, "{line}");
    }
}
