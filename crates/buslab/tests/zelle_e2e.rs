//! The ZELLE cell model served on a real pseudo-terminal at 9600 8N2, driven by the host
//! client and by the `buslab zelle` CLI. Real time: each exchange is a few bytes.

#[path = "support/zelle_served.rs"]
mod served;

use std::io::Write;
use std::process::Command;
use std::time::Duration;

use buslab_zelle::client::{Error, Port, SeriesParams, Transfer};
use buslab_zelle::{BatteryRam, START_BYTE};
use served::{Served, buslab_zelle as buslab, client_on};

#[test]
fn every_command_through_the_client_over_a_pty() {
    let mut s = Served::start(&["--analog", "1=1V", "--analog", "3=4V"]);
    let mut c = s.client();
    c.reset().unwrap();
    // 7 and 4: analog reads.
    assert_eq!(c.analog(1).unwrap(), 51);
    assert_eq!(c.analog_repeat(&[3, 1, 2]).unwrap(), [204, 51, 0]);
    // 11, 12: port 1, with an outside pull-down from the control interface.
    c.write_port1(0xEF).unwrap();
    assert_eq!(c.read_port1().unwrap(), 0xEF);
    assert!(s.control("p1 pull 0x40").starts_with("ok"));
    assert_eq!(c.read_port1().unwrap(), 0xAF);
    // 13: the START key, held from the control interface.
    assert!(!c.key_pressed().unwrap());
    assert!(s.control("key down").starts_with("ok"));
    assert!(c.key_pressed().unwrap());
    s.control("key up");
    // 14, 15: P2.6.
    c.write_p26(false).unwrap();
    assert!(!c.read_p26().unwrap());
    c.write_p26(true).unwrap();
    assert!(c.read_p26().unwrap());
    // 16, 17: registers.
    c.write_register(0x40, 0x5A).unwrap();
    assert_eq!(c.read_register(0x40).unwrap(), 0x5A);
    // 8: the parallel bus.
    c.bus_write(9, 0x33).unwrap();
    assert_eq!(c.bus_read(9).unwrap(), 0x33);
    // 18, 19: any RAM address.
    c.poke(0x2000, 0xC3).unwrap();
    assert_eq!(c.peek(0x2000).unwrap(), 0xC3);
    // 3 and 2: data RAM, pipelined and stop-and-wait.
    let data: Vec<u8> = (0..24).map(|i| i * 11).collect();
    c.write_data(&data, Transfer::Pipelined).unwrap();
    assert_eq!(c.read_data(24, Transfer::StopAndWait).unwrap(), data);
    c.write_data(&data[..5], Transfer::StopAndWait).unwrap();
    assert_eq!(c.read_data(24, Transfer::Pipelined).unwrap(), data);
    // 5, 6: load and run a program; 0 interrupts it.
    c.load_program(&[0x80, 0xFE], Transfer::Pipelined).unwrap();
    assert_eq!(c.peek(0x0400).unwrap(), 0x80);
    assert_eq!(c.peek(START_BYTE).unwrap(), 130);
    c.run_program().unwrap();
    let st = s.status_until("program running");
    assert!(st.contains("program running"), "{st}");
    c.interrupt().unwrap();
    assert_eq!(c.peek(START_BYTE).unwrap(), 0);
    // 1, 9, 10: a series of two blocks, then read the count (16) and the values (2).
    let params = SeriesParams::new(&[3, 1], 3, 4).unwrap();
    c.start_series(&params).unwrap();
    c.start_block().unwrap();
    s.block_done(6);
    c.start_block().unwrap();
    s.block_done(12);
    c.interrupt().unwrap();
    assert_eq!(c.value_count().unwrap(), 12);
    let dump = c.read_data(20, Transfer::Pipelined).unwrap();
    assert_eq!(dump[..8], params.to_bytes().unwrap());
    assert_eq!(
        dump[8..],
        [204, 51, 204, 51, 204, 51, 204, 51, 204, 51, 204, 51]
    );
    // 10 re-arms with the same parameters and starts counting again.
    c.repeat_series().unwrap();
    c.start_block().unwrap();
    s.block_done(6);
    c.interrupt().unwrap();
    assert_eq!(c.value_count().unwrap(), 6);
    assert!(s.control("status").contains("lost 0"));
}

