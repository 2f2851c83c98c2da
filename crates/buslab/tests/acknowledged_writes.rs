//! Nothing a served device acknowledged is lost: `kill -9` during a stream of confirmed writes
//! (ZELLE pokes, CPU196 flash blocks, PIC program and EEPROM writes), then a restart on the
//! same state file, finds every confirmed write; saves from many control clients at once never
//! leave a file that does not load; SIGTERM and SIGHUP stop a server as cleanly as Ctrl-C.
//! Real processes, real signals.

#[path = "support/zelle_served.rs"]
mod served;

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use buslab_cpu196::host::Client as BoardClient;
use buslab_cpu196::{Image, Message, MsgCode};
use buslab_link::{LineSettings, SerialLine};
use buslab_zelle::BatteryRam;
use served::Served;

/// The RAM in the cell's state file.
fn ram_in(dir: &Path) -> BatteryRam {
    let text = std::fs::read_to_string(dir.join("state.toml")).unwrap();
    BatteryRam::from_state_file(&text).expect("the state file loads")
}

/// Two control clients asking for `save` as fast as the server answers, until `stop`.
fn savers(
    sock: &Path,
    stop: &Arc<AtomicBool>,
    saves: &Arc<AtomicU64>,
) -> Vec<std::thread::JoinHandle<()>> {
    (0..2)
        .map(|_| {
            let stream = UnixStream::connect(sock).unwrap();
            let (stop, saves) = (stop.clone(), saves.clone());
            std::thread::spawn(move || {
                let mut replies = BufReader::new(stream.try_clone().unwrap()).lines();
                let mut stream = stream;
                while !stop.load(Ordering::SeqCst) {
                    if writeln!(stream, "save").is_err() {
                        return;
                    }
                    match replies.next() {
                        Some(Ok(line)) if line.contains("saved") => {
                            saves.fetch_add(1, Ordering::SeqCst);
                        }
                        _ => return,
                    }
                }
            })
        })
        .collect()
}

#[test]
fn zelle_pokes_confirmed_before_a_kill_9_survive_it_while_saves_race() {
    const ROUNDS: u16 = 3;
    const POKES: u16 = 160;
    let mut dir = tempfile::tempdir().unwrap();
    let sock = dir.path().join("control.sock");
    let sock_arg = sock.to_string_lossy().into_owned();
    let mut confirmed: Vec<(u16, u8)> = Vec::new();
    let saves = Arc::new(AtomicU64::new(0));
    for round in 0..ROUNDS {
        let s = Served::start_in(dir, &["--control", &sock_arg]);
        // The restarted server replayed the journal into the state file it wrote at start.
        let ram = ram_in(s.dir.path());
        let lost: Vec<_> = confirmed
            .iter()
            .filter(|&&(addr, value)| ram.read(addr) != value)
            .collect();
        assert!(
            lost.is_empty(),
            "round {round}: {} of {} confirmed pokes lost, e.g. {:x?}",
            lost.len(),
            confirmed.len(),
            &lost[..lost.len().min(5)]
        );
        let stop = Arc::new(AtomicBool::new(false));
        let racing = savers(&sock, &stop, &saves);
        let mut c = s.client();
        c.reset().unwrap();
        let mut pending = Vec::new();
        for i in 0..POKES {
            let addr = 0x1000 + round * 0x400 + i;
            let value = (i as u8).wrapping_mul(7).wrapping_add(round as u8) | 1;
            c.poke(addr, value).unwrap();
            pending.push((addr, value));
            // A reply confirms every poke before it: the cell works through its line in order.
            if i % 8 == 7 {
                assert_eq!(c.peek(addr).unwrap(), value);
                confirmed.append(&mut pending);
            }
        }
        // More pokes on their way, then the kill.
        let mut port = c.into_port();
        for i in 0..8u16 {
            let [high, low] = (0x7000 + i).to_be_bytes();
            buslab_zelle::client::Port::send(&mut port, &[19, high, low, 0x55]).unwrap();
        }
        dir = s.kill_9();
        stop.store(true, Ordering::SeqCst);
        for t in racing {
            t.join().unwrap();
        }
    }
    // A last start finds everything; SIGHUP then stops it cleanly: state saved, link gone.
    let link = dir.path().join("ttyZELLE");
    let link_arg = link.to_string_lossy().into_owned();
    let s = Served::start_in(dir, &["--link", &link_arg]);
    let ram = ram_in(s.dir.path());
    assert!(confirmed.iter().all(|&(a, v)| ram.read(a) == v));
    let mut c = s.client();
    c.poke(0x6000, 0xA5).unwrap();
    assert_eq!(c.peek(0x6000).unwrap(), 0xA5);
    drop(c);
    assert!(link.exists());
    let (status, dir) = s.signal("HUP");
    assert!(status.success(), "{status}");
    assert!(!link.exists(), "SIGHUP left the link behind");
    assert_eq!(ram_in(dir.path()).read(0x6000), 0xA5);
    let journals: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("journal"))
        .collect();
    assert!(journals.is_empty(), "{journals:?}");
    eprintln!(
        "{} confirmed pokes over {ROUNDS} kill -9 restarts, 0 lost; {} racing saves",
        confirmed.len(),
        saves.load(Ordering::SeqCst)
    );
}

const BAUD: u32 = 250_000;

/// `buslab cpu196 serve --image DIR/image.toml` as a child process, and its PTY.
fn serve_board(dir: &Path, extra: &[&str]) -> (Child, PathBuf) {
    let log = std::fs::File::create(dir.join("serve.log")).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args([
            "-v",
            "cpu196",
            "serve",
            "--baud",
            &BAUD.to_string(),
            "--image",
        ])
        .arg(dir.join("image.toml"))
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(log)
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    let pty = PathBuf::from(line.trim());
    assert!(pty.exists(), "serve printed {line:?}");
    // Keep reading whatever else it prints.
    std::thread::spawn(move || std::io::copy(&mut stdout, &mut std::io::sink()));
    (child, pty)
}

