//! The client's receive path, sans-IO: bytes from the server in; frames and error frames kept
//! for `recv`, every other message handed out. [`crate::SocketcandBus`] owns the socket around
//! it; a benchmark or a test drives it with bytes alone.

use std::collections::VecDeque;

use buslab_bus::bus::matches_any;
use buslab_bus::{ErrorFrame, Filter, Message, Record};

use super::ClientError;
use crate::ProtocolError;
use crate::element::{Deframer, element_text};
use crate::message::{ServerMessage, parse_frame_fast};

/// Received frames and error frames kept for `recv` at most; beyond, the oldest are dropped
/// (with a warning). A client busy in a long request on a busy bus must not grow without end.
pub const MAX_INBOX: usize = 1 << 18;

/// What a client received and has not handed out yet.
#[derive(Debug)]
pub struct Inbound {
    deframer: Deframer,
    inbox: VecDeque<Message>,
    /// Events dropped because the inbox was full, and the count last warned about.
    dropped: u64,
    dropped_warned: u64,
    channel: String,
    filters: Vec<Filter>,
    error_frames: bool,
    /// Frames and error frames taken in so far, kept or not.
    received: u64,
}

impl Inbound {
    /// Received frames are stamped with `channel`.
    pub fn new(channel: &str) -> Self {
        Self {
            deframer: Deframer::new(),
            inbox: VecDeque::new(),
            dropped: 0,
            dropped_warned: 0,
            channel: channel.to_string(),
            filters: Vec::new(),
            error_frames: false,
            received: 0,
        }
    }

    /// Bytes received from the server.
    pub fn push(&mut self, bytes: &[u8]) {
        self.deframer.push(bytes);
    }

    /// Only frames that pass one of `filters` are kept (all if empty).
    pub fn set_filters(&mut self, filters: &[Filter]) {
        self.filters = filters.to_vec();
    }

    /// Whether error frames are kept (a plain socketcand started with -e sends them unasked).
    pub fn set_error_frames(&mut self, on: bool) {
        self.error_frames = on;
    }

    /// Frames and error frames taken in so far, kept or not.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Handles the buffered elements: frames and error frames go to the inbox; the first other
    /// message is returned. `None`: everything buffered was handled.
    pub fn next_message(&mut self) -> Result<Option<ServerMessage>, ClientError> {
        while let Some(inside) = self.deframer.next_inside() {
            let inside = inside?;
            // Frames straight from the buffer; the rest checked and parsed as text (the same
            // result as `next_element` and `ServerMessage::parse`).
            let msg = match parse_frame_fast(inside) {
                Some((frame, timestamp)) => ServerMessage::Frame { frame, timestamp },
                None => ServerMessage::parse(element_text(inside)?)?,
            };
            match msg {
                ServerMessage::Frame { frame, timestamp } => {
                    self.received += 1;
                    // Filtered on arrival too, so unwanted traffic does not pile up (and its
                    // channel name is not copied).
                    if matches_any(&self.filters, &frame) {
                        let m = Message::rx(timestamp, self.channel.clone(), frame);
                        self.keep(m.into_record());
                    }
                }
                ServerMessage::ErrorFrame {
                    class,
                    timestamp,
                    data,
                } => {
                    self.received += 1;
                    if self.error_frames {
                        let error = ErrorFrame::decode(class, &data).map_err(|e| {
                            ProtocolError::Arguments {
                                command: "error",
                                expected: "an error frame",
                                got: e.to_string(),
                            }
                        })?;
                        self.keep(Message::error(timestamp, self.channel.clone(), error));
                    }
                }
                other => return Ok(Some(other)),
            }
        }
        Ok(None)
    }

    /// Keeps an event for `recv`, dropping the oldest when the inbox is full.
    fn keep(&mut self, event: Message) {
        if self.inbox.len() >= MAX_INBOX {
            self.inbox.pop_front();
            self.dropped += 1;
            if self.dropped >= self.dropped_warned.max(1) * 2 || self.dropped_warned == 0 {
                tracing::warn!(
                    "{}: {} received frames dropped so far: the program does not read them (at most {MAX_INBOX} are kept)",
                    self.channel,
                    self.dropped
                );
                self.dropped_warned = self.dropped;
            }
        }
        self.inbox.push_back(event);
    }