#[test]
fn cli_measure_follows_the_sine_and_dump_peek_poke_agree() {
    let s = Served::start(&["--analog", "1=sine:2Hz:2V:2.5V", "--analog", "2=3.3V"]);
    let csv_path = s.dir.path().join("m.csv");
    let csv_arg = csv_path.to_str().unwrap();
    buslab(&s.pty, &["reset"]);
    let args = [
        "measure",
        "-c",
        "1,2",
        "--interval",
        "10ms",
        "--cycles",
        "100",
        // The block lasts 1 s; the host may be that late again on a loaded machine before
        // the stop cuts it short.
        "--block-margin",
        "1s",
        "-o",
        csv_arg,
    ];
    buslab(&s.pty, &args);
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("time_s,ch1,ch2"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 100);
    assert!(
        (rows[1][0] - rows[0][0] - 0.010).abs() < 1e-9,
        "10 ms apart"
    );
    // A 2 Hz sine sampled every 10 ms: periodic over 50 rows, 2.5 V ± 2 V, smooth.
    let ch1: Vec<f64> = rows.iter().map(|r| r[1]).collect();
    for i in 0..50 {
        assert!((ch1[i] - ch1[i + 50]).abs() <= 1.0, "row {i}: {ch1:?}");
    }
    let (min, max) = ch1
        .iter()
        .fold((255.0f64, 0.0f64), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    assert!(min <= 30.0 && max >= 225.0, "{min}..{max}");
    for w in ch1.windows(2) {
        assert!((w[1] - w[0]).abs() <= 17.0, "a sine, not noise: {w:?}");
    }
    assert!(rows.iter().all(|r| r[2] == 168.0), "3.3 V on channel 2");

    // dump: the 8 parameter bytes (100 cycles, channels 1 2, interval 10 - 2), then values.
    let dump = buslab(&s.pty, &["dump"]);
    let first = dump.lines().next().unwrap();
    assert!(
        first.starts_with("0800: 00 64 01 02 00 00 00 08 "),
        "{first}"
    );
    let listed: usize = dump.lines().map(|l| l.split_whitespace().count() - 1).sum();
    assert_eq!(listed, 8 + 200);
    let second: Vec<u8> = first
        .split_whitespace()
        .skip(9)
        .map(|h| u8::from_str_radix(h, 16).unwrap())
        .collect();
    assert_eq!(f64::from(second[0]), ch1[0]);
    assert_eq!(second[1], 168);

    // poke / peek round trip, in the three number spellings.
    buslab(&s.pty, &["poke", "0x3000", "171"]);
    assert_eq!(buslab(&s.pty, &["peek", "3000h"]).trim(), "0xab");
    assert_eq!(buslab(&s.pty, &["peek", "12288"]).trim(), "0xab");
}

/// `measure --plot FILE.svg` draws the channels in volts, read back from the SVG; `--plot`
/// alone still draws in the terminal.
#[test]
fn measure_plot_draws_the_channels_in_volts_or_in_the_terminal() {
    let s = Served::start(&["--analog", "1=sine:2Hz:2V:2.5V", "--analog", "2=1V"]);
    let svg_path = s.dir.path().join("m.svg");
    let csv_path = s.dir.path().join("m.csv");
    buslab(&s.pty, &["reset"]);
    let common = [
        "measure",
        "-c",
        "1,2",
        "--interval",
        "10ms",
        "--cycles",
        "100",
        // As above: the block lasts 1 s, and the host may be that late on a loaded machine.
        "--block-margin",
        "1s",
    ];
    fn with<'a>(common: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
        [common, extra].concat()
    }
    buslab(
        &s.pty,
        &with(
            &common,
            &[
                "-o",
                csv_path.to_str().unwrap(),
                "--plot",
                svg_path.to_str().unwrap(),
            ],
        ),
    );
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let seen = buslab_plot::inspect::parse(&svg).unwrap();
    let panel = seen.panel("analog inputs").unwrap();
    assert_eq!(panel.legend(), ["ch1", "ch2"], "named as in the CSV");
    assert_eq!(panel.value_title(), Some("voltage (V)"));
    let span = |points: &[(f64, f64)]| {
        points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.1), hi.max(p.1))
        })
    };
    let ch1 = panel.series("ch1").unwrap();
    let (lo, hi) = span(&ch1);
    assert!(
        (lo - 0.5).abs() < 0.2 && (hi - 4.5).abs() < 0.2,
        "{lo}..{hi}"
    );
    // 100 cycles 10 ms apart: about a second.
    let last = ch1.last().unwrap().0;
    let seconds = if panel.time_title() == Some("time (ms)") {
        last / 1000.0
    } else {
        last
    };
    assert!(
        (seconds - 0.99).abs() < 0.03,
        "{:?}: {last}",
        panel.time_title()
    );
    let (lo, hi) = span(&panel.series("ch2").unwrap());
    assert!(
        (lo - 1.0).abs() < 0.05 && (hi - 1.0).abs() < 0.05,
        "{lo}..{hi}"
    );

    // `--plot` alone: characters on stderr, the CSV on stdout as before.
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["zelle", "--timeout", "30s", "--port"])
        .arg(&s.pty)
        .args(with(&common, &["--plot"]))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("time_s,ch1,ch2\n"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains('*') && stderr.contains('+'), "{stderr}");
}

