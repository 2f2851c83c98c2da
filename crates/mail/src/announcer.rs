//! The bus side of the notifier, sans-IO: a remote frame announces mail, the reader's remote
//! frame on the same ID asks for it, the file protocol carries it.

use std::collections::VecDeque;

use buslab_can::{Frame, Id};

/// Mails waiting for their reader at most: `buslab mail` fetches no more while this many
/// wait (they stay on the server until there is room), so a mailbox flooded while nobody
/// reads holds at most this many texts in memory.
pub const MAX_WAITING: usize = 64;

/// The bus side of the notifier, sans-IO: mails in, frames out.
#[derive(Debug)]
pub struct Announcer {
    id: Id,
    mails: VecDeque<Vec<u8>>,
    /// The first mail was announced and not yet asked for.
    announced: bool,
    outbox: VecDeque<Frame>,
    delivered: usize,
}

impl Announcer {
    pub fn new(id: Id) -> Self {
        Self {
            id,
            mails: VecDeque::new(),
            announced: false,
            outbox: VecDeque::new(),
            delivered: 0,
        }
    }

    fn announcement(&self) -> Frame {
        Frame::remote(self.id, 0).expect("DLC 0")
    }

    /// A new mail: announced at once unless another one waits for its reader.
    pub fn push_mail(&mut self, text: Vec<u8>) {
        self.mails.push_back(text);
        if !self.announced {
            self.announced = true;
            self.outbox.push_back(self.announcement());
        }
    }

    /// Announces the waiting mail again (a MoniCAN started since has no notice).
    pub fn remind(&mut self) {
        if self.announced {
            self.outbox.push_back(self.announcement());
        }
    }

    /// A frame from the bus: MoniCAN's remote frame on the mail ID asks for the mail.
    pub fn handle_frame(&mut self, frame: &Frame) {
        if !(self.announced && frame.is_remote() && frame.id() == self.id && frame.dlc() == 0) {
            return;
        }
        let Some(text) = self.mails.pop_front() else {
            return;
        };
        self.outbox.extend(buslab_can::file::frames(self.id, &text));
        self.delivered += 1;
        self.announced = !self.mails.is_empty();
        if self.announced {
            self.outbox.push_back(self.announcement());
        }
    }

    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.outbox.pop_front()
    }

    /// Mails sent to a reader so far.
    pub fn delivered(&self) -> usize {
        self.delivered
    }

    /// Mails not yet asked for.
    pub fn waiting(&self) -> usize {
        self.mails.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id() -> Id {
        Id::standard(0x700).unwrap()
    }

    #[test]
    fn a_mail_is_announced_and_sent_when_asked_for() {
        let mut a = Announcer::new(id());
        a.push_mail(b"0123456789".to_vec());
        a.push_mail(b"second".to_vec());
        let announce = a.poll_transmit().unwrap();
        assert!(announce.is_remote() && announce.id() == id() && announce.dlc() == 0);
        assert_eq!(a.poll_transmit(), None, "one announcement for two mails");
        a.handle_frame(&"700#00".parse().unwrap());
        a.handle_frame(&"701#R".parse().unwrap());
        assert_eq!(
            a.poll_transmit(),
            None,
            "only a remote frame on the ID asks"
        );
        a.handle_frame(&"700#R".parse().unwrap());
        let sent: Vec<Frame> = std::iter::from_fn(|| a.poll_transmit()).collect();
        assert_eq!(
            sent.len(),
            3,
            "8 bytes, 2 bytes, then the next announcement"
        );
        assert_eq!(sent[0].payload(), b"01234567");
        assert_eq!(sent[1].payload(), b"89");
        assert!(sent[2].is_remote());
        assert_eq!((a.delivered(), a.waiting()), (1, 1));
    }
}
