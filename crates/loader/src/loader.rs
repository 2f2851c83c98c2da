//! The CAN loader (`loadcan.s`, seed 002 §4.4.1) as a sans-IO state machine: frames in,
//! frames and an outcome out, time explicit (ns).
//!
//! 1. It is started by a remote frame with ID 0 and DLC 0 (MoniCAN's hand-over, §4.3.3.3) and
//!    answers at once with a data frame with ID 0 and no data (§4.4.1.1; docs/decisions.md
//!    has why the node does not send §5.4.4.6's remote frame).
//! 2. The supervisor sends the S-record file as ASCII on ID 0, 8 bytes a frame; a frame with
//!    fewer than 8 bytes (possibly none) ends it. The text goes to the receive buffer
//!    (`debut_fichier`, [`TEXT_BUFFER`] bytes).
//! 3. Then every record is checked (syntax, checksum, counts, addresses in the node's memory,
//!    no two records on the same byte). Only a file without a single bad record is loaded:
//!    [`Outcome::Loaded`] carries the program for the node to write into its memory;
//!    [`Outcome::Refused`] names every bad line and nothing is written.
//!
//! A remote frame with ID 0 while a file arrives starts over (the supervisor's new attempt). A
//! transfer that stops for [`IDLE_TIMEOUT`] is given up ([`Outcome::Stopped`]): the seed's
//! loader would wait for ever, leaving the node deaf to everything else.

use buslab_can::{Frame, Id, Nanos, StandardId};

use crate::memory::{MemoryMap, TEXT_BUFFER};
use crate::srec::{self, Program, SrecErrors};

/// The loader's identifier (§4.4.1.1: « d'identificateur 0 »).
pub const LOADER_ID: u16 = 0;
/// A transfer with no frame for this long is given up (10 s).
pub const IDLE_TIMEOUT: Nanos = Nanos::from_secs(10);

/// The loader's identifier as an [`Id`].
pub fn loader_id() -> Id {
    Id::Standard(StandardId::new(LOADER_ID).expect("0 is an 11-bit identifier"))
}

/// Whether `frame` asks for the loader: a remote frame with ID 0 and DLC 0.
pub fn is_request(frame: &Frame) -> bool {
    frame.is_remote() && frame.id() == loader_id() && frame.dlc() == 0
}

/// The loader's answer: a data frame with ID 0 and no data (§4.4.1.1).
pub fn answer() -> Frame {
    Frame::data(loader_id(), &[]).expect("an empty data frame")
}

/// How a transfer ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Every record is good: the node writes `program` into its memory.
    Loaded { program: Program, text_bytes: usize },
    /// Bad records: nothing is written.
    Refused {
        errors: SrecErrors,
        text_bytes: usize,
    },
    /// The file was longer than the receive buffer (what came beyond was not kept).
    TooLong { text_bytes: usize },
    /// No frame for [`IDLE_TIMEOUT`] in the middle of the file.
    Stopped { text_bytes: usize },
}

impl Outcome {
    /// Bytes of S-record text that arrived.
    pub fn text_bytes(&self) -> usize {
        match self {
            Outcome::Loaded { text_bytes, .. }
            | Outcome::Refused { text_bytes, .. }
            | Outcome::TooLong { text_bytes }
            | Outcome::Stopped { text_bytes } => *text_bytes,
        }
    }

    pub fn is_loaded(&self) -> bool {
        matches!(self, Outcome::Loaded { .. })
    }
}

/// The loader while it runs.
#[derive(Debug)]
pub struct Loader {
    map: MemoryMap,
    text: Vec<u8>,
    /// Bytes that arrived beyond the buffer (counted, not kept).
    beyond: usize,
    outbox: Option<Frame>,
    outcome: Option<Outcome>,
    /// When the last frame of the file arrived (or the loader started).
    last_frame: Nanos,
    receiving: bool,
}

impl Loader {
    /// The loader, entered at `now`: its answer to the request is queued.
    pub fn new(map: MemoryMap, now: Nanos) -> Self {
        Self {
            map,
            text: Vec::new(),
            beyond: 0,
            outbox: Some(answer()),
            outcome: None,
            last_frame: now,
            receiving: true,
        }
    }

    /// Bytes of S-record text received so far.
    pub fn received(&self) -> usize {
        self.text.len() + self.beyond
    }

    /// Whether the file is still arriving.
    pub fn is_receiving(&self) -> bool {
        self.receiving
    }

    /// A frame from the bus at `now`. Frames on other identifiers are not the loader's.
    pub fn handle_frame(&mut self, now: Nanos, frame: &Frame) {
        if !self.receiving || frame.id() != loader_id() {
            return;
        }
        if frame.is_remote() {
            // The supervisor starts over.
            self.text.clear();
            self.beyond = 0;
            self.outbox = Some(answer());
            self.last_frame = now;
            return;
        }
        self.last_frame = now;
        let data = frame.payload();
        let room = TEXT_BUFFER.saturating_sub(self.text.len());
        let kept = data.len().min(room);
        self.text.extend_from_slice(&data[..kept]);
        self.beyond += data.len() - kept;
        if data.len() < 8 {
            self.finish();
        }
    }

    /// Time passes: a transfer that stopped is given up.
    pub fn handle_timeout(&mut self, now: Nanos) {
        if self.receiving && now >= self.last_frame.saturating_add(IDLE_TIMEOUT) {
            self.receiving = false;
            self.outcome = Some(Outcome::Stopped {
                text_bytes: self.received(),
            });
        }
    }