#[test]
fn power_cycle_while_armed_resumes_measuring_and_survives_a_restart() {
    let mut s = Served::start(&["--analog", "2=2.5V"]);
    let mut c = s.client();
    c.reset().unwrap();
    c.start_series(&SeriesParams::new(&[2], 5, 2).unwrap())
        .unwrap();
    let st = s.status_until("waiting for START");
    assert!(st.contains("waiting for START"), "{st}");
    let off = s.control("power off");
    assert!(off.starts_with("ok power off; saved"), "{off}");
    let ram = BatteryRam::from_state_file(&std::fs::read_to_string(s.state_file()).unwrap());
    assert_eq!(
        ram.unwrap().read(START_BYTE),
        129,
        "armed in the state file"
    );
    let on = s.control("power on");
    assert!(on.contains("series armed, waiting for START"), "{on}");
    // It measures: START from the host, then stop and count.
    c.start_block().unwrap();
    s.block_done(5);
    c.interrupt().unwrap();
    assert_eq!(c.value_count().unwrap(), 5);
    assert_eq!(c.read_data(13, Transfer::Pipelined).unwrap()[8..], [128; 5]);

    // Arm again, stop the server (it saves), start a new one on the same state file.
    c.repeat_series().unwrap();
    // Stopped only once the cell has the command (the server may read it late).
    s.status_where("armed again", |st| st.contains("waiting for START"));
    drop(c);
    let dir = s.stop();
    let mut s = Served::start_in(dir, &[]);
    assert!(
        s.control("status")
            .contains("series armed, waiting for START")
    );
    // START key from the control interface starts a block.
    s.control("key press 100ms");
    s.block_done(5);
    let mut c = s.client();
    c.interrupt().unwrap();
    assert_eq!(c.value_count().unwrap(), 5);
}

