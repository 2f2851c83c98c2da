//! `buslab lab` serves a ZELLE cell and a CPU196 board next to the bus; the host tools reach
//! them through the links it makes.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use assert_cmd::cargo::CommandCargoExt;

fn buslab() -> Command {
    Command::cargo_bin("buslab").unwrap()
}

/// The lab process, killed if the test ends early (it runs until told to stop).
struct Lab(std::process::Child);

impl Drop for Lab {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn wait_for(path: &Path) {
    let start = Instant::now();
    while !path.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn lab_devices_answer_the_host_tools_and_keep_their_state() {
    let dir = tempfile::tempdir().unwrap();
    let mut lab = Lab(buslab()
        .args(["lab", "--dir"])
        .arg(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap());
    // The banner's lines, as they come.
    let (lines_tx, lines) = mpsc::channel();
    let stderr = lab.0.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = lines_tx.send(line.clone());
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let url = loop {
        let line = lines
            .recv_timeout(Duration::from_secs(60))
            .expect("the lab's banner names its bus");
        if let Some(at) = line.find("socketcand://") {
            break line[at..].split_whitespace().next().unwrap().to_string();
        }
    };
    let (zelle, cpu196) = (dir.path().join("zelle"), dir.path().join("cpu196"));
    wait_for(&zelle);
    wait_for(&cpu196);

    let out = buslab()
        .args(["zelle", "--timeout", "30s", "--port"])
        .arg(&zelle)
        .args(["poke", "0x2000", "0x5A"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = buslab()
        .args(["zelle", "--timeout", "30s", "--port"])
        .arg(&zelle)
        .args(["peek", "0x2000"])
        .output()
        .unwrap();
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("0x5a"),
        "{out:?}"
    );

    let out = buslab()
        .args(["cpu196", "--timeout", "30s", "--port"])
        .arg(&cpu196)
        .arg("info")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("serial number"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // Any socketcand client joins the lab's bus and sees its nodes' traffic: the engine's
    // periodic frame and the counter (a client of the lab, paced by the host's clock, so the
    // test waits for it rather than counting frames).
    let mut dump = Lab(buslab()
        .args(["dump", "--bus", &url])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap());
    let (dump_tx, dump_lines) = mpsc::channel();
    let stdout = dump.0.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if dump_tx.send(line).is_err() {
                break;
            }
        }
    });
    let (mut engine, mut counter, mut seen) = (false, false, String::new());
    while !(engine && counter) {
        let line = dump_lines
            .recv_timeout(Duration::from_secs(60))
            .unwrap_or_else(|_| {
                panic!("the engine's and the counter's frames never came:\n{seen}")
            });
        engine |= line.contains("0C0   [8]  0F A0 00 3C");
        counter |= line.contains("200   [4]");
        seen.push_str(&line);
        seen.push('\n');
    }
    drop(dump);

    // SIGTERM stops the lab as cleanly as Ctrl-C: links removed, state saved.
    let killed = Command::new("kill")
        .args(["-TERM", &lab.0.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = lab.0.wait().unwrap();
    let banner = reader.join().unwrap();
    assert!(status.success(), "{banner}");
    assert!(
        banner.contains("ZELLE cell") && banner.contains("CPU196 board"),
        "{banner}"
    );
    // The links go away with the lab; the battery-backed RAM stays in the state file.
    assert!(!zelle.exists() && !cpu196.exists());
    let state = std::fs::read_to_string(dir.path().join("zelle.toml")).unwrap();
    assert!(
        state.contains("5A") || state.contains("5a"),
        "poked byte not saved:\n{state}"
    );
    assert!(dir.path().join("cpu196.toml").exists());
}