fn board_client(pty: &Path) -> BoardClient<SerialLine> {
    let port = SerialLine::open(pty, LineSettings::n81(BAUD)).unwrap();
    let mut c = BoardClient::new(port, BAUD);
    c.timeout = Duration::from_secs(30);
    c
}

fn image_in(dir: &Path) -> Image {
    let text = std::fs::read_to_string(dir.join("image.toml")).unwrap();
    Image::from_toml(&text).expect("the image loads")
}

fn completed(c: &mut BoardClient<SerialLine>, m: &Message) {
    c.request(m, 3, |r| {
        (*r == Message::Msg(MsgCode::COMPLETED)).then_some(())
    })
    .unwrap();
}

#[test]
fn cpu196_flash_pic_and_eeprom_writes_confirmed_before_a_kill_9_survive_it() {
    const ROUNDS: u8 = 3;
    const BLOCKS: u8 = 80;
    let dir = tempfile::tempdir().unwrap();
    let mut confirmed: Vec<(u8, u8, [u8; 256])> = Vec::new();
    let mut pic: Vec<(u8, Box<[u8; 4096]>)> = Vec::new();
    let mut eeprom = None;
    for round in 0..ROUNDS {
        let (mut child, pty) = serve_board(dir.path(), &[]);
        let image = image_in(dir.path());
        let lost = confirmed
            .iter()
            .filter(|(bank, block, data)| image.flash.read(*bank, *block).unwrap() != data)
            .count();
        assert_eq!(
            lost,
            0,
            "round {round}: {lost} of {} confirmed blocks lost",
            confirmed.len()
        );
        if let Some(e) = eeprom {
            assert_eq!(
                image.pic_eeprom, e,
                "round {round}: the EEPROM write was lost"
            );
        }
        for (block, data) in &pic {
            let at = (*block as usize - 1) * 4096;
            assert_eq!(
                &image.pic_program[at..at + 4096],
                &data[..],
                "PIC block {block}"
            );
        }
        let mut c = board_client(&pty);
        let bank = 2 + round;
        completed(&mut c, &Message::FlashErase { bank });
        let e = [round.wrapping_mul(31) | 1; 256];
        completed(&mut c, &Message::EepromWrite(Box::new(e)));
        eeprom = Some(e);
        let block = round % 3 + 1;
        let data: Box<[u8; 4096]> = Box::new(core::array::from_fn(|i| (i as u8) ^ round));
        c.pic_write(block, &data, &mut |_| {}).unwrap();
        pic.retain(|(b, _)| *b != block);
        pic.push((block, data));
        for k in 0..BLOCKS {
            let data: [u8; 256] = core::array::from_fn(|i| (i as u8).wrapping_add(k) ^ round);
            completed(
                &mut c,
                &Message::FlashWrite {
                    bank,
                    block: 0x60 + k,
                    data: Box::new(data),
                },
            );
            confirmed.push((bank, 0x60 + k, data));
        }
        // More writes on their way, then the kill.
        for k in 0..4u8 {
            c.send(&Message::FlashWrite {
                bank,
                block: 0x28 + k,
                data: Box::new([0x77; 256]),
            })
            .unwrap();
        }
        child.kill().unwrap();
        child.wait().unwrap();
    }
    // A last start finds everything; SIGTERM then stops it cleanly: image saved, journals gone.
    let (child, _) = serve_board(dir.path(), &[]);
    let image = image_in(dir.path());
    assert!(
        confirmed
            .iter()
            .all(|(bank, block, data)| image.flash.read(*bank, *block).unwrap() == data)
    );
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = wait(child);
    assert!(status.success(), "{status}");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("journal"))
        .collect();
    assert!(names.is_empty(), "{names:?}");
    eprintln!(
        "{} confirmed flash blocks, {} PIC blocks and the EEPROM over {ROUNDS} kill -9 restarts, 0 lost",
        confirmed.len(),
        pic.len()
    );
}

fn wait(mut child: Child) -> std::process::ExitStatus {
    child.wait().unwrap()
}

#[test]
fn a_signal_as_soon_as_the_device_is_served_stops_it_cleanly() {
    // The handler was installed after the PTY, its link and the first line: SIGTERM or SIGHUP
    // sent when the path appeared killed the process, left the link and saved nothing.
    for (device, file_option) in [("zelle", "--state"), ("cpu196", "--image")] {
        for signal in ["INT", "TERM", "HUP"] {
            let dir = tempfile::tempdir().unwrap();
            let file = dir.path().join("state.toml");
            let link = dir.path().join("tty");
            let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
                .args(["-q", device, "serve", file_option])
                .arg(&file)
                .arg("--link")
                .arg(&link)
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            let mut first = String::new();
            BufReader::new(child.stdout.take().unwrap())
                .read_line(&mut first)
                .unwrap();
            assert!(link.exists(), "{device}: {first:?}");
            let sent = Command::new("kill")
                .args([&format!("-{signal}"), &child.id().to_string()])
                .status()
                .unwrap();
            assert!(sent.success());
            let status = child.wait().unwrap();
            assert!(status.success(), "{device} serve, SIG{signal}: {status}");
            assert!(!link.exists(), "{device} serve, SIG{signal} left the link");
            assert!(file.exists(), "{device} serve, SIG{signal} saved nothing");
        }
    }
}