#[test]
fn byte_0_interrupts_a_running_series() {
    let mut s = Served::start(&[]);
    let mut c = s.client();
    c.reset().unwrap();
    // 60000 cycles every 20 ms: twenty minutes unless interrupted.
    c.start_series(&SeriesParams::new(&[1], 60_000, 20).unwrap())
        .unwrap();
    c.start_block().unwrap();
    // Measuring, with a few values stored (one every 20 ms).
    s.status_where("measuring with 3 values", |st| {
        st.contains("measuring")
            && st
                .split(", ")
                .find_map(|f| f.strip_suffix(" values"))
                .and_then(|n| n.parse::<u32>().ok())
                .is_some_and(|n| n >= 3)
    });
    c.interrupt().unwrap();
    let st = s.status_until("mode Ready, ready");
    assert!(st.contains("mode Ready, ready"), "{st}");
    let n = c.value_count().unwrap();
    assert!(n >= 3, "{n} values");
    assert_eq!(c.peek(START_BYTE).unwrap(), 0);
    c.port().pause(Duration::from_millis(60));
    assert_eq!(
        c.value_count().unwrap(),
        n,
        "no more values after the interrupt"
    );
}

/// `--strict-setup`: the cell's own rule, a byte sent within the set-up is lost. Sent in one
/// write, the command and the request reach the server together however loaded the host is.
#[test]
fn ignoring_the_setup_pause_loses_the_byte_with_strict_setup() {
    let mut s = Served::start(&["--strict-setup"]);
    let mut c = s.client();
    c.reset().unwrap();
    // Command 2 and its first request in one write: back to back on the line.
    c.port().send(&[2, 1]).unwrap();
    // The request was lost: the cell counts it, and never answers.
    s.status_where("losing the request in the set-up", |st| {
        st.contains("set-up 1")
    });
    let mut b = [0u8; 1];
    assert_eq!(
        c.port().recv(&mut b, Duration::from_millis(300)).unwrap(),
        0
    );
    // Still in command 2's exchange: a request sent on its own is answered.
    c.port().send(&[1]).unwrap();
    assert_eq!(c.port().recv(&mut b, served::ALLOWANCE).unwrap(), 1);
}

/// By default a served cell keeps a byte sent within the set-up and counts it: a pseudo-terminal
/// cannot show whether the client paused (its drain returns at once, a loaded server reads the
/// command and the next byte together), and a client that paused must never lose its byte.
#[test]
fn a_byte_sent_within_the_setup_is_kept_and_counted() {
    let mut s = Served::start(&[]);
    let mut c = s.client();
    c.reset().unwrap();
    c.poke(0x0800, 0xA5).unwrap();
    c.port().send(&[2, 1]).unwrap();
    let mut b = [0u8; 1];
    assert_eq!(c.port().recv(&mut b, served::ALLOWANCE).unwrap(), 1);
    assert_eq!(b, [0xA5]);
    let st = s.status_where("counting the byte kept in the set-up", |st| {
        st.contains("kept in set-up 1")
    });
    assert!(st.contains("lost 0 (set-up 0"), "{st}");
}

#[test]
fn garbage_then_reset_and_wrong_line_settings_give_clear_errors() {
    let mut s = Served::start(&[]);
    let mut c = s.client();
    // 120 pseudo-random bytes at line rate, then the ten-zeros reset.
    let mut x: u32 = 0x1234_5678;
    let garbage: Vec<u8> = (0..120)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x % 24) as u8
        })
        .collect();
    c.port().send(&garbage).unwrap();
    c.port().pause(Duration::from_millis(200));
    c.reset().unwrap();
    let st = s.status_until(", ready,");
    assert!(st.contains(", ready,"), "{st}");
    assert!(!c.key_pressed().unwrap());
    drop(c);

    // A host at the wrong baud rate: its bytes are framing errors, the client times out.
    let port =
        buslab_link::SerialLine::open(&s.pty, buslab_link::LineSettings::n82(19200)).unwrap();
    let mut wrong = buslab_zelle::client::Client::with_timeout(port, Duration::from_millis(200));
    let err = wrong.peek(0x0800).unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    assert!(err.to_string().contains("9600 8N2"), "{err}");
    drop(wrong);
    let _ = client_on;
}

