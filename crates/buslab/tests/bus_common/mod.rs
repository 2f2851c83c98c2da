//! `buslab bus serve` as a child process for the CAN client tests.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};

use buslab_can::Frame;
use buslab_socketcand::SocketcandBus;

pub struct Serve {
    child: Child,
    pub addr: SocketAddr,
    pub url: String,
}

impl Serve {
    pub fn start(bitrate: u32) -> Self {
        Self::start_with(bitrate, &[])
    }

    pub fn start_with(bitrate: u32, extra: &[&str]) -> Self {
        Self::start_logging(bitrate, extra, Stdio::null())
    }

    /// As [`Serve::start_with`], its log (stderr) going to `stderr`.
    pub fn start_logging(bitrate: u32, extra: &[&str], stderr: Stdio) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["bus", "serve", "--listen", "127.0.0.1:0", "--bitrate"])
            .arg(bitrate.to_string())
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let url = line.trim().to_string();
        let addr = url
            .strip_prefix("socketcand://")
            .and_then(|r| r.split('/').next())
            .unwrap_or_else(|| panic!("no URL from bus serve: {line:?}"))
            .parse()
            .unwrap();
        Self { child, addr, url }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Whether the server has ended.
    pub fn has_ended(&mut self) -> bool {
        self.child.try_wait().unwrap().is_some()
    }

    pub fn client(&self) -> SocketcandBus {
        let mut bus = SocketcandBus::connect(self.addr, "vcan0").unwrap();
        assert!(bus.enable_extensions().unwrap());
        bus
    }

    pub fn buslab(&self) -> Command {
        let mut c = Command::new(env!("CARGO_BIN_EXE_buslab"));
        c.env_remove("BUSLAB_BUS");
        c
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}
