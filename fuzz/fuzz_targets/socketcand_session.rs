//! One socketcand server connection (the sans-IO `Session`) driven as the server drives it.
//! Input: the client's bytes, with ops (see `buslab_fuzz::items`) for what else happens: a
//! frame or an error frame from the bus, the host answering late or refusing the join, a
//! client that reads slowly, time passing, the client leaving (its output closed, its input
//! ended). It never panics, never asks for anything while it waits for the join, what it
//! buffers for the client stays bounded by what the client sent (nothing once the client
//! left), and once the input ended it hands out what is left and is drained.
#![no_main]

use buslab_can::{Frame, Id, Nanos, StandardId};
use buslab_fuzz::{Item, items};
use buslab_socketcand::server::{Action, Session, SessionConfig};
use buslab_socketcand::{ServerMessage, Timestamp};
use libfuzzer_sys::fuzz_target;

/// Bytes of output one received byte may cause (an error reply quotes at most an excerpt of
/// the bad element), on top of the frames the session may hold for a slow client.
const OUTPUT_PER_INPUT_BYTE: usize = 64;
const OUTPUT_SLACK: usize = 4096;
const MAX_OUTPUT: usize = 2048;

struct Host {
    session: Session,
    now: Nanos,
    received: usize,
    waiting_join: bool,
    waiting_reply: bool,
    closed: bool,
    /// The host answers joins and requests at once (else only on the answer op).
    prompt: bool,
    refuse_join: bool,
    /// The client reads everything at once (else only on the read op).
    reads: bool,
    /// The client left: its output is closed.
    left: bool,
    /// Its input ended.
    ended: bool,
}

impl Host {
    fn check_output(&self) {
        let (a, b) = self.session.output();
        let buffered = a.len() + b.len();
        assert!(
            !self.left || buffered == 0,
            "{buffered} bytes buffered for a client that left"
        );
        let bound = MAX_OUTPUT + OUTPUT_PER_INPUT_BYTE * self.received + OUTPUT_SLACK;
        assert!(
            buffered <= bound,
            "{buffered} bytes buffered for the client after it sent {} (bound {bound})",
            self.received
        );
    }

    fn act(&mut self) {
        while !self.closed {
            if self.prompt {
                self.answer();
            }
            let Some(action) = self.session.poll_action(self.now) else {
                if self.ended && !self.waiting_join && !self.waiting_reply {
                    assert!(self.session.is_drained(), "input ended, nothing handed out");
                }
                break;
            };
            assert!(
                !self.waiting_join,
                "asked for {action:?} while waiting for the join"
            );
            match action {
                Action::Join => self.waiting_join = true,
                Action::Send(_) => {}
                Action::Request(_) => self.waiting_reply = true,
                Action::Close => {
                    assert!(self.session.is_closing());
                    self.closed = true;
                }
                Action::Unfinished { bytes, .. } => {
                    assert!(self.ended, "an unfinished element before the end");
                    assert!(bytes > 0 && bytes <= self.received);
                }
            }
        }
        if self.prompt {
            self.answer();
        }
    }

    fn answer(&mut self) {
        if self.waiting_join {
            self.waiting_join = false;
            let result = if self.refuse_join {
                Err("the bus is full".to_string())
            } else {
                Ok(3)
            };
            if self.session.joined(result) == Some(Action::Close) {
                self.closed = true;
            }
        } else if self.waiting_reply {
            self.waiting_reply = false;
            self.session.reply(&ServerMessage::Ok);
        }
    }

    fn read(&mut self, all: bool) {
        let (a, b) = self.session.output();
        let n = a.len() + b.len();
        self.session.consumed(if all { n } else { n / 2 }, self.now);
    }

    fn receive(&mut self, bytes: &[u8]) {
        if !bytes.is_empty() && self.session.wants_input() {
            self.received += bytes.len();
            self.session.receive(bytes);
        }
        self.act();
    }

    fn op(&mut self, op: u8) {
        let ts = Timestamp::from(self.now);
        match op % 8 {
            0 => {
                let id = Id::Standard(StandardId::new(u16::from(op) << 3).unwrap());
                let frame = Frame::data(id, &[op; 8][..usize::from(op % 9)]).unwrap();
                self.session.deliver_frame(&frame, ts, self.now);
            }
            1 => {
                let class = u32::from(op) * 0x0101;
                self.session
                    .deliver_error_frame(class, &[op; 8], ts, self.now);
            }
            2 => self.read(false),
            3 => {
                if let Some(t) = self.session.next_deadline() {
                    self.now = self.now.max(t);
                }
            }
            4 => self.now += Nanos::from_millis(u64::from(op)),
            5 => self.prompt = !self.prompt,
            6 => self.answer(),
            _ => match op >> 6 {
                0 => {
                    self.left = true;
                    self.session.close_output();
                }
                1 => {
                    self.left = true;
                    self.ended = true;
                    self.session.close_output();
                    self.session.finish_input();
                }
                k => {
                    self.reads = !self.reads;
                    self.refuse_join = k == 3;
                }
            },
        }
        if self.session.handle_timeout(self.now) == Some(Action::Close) {
            self.closed = true;
        }
        self.act();
    }
}

fuzz_target!(|data: &[u8]| {
    let mut config = SessionConfig::new("vcan0");
    config.max_output = MAX_OUTPUT;
    config.raw_hold_ns = Nanos::from_millis(50);
    config.open_timeout_ns = Nanos::from_secs(1);
    let mut host = Host {
        session: Session::new(config, Nanos::ZERO),
        now: Nanos::ZERO,
        received: 0,
        waiting_join: false,
        waiting_reply: false,
        closed: false,
        prompt: true,
        refuse_join: false,
        reads: true,
        left: false,
        ended: false,
    };
    let mut chunk = Vec::new();
    for item in items(data) {
        match item {
            Item::Data(b) => chunk.push(b),
            Item::Op(op) => {
                host.receive(&chunk);
                chunk.clear();
                host.op(op);
            }
        }
        host.check_output();
        if host.reads {
            host.read(true);
        }
    }
    host.receive(&chunk);
    host.check_output();
});