#[test]
fn cli_rejects_bad_arguments_with_the_value_named() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("zelle");
    let s = Served::start_in(dir, &["--link", link.to_str().unwrap()]);
    // The symlink works as the port.
    assert_eq!(buslab(&link, &["key"]).trim(), "released");
    for (args, needle) in [
        (vec!["peek", "0x10000"], "address `0x10000`"),
        (vec!["reg", "256"], "register address `256`"),
        (vec!["reg", "128", "1"], "register address to write `128`"),
        (vec!["analog", "5"], "channel 5 is out of range 1..4"),
        // Each reading was a byte of one up-front allocation: 4 GB.
        (
            vec!["analog", "1", "--repeat", "4000000000"],
            "4000000000 is not in 1..=1000000",
        ),
        (
            vec!["measure", "-c", "1,2,3", "--interval", "2ms"],
            "interval 2 ms",
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["zelle", "--port"])
            .arg(&s.pty)
            .args(&args)
            .output()
            .unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["zelle", "key"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("--port PATH is required"));
}

#[test]
fn serve_rejects_bad_analog_channels_with_the_range() {
    for arg in ["9=1V", "0=1V", "x=1V"] {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["zelle", "serve", "--analog", arg])
            .stdin(std::process::Stdio::null())
            .output()
            .unwrap();
        assert!(!out.status.success(), "{arg} was accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        let ch = arg.split('=').next().unwrap();
        assert!(
            err.contains(&format!("channel `{ch}` is out of range 1..4")),
            "{arg}: {err}"
        );
    }
}

/// An Intel HEX data record for `data` at `addr`, then the end record.
fn hex_file(addr: u16, data: &[u8]) -> String {
    let mut record = vec![data.len() as u8, (addr >> 8) as u8, addr as u8, 0];
    record.extend_from_slice(data);
    let sum = record.iter().fold(0u8, |s, b| s.wrapping_add(*b));
    record.push(sum.wrapping_neg());
    let hex: String = record.iter().map(|b| format!("{b:02X}")).collect();
    format!(":{hex}\n:00000001FF\n")
}