    /// The next kept event: error frames only if `with_errors` (else dropped), frames that
    /// pass the filters.
    pub fn pop(&mut self, with_errors: bool) -> Option<Message> {
        while let Some(event) = self.inbox.pop_front() {
            match &event.record {
                Record::Frame(frame) if matches_any(&self.filters, frame) => return Some(event),
                Record::Error(_) if with_errors => return Some(event),
                _ => {}
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// What a client makes of `bytes` read in pieces of `piece` bytes, in order: frames kept,
    /// other messages, errors.
    fn through_inbound(bytes: &[u8], piece: usize) -> Vec<String> {
        let mut inbound = Inbound::new("vcan0");
        let mut seen = Vec::new();
        for read in bytes.chunks(piece) {
            inbound.push(read);
            loop {
                let next = inbound.next_message();
                while let Some(event) = inbound.pop(true) {
                    let Some(m) = event.into_frame() else {
                        panic!("error frames are not kept")
                    };
                    seen.push(format!("{:?} {}", m.record, m.at.as_secs_f64()));
                }
                match next {
                    Ok(None) => break,
                    Ok(Some(m)) => seen.push(format!("{m:?}")),
                    Err(e) => seen.push(e.to_string()),
                }
            }
        }
        seen
    }

    /// The same through the text API: `Deframer::next_element`, then `ServerMessage::parse`.
    fn through_text(bytes: &[u8], piece: usize) -> Vec<String> {
        let mut deframer = Deframer::new();
        let mut seen = Vec::new();
        for read in bytes.chunks(piece) {
            deframer.push(read);
            text_elements(&mut deframer, &mut seen);
        }
        seen
    }

    fn text_elements(deframer: &mut Deframer, seen: &mut Vec<String>) {
        while let Some(element) = deframer.next_element() {
            let message = element
                .map_err(ClientError::from)
                .and_then(|e| ServerMessage::parse(&e).map_err(ClientError::from));
            match message {
                Ok(ServerMessage::Frame { frame, timestamp }) => {
                    seen.push(format!("{frame:?} {}", timestamp.as_secs_f64()));
                }
                Ok(ServerMessage::ErrorFrame { .. }) => {}
                Ok(m) => seen.push(format!("{m:?}")),
                Err(e) => seen.push(e.to_string()),
            }
        }
    }

    fn piece() -> impl Strategy<Value = Vec<u8>> {
        prop_oneof![
            Just(b"< frame 123 1.000001 0102030405060708 >".to_vec()),
            Just(b"< frame 1FFFFFFF 23.5 >".to_vec()),
            Just(b"< frame 123 1.0 R3 >".to_vec()),
            Just(b"< ok >".to_vec()),
            Just(b"< error 004 1.0 00 08 >".to_vec()),
            "< frame [0-9A-Fa-g+]{0,9} [0-9.]{0,9} [0-9A-FRr <]{0,18} >"
                .prop_map(String::into_bytes),
            prop::collection::vec(
                prop_oneof![
                    Just(b'<'),
                    Just(b'>'),
                    Just(b' '),
                    Just(b'\n'),
                    Just(0xff),
                    Just(b'1'),
                    any::<u8>()
                ],
                0..12,
            ),
        ]
    }

    proptest! {
        /// Frames read from the buffer, and garbage, come out as the text API reads them.
        #[test]
        fn the_receive_path_reads_as_the_text_api(
            pieces in prop::collection::vec(piece(), 0..20),
            read in 1usize..64,
        ) {
            let bytes = pieces.concat();
            prop_assert_eq!(through_inbound(&bytes, read), through_text(&bytes, read));
        }
    }

    #[test]
    fn frames_are_kept_for_recv_and_other_messages_handed_out() {
        let text = b"< frame 123 1.000001 0102 >< ok >< frame 7FF 2.5 >\xff< frame 1 1.0 >";
        assert_eq!(
            through_inbound(text, 7),
            [
                "Frame(123#0102) 1.000001",
                "Ok",
                "Frame(7FF#) 2.5",
                "bad data from the server: text outside < >: \"\u{fffd}\"",
                "Frame(001#) 1",
            ]
        );
    }
}