    /// When [`handle_timeout`](Self::handle_timeout) must be called.
    pub fn next_deadline(&self) -> Option<Nanos> {
        self.receiving
            .then(|| self.last_frame.saturating_add(IDLE_TIMEOUT))
    }

    /// The next frame to send (the answer).
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.outbox.take()
    }

    /// How the transfer ended, once it has (taken once).
    pub fn take_outcome(&mut self) -> Option<Outcome> {
        self.outcome.take()
    }

    /// The end of the file: the text becomes a program, or the reasons it cannot.
    fn finish(&mut self) {
        self.receiving = false;
        let text_bytes = self.received();
        let text = std::mem::take(&mut self.text);
        self.outcome = Some(if self.beyond > 0 {
            Outcome::TooLong { text_bytes }
        } else {
            check(&self.map, &text).map_or_else(
                |errors| Outcome::Refused { errors, text_bytes },
                |program| Outcome::Loaded {
                    program,
                    text_bytes,
                },
            )
        });
    }
}

/// An S-record file as the loader checks it: every record, then every address against `map`.
/// The host runs the same check before it sends a file.
pub fn check(map: &MemoryMap, text: &[u8]) -> Result<Program, SrecErrors> {
    let program = srec::parse(text)?;
    let errors = map.check_program(&program);
    if errors.is_empty() {
        Ok(program)
    } else {
        Err(errors)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(text: &[u8]) -> Vec<Frame> {
        buslab_can::file::frames(loader_id(), text).collect()
    }

    fn good_file() -> Vec<u8> {
        crate::srec::write(b"prog", [(0x32000, &[0x60u8; 20][..])], Some(0x32000))
    }

    #[test]
    fn it_answers_then_loads_a_good_file() {
        let mut l = Loader::new(MemoryMap::ppc403(), Nanos::new(5));
        assert_eq!(l.poll_transmit(), Some(answer()));
        assert_eq!(l.poll_transmit(), None);
        let text = good_file();
        // Other identifiers are not the loader's.
        l.handle_frame(Nanos::new(6), &"123#0102".parse().unwrap());
        for (i, f) in frames(&text).iter().enumerate() {
            assert!(l.is_receiving());
            l.handle_frame(Nanos::new(10 + i as u64), f);
        }
        assert!(!l.is_receiving());
        let Some(Outcome::Loaded {
            program,
            text_bytes,
        }) = l.take_outcome()
        else {
            panic!("not loaded")
        };
        assert_eq!(text_bytes, text.len());
        assert_eq!(program.start, Some(0x32000));
        assert_eq!(program.ranges(), [(0x32000, 0x32013)]);
        assert_eq!(l.next_deadline(), None);
    }

    #[test]
    fn a_bad_file_is_refused_with_its_lines() {
        let mut text = good_file();
        // Corrupt a digit of the data record (line 2): its checksum no longer agrees.
        let at = text.iter().position(|&b| b == b'\n').unwrap() + 12;
        text[at] = if text[at] == b'0' { b'1' } else { b'0' };
        let mut l = Loader::new(MemoryMap::ppc403(), Nanos::ZERO);
        for f in frames(&text) {
            l.handle_frame(Nanos::new(1), &f);
        }
        let Some(Outcome::Refused { errors, .. }) = l.take_outcome() else {
            panic!("not refused")
        };
        assert_eq!(errors.first().unwrap().line, 2);
        assert!(errors.to_string().contains("checksum"));
        // Flash is not for programs.
        let flash = crate::srec::write(b"", [(0xFFFE_2000, &[1u8][..])], None);
        let errors = check(&MemoryMap::ppc403(), &flash).unwrap_err();
        assert!(
            errors
                .to_string()
                .starts_with("line 2: 0xFFFE2000..=0xFFFE2000 is flash")
        );
    }

    #[test]
    fn a_new_request_starts_over_and_silence_gives_up() {
        let mut l = Loader::new(MemoryMap::ppc403(), Nanos::ZERO);
        l.poll_transmit();
        l.handle_frame(Nanos::new(1), &"000#5331303030303030".parse().unwrap());
        assert_eq!(l.received(), 8);
        l.handle_frame(Nanos::new(2), &"000#R".parse().unwrap());
        assert_eq!(l.received(), 0);
        assert_eq!(l.poll_transmit(), Some(answer()));
        l.handle_frame(Nanos::new(3), &"000#5331303030303030".parse().unwrap());
        assert_eq!(l.next_deadline(), Some(Nanos::new(3) + IDLE_TIMEOUT));
        l.handle_timeout(Nanos::new(2) + IDLE_TIMEOUT);
        assert!(l.is_receiving());
        l.handle_timeout(Nanos::new(3) + IDLE_TIMEOUT);
        assert_eq!(l.take_outcome(), Some(Outcome::Stopped { text_bytes: 8 }));
    }

    #[test]
    fn a_file_beyond_the_buffer_is_refused_whole() {
        let mut l = Loader::new(MemoryMap::ppc403(), Nanos::ZERO);
        let full: Frame = "000#5353535353535353".parse().unwrap();
        for _ in 0..TEXT_BUFFER / 8 + 2 {
            l.handle_frame(Nanos::new(1), &full);
        }
        l.handle_frame(Nanos::new(1), &"000#".parse().unwrap());
        assert_eq!(
            l.take_outcome(),
            Some(Outcome::TooLong {
                text_bytes: TEXT_BUFFER + 16
            })
        );
    }
}