#[test]
fn cli_covers_every_client_command() {
    let mut s = Served::start(&["--analog", "2=5V"]);
    let pty = s.pty.clone();
    let dir = s.dir.path().to_path_buf();
    let run = |args: &[&str]| buslab(&pty, args).trim().to_owned();
    assert_eq!(run(&["reset"]), "ready");
    assert_eq!(run(&["analog", "2"]), "ch2 255 5.000 V");
    assert_eq!(run(&["analog", "2", "--repeat", "3"]).lines().count(), 3);
    run(&["port1", "0xEF"]);
    assert_eq!(run(&["port1"]), "0b11101111");
    run(&["p26", "0"]);
    assert_eq!(run(&["p26"]), "0");
    assert_eq!(run(&["key"]), "released");
    run(&["reg", "0x21", "7"]);
    assert_eq!(run(&["reg", "33"]), "0x07");
    run(&["bus", "4", "0x11"]);
    assert_eq!(run(&["bus", "4"]), "0x11");

    // upload, then dump to a file, both transfer modes. The 8 bytes are series parameters:
    // 2 cycles of channel 2, 1 ms apart.
    let params = [0, 2, 2, 0, 0, 0, 0, 0];
    std::fs::write(dir.join("p.bin"), params).unwrap();
    run(&["upload", dir.join("p.bin").to_str().unwrap()]);
    let out = dir.join("out.bin");
    run(&["dump", "--len", "8", "-o", out.to_str().unwrap()]);
    assert_eq!(std::fs::read(&out).unwrap(), params);
    run(&[
        "dump",
        "--len",
        "8",
        "--stop-and-wait",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(std::fs::read(&out).unwrap(), params);

    // repeat arms a series with those parameters, start runs a block, stop ends it.
    run(&["repeat"]);
    assert!(
        s.status_until("waiting for START")
            .contains("waiting for START")
    );
    run(&["start"]);
    s.block_done(2);
    run(&["stop"]);
    assert_eq!(run(&["reg", "7"]), "0x02");
    let dump = run(&["dump"]);
    assert_eq!(dump, "0800: 00 02 02 00 00 00 00 00 ff ff");

    // load an Intel HEX program, run it, stop it.
    std::fs::write(dir.join("p.hex"), hex_file(0x0400, &[0x80, 0xFE])).unwrap();
    assert!(run(&["load", dir.join("p.hex").to_str().unwrap()]).starts_with("loaded 2 bytes"));
    assert_eq!(run(&["peek", "0x0401"]), "0xfe");
    run(&["run"]);
    assert!(
        s.status_until("program running")
            .contains("program running")
    );
    run(&["stop"]);
    assert!(s.status_until(", ready,").contains(", ready,"));
    // A HEX file outside the program area is refused before anything is sent.
    std::fs::write(dir.join("low.hex"), hex_file(0x0000, &[1])).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["zelle", "--port"])
        .arg(&pty)
        .arg("load")
        .arg(dir.join("low.hex"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("outside the program area"));
}

#[test]
fn a_program_is_traced_and_its_cpu_and_registers_are_shown_after_its_stop() {
    let mut s = Served::start(&["--trace", "200"]);
    let trace = s.stderr_lines();
    let pty = s.pty.clone();
    let dir = s.dir.path().to_path_buf();
    let run = |args: &[&str]| buslab(&pty, args).trim().to_owned();
    // MOV R3,#0AAh; MOV 30h,#5Ah; MOV A,#41h; LCALL 0030h (Sende); SJMP $
    let program = [
        0x7B, 0xAA, 0x75, 0x30, 0x5A, 0x74, 0x41, 0x12, 0x00, 0x30, 0x80, 0xFE,
    ];
    std::fs::write(dir.join("p.hex"), hex_file(0x0400, &program)).unwrap();
    run(&["load", dir.join("p.hex").to_str().unwrap()]);
    run(&["run"]);
    // The trace shows each instruction with its bytes and mnemonic, and the OS routine.
    let mut seen = Vec::new();
    let deadline = std::time::Instant::now() + served::ALLOWANCE;
    while !seen
        .iter()
        .any(|l: &String| l.contains("040A  80 FE     SJMP 040Ah"))
    {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match trace.recv_timeout(left) {
            Ok(line) => seen.push(line),
            Err(e) => panic!("no SJMP in the trace ({e}): {seen:#?}"),
        }
    }
    let expected = [
        "0400  7B AA     MOV R3,#AAh",
        "0402  75 30 5A  MOV 30h,#5Ah",
        "0405  74 41     MOV A,#41h",
        "0407  12 00 30  LCALL 0030h",
        "OS routine Sende",
    ];
    let mut at = 0;
    for line in &seen {
        if at < expected.len() && line.contains(expected[at]) {
            at += 1;
        }
    }
    assert_eq!(at, expected.len(), "in order: {expected:?}\n{seen:#?}");
    assert!(
        s.control("cpu")
            .starts_with("ok program running: PC=040A A=41"),
        "{}",
        s.control("cpu")
    );
    run(&["stop"]);
    s.status_until(", ready,");
    let cpu = s.control("cpu");
    assert!(
        cpu.starts_with("ok program stopped (interrupted by a 0 on RxD): PC=040A A=41"),
        "{cpu}"
    );
    assert!(cpu.contains("bank 0 R0-R7=00 00 00 AA"), "{cpu}");
    // Through the protocol (command 16): the RAM as the program left it.
    let regs = run(&["regs"]);
    assert!(
        regs.contains("bank 0 00h  R0-R7  00 00 00 AA 00 00 00 00"),
        "{regs}"
    );
    assert!(
        regs.contains("30h           5A 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00"),
        "{regs}"
    );
    assert!(
        regs.contains("SFR (the OS's, as it answers): SP="),
        "{regs}"
    );
}

#[test]
fn serve_refuses_a_trace_rate_out_of_range() {
    for bad in ["0", "1000001", "lots"] {
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["zelle", "serve", "--trace", bad])
            .output()
            .unwrap();
        assert!(!out.status.success(), "--trace {bad} was taken");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(bad) && err.contains("--trace"), "{err}");
    }
}

#[test]
fn csv_replay_feeds_an_input_from_the_command_line_and_the_control_interface() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("in.csv");
    std::fs::write(&csv, "seconds,volts\n0,1.0\n").unwrap();
    let spec = format!("3=csv:{}", csv.display());
    let mut s = Served::start_in(dir, &["--analog", &spec]);
    let mut c = s.client();
    assert_eq!(c.analog(3).unwrap(), 51);
    std::fs::write(&csv, "0,4.0\n").unwrap();
    let reply = s.control(&format!("analog 3 csv:{}", csv.display()));
    assert!(
        reply.starts_with("ok analog 3 = replay of 1 points"),
        "{reply}"
    );
    assert_eq!(c.analog(3).unwrap(), 204);
    let reply = s.control("analog 3 csv:/nonexistent/in.csv");
    assert!(
        reply.starts_with("error: cannot read /nonexistent/in.csv"),
        "{reply}"
    );
}

/// A child process killed when dropped (also when an assertion fails first).
struct Child(std::process::Child);

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_stopping_server_leaves_a_newer_servers_control_socket_alone() {
    use std::io::{BufRead, BufReader};
    use std::os::unix::fs::MetadataExt;
    use std::process::Stdio;

    let dir = tempfile::tempdir().unwrap();
    let sock = dir.path().join("zelle.sock");
    let serve = || {
        Child(
            Command::new(env!("CARGO_BIN_EXE_buslab"))
                .args(["zelle", "serve", "--control"])
                .arg(&sock)
                .stdin(Stdio::piped())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        )
    };
    let inode = || std::fs::symlink_metadata(&sock).ok().map(|m| m.ino());
    let wait_for = |what: &dyn Fn() -> bool| {
        let until = std::time::Instant::now() + served::ALLOWANCE;
        while !what() {
            assert!(
                std::time::Instant::now() < until,
                "no control socket change within {:?}",
                served::ALLOWANCE
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let mut first = serve();
    wait_for(&|| inode().is_some());
    let first_inode = inode();
    // A second server takes the name over (the first one's socket file is replaced).
    let _second = serve();
    wait_for(&|| inode().is_some() && inode() != first_inode);
    let _ = Command::new("kill")
        .args(["-INT", &first.0.id().to_string()])
        .status();
    first.0.wait().unwrap();
    // The second server's socket is still there and answers.
    let stream = std::os::unix::net::UnixStream::connect(&sock)
        .expect("the second server's control socket was removed");
    writeln!(&stream, "status").unwrap();
    let mut reply = String::new();
    BufReader::new(&stream).read_line(&mut reply).unwrap();
    assert!(reply.starts_with("ok mode"), "{reply}");
}

#[test]
fn serve_refuses_a_state_file_it_cannot_write() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["zelle", "serve", "--state", "/nonexistent/dir/cell.toml"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // It must stop at once with an error (before, it served on and lost every change).
    let until = std::time::Instant::now() + served::ALLOWANCE;
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > until {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still serving with a file it cannot write");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot write state file /nonexistent/dir/cell.toml"),
        "{err}"
    );
}

#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    // `buslab zelle --port PTY key | true`: the reader is gone before the answer is printed.
    let s = Served::start(&[]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["zelle", "--port"])
        .arg(&s.pty)
        .arg("key")
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
}
