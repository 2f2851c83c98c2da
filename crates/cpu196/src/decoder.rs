//! Streaming frame decoder with the kernel's error handling (`reception_commande`): a command
//! byte must be followed by its complement, and the whole frame must arrive without a pause
//! longer than the time-out.

use buslab_device::Nanos;

use crate::adconfig::AdConfig;
use crate::message::{Message, ParseError};
use crate::wire::{self, Lengths, ParamsError};

/// Default pause allowed between two bytes of one frame.
pub const DEFAULT_TIMEOUT_NS: Nanos = Nanos::from_millis(200);

/// A framing problem, reported the way the kernel reports it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// `msg_reception_error`: `got` is not the complement of `cmd`. `got` is taken as the
    /// start of the next frame (so a stream resynchronises on the next good command).
    #[error("command {cmd:02X}h was followed by {got:02X}h instead of its complement {want:02X}h", want = !*cmd)]
    WrongComplement { cmd: u8, got: u8 },
    /// `msg_time_out`: the frame stopped arriving.
    #[error("{name} ({cmd:02X}h) timed out after {received} parameter bytes", name = wire::command_name(*cmd))]
    TimeOut { cmd: u8, received: usize },
    /// `msg_invalid_parameter_value`: the frame is complete (or cannot be delimited) but wrong.
    #[error(transparent)]
    Params(#[from] ParamsError),
    #[error(transparent)]
    Parse(#[from] ParseError),
}

/// Data bytes of a PIC block write (`F6 02`) acknowledged at a time.
pub const PIC_CHUNK: usize = 256;

/// What the decoder produced.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    Message(Message),
    Error(FrameError),
    /// 256 more data bytes of a PIC block write (`F6 02 Bloc Data[0..4095]`) are in, before
    /// the frame is complete: the kernel acknowledges each 256 as they arrive ("réponse d'un
    /// message msg_completed tous les 256 octets (16 fois)"). Chunks 0..=14 come this way; the
    /// last one completes the frame and comes as the [`Message::PicWrite`].
    PicChunk {
        block: u8,
        index: u8,
        data: Box<[u8; PIC_CHUNK]>,
    },
}

#[derive(Clone, Debug)]
enum State {
    Idle,
    Complement {
        cmd: u8,
    },
    Params {
        cmd: u8,
        buf: Vec<u8>,
        need: Option<usize>,
    },
}

/// Parameter counts the decoder needs beyond the bytes.
#[derive(Clone, Debug)]
struct Context {
    user: Box<[u8; 0xF0]>,
    adcont: Option<usize>,
}

impl Lengths for Context {
    fn user_len(&self, cmd: u8) -> usize {
        self.user[cmd as usize] as usize
    }
    fn adcont_len(&self) -> Option<usize> {
        self.adcont
    }
}

/// Turns a byte stream (with arrival times) into [`Event`]s.
#[derive(Clone, Debug)]
pub struct Decoder {
    state: State,
    ctx: Context,
    timeout_ns: Nanos,
    last_byte_at: Nanos,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    pub fn new() -> Self {
        Self {
            state: State::Idle,
            ctx: Context {
                user: Box::new([0; 0xF0]),
                adcont: None,
            },
            timeout_ns: DEFAULT_TIMEOUT_NS,
            last_byte_at: Nanos::ZERO,
        }
    }

    /// Pause allowed between two bytes of one frame.
    pub fn with_timeout(mut self, timeout_ns: Nanos) -> Self {
        self.timeout_ns = timeout_ns;
        self
    }

    /// Declares that user command `cmd` (00h..EFh) carries `len` parameter bytes (default 0).
    pub fn set_user_len(&mut self, cmd: u8, len: u8) {
        if let Some(slot) = self.ctx.user.get_mut(cmd as usize) {
            *slot = len;
        }
    }

    /// Sets the `FA` data length directly (`None`: FA frames cannot be delimited).
    pub fn set_adcont_len(&mut self, len: Option<usize>) {
        self.ctx.adcont = len;
    }

    pub fn adcont_len(&self) -> Option<usize> {
        self.ctx.adcont
    }

    /// Whether a frame is partly received.
    pub fn in_frame(&self) -> bool {
        !matches!(self.state, State::Idle)
    }

    /// When [`poll`](Self::poll) will report a time-out if no byte arrives.
    pub fn deadline(&self) -> Option<Nanos> {
        self.in_frame().then(|| self.last_byte_at + self.timeout_ns)
    }

    /// Reports a time-out if the partial frame has waited too long.
    pub fn poll(&mut self, now: Nanos) -> Option<Event> {
        let deadline = self.deadline()?;
        if now < deadline {
            return None;
        }
        let (cmd, received) = match &self.state {
            State::Complement { cmd } => (*cmd, 0),
            State::Params { cmd, buf, .. } => (*cmd, buf.len()),
            State::Idle => unreachable!("deadline is None when idle"),
        };
        self.state = State::Idle;
        Some(Event::Error(FrameError::TimeOut { cmd, received }))
    }

    /// Feeds one byte that arrived at `now`.
    pub fn push(&mut self, now: Nanos, byte: u8) -> Option<Event> {
        // A frame that timed out before this byte is reported now; the byte starts afresh
        // (at most one event is produced since a lone byte never completes a frame).
        let timed_out = self.poll(now);
        self.last_byte_at = now;
        let event = match core::mem::replace(&mut self.state, State::Idle) {
            State::Idle => {
                self.state = State::Complement { cmd: byte };
                None
            }
            State::Complement { cmd } if byte == !cmd => self.begin_params(cmd),
            State::Complement { cmd } => {
                self.state = State::Complement { cmd: byte };
                Some(Event::Error(FrameError::WrongComplement { cmd, got: byte }))
            }
            State::Params { cmd, mut buf, need } => {
                buf.push(byte);
                let chunk = pic_chunk(cmd, &buf);
                let event = self.advance(cmd, buf, need);
                debug_assert!(chunk.is_none() || event.is_none());
                chunk.or(event)
            }
        };
        debug_assert!(timed_out.is_none() || event.is_none());
        timed_out.or(event)
    }

    fn begin_params(&mut self, cmd: u8) -> Option<Event> {
        self.advance(cmd, Vec::new(), None)
    }

    fn advance(&mut self, cmd: u8, buf: Vec<u8>, mut need: Option<usize>) -> Option<Event> {
        if need.is_none() {
            match wire::params_len(cmd, &buf, &self.ctx) {
                Ok(n) => need = n,
                Err(e) => return Some(Event::Error(e.into())),
            }
        }
        match need {
            Some(n) if buf.len() >= n => Some(self.finish(cmd, &buf)),
            _ => {
                self.state = State::Params { cmd, buf, need };
                None
            }
        }
    }

    fn finish(&mut self, cmd: u8, params: &[u8]) -> Event {
        match Message::parse(cmd, params) {
            Ok(m) => {
                // The board announces the layout of its FA frames with a CFGAD reply.
                if let Message::CfgAd { c196, .. } = &m {
                    self.ctx.adcont = AdConfig::parse(c196).ok().and_then(|c| c.frame_data_len());
                }
                Event::Message(m)
            }
            Err(e) => Event::Error(e.into()),
        }
    }
}

/// The chunk a PIC block write's parameters `buf` just completed, if the frame goes on.
fn pic_chunk(cmd: u8, buf: &[u8]) -> Option<Event> {
    const HEAD: usize = 2;
    let data = buf.len().checked_sub(HEAD)?;
    if cmd != wire::PRGPIC || buf[0] != 0x02 || data == 0 || data % PIC_CHUNK != 0 {
        return None;
    }
    if data >= wire::PIC_BLOCK {
        return None;
    }
    let chunk = <[u8; PIC_CHUNK]>::try_from(&buf[buf.len() - PIC_CHUNK..]).ok()?;
    Some(Event::PicChunk {
        block: buf[1],
        index: (data / PIC_CHUNK - 1) as u8,
        data: Box::new(chunk),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codes::MsgCode;
    use crate::message::Message;

    fn feed(d: &mut Decoder, t0: Nanos, bytes: &[u8]) -> Vec<Event> {
        bytes
            .iter()
            .enumerate()
            .filter_map(|(i, &b)| d.push(t0 + Nanos::new(1000) * i as u64, b))
            .collect()
    }

    #[test]
    fn resynchronises_after_garbage() {
        let mut d = Decoder::new();
        let mut bytes = vec![0x12, 0x34];
        bytes.extend(Message::Msg(MsgCode::COMPLETED).to_bytes().unwrap());
        let ev = feed(&mut d, Nanos::ZERO, &bytes);
        assert_eq!(
            ev,
            vec![
                Event::Error(FrameError::WrongComplement {
                    cmd: 0x12,
                    got: 0x34
                }),
                Event::Error(FrameError::WrongComplement {
                    cmd: 0x34,
                    got: 0xFE
                }),
                Event::Message(Message::Msg(MsgCode::COMPLETED)),
            ]
        );
    }

    #[test]
    fn a_truncated_frame_times_out() {
        let mut d = Decoder::new().with_timeout(Nanos::new(1_000_000));
        assert!(feed(&mut d, Nanos::ZERO, &[0xF5, 0x0A, 0x00, 0x01]).is_empty());
        assert_eq!(d.deadline(), Some(Nanos::new(3000 + 1_000_000)));
        assert_eq!(d.poll(Nanos::new(1_002_999)), None);
        assert_eq!(
            d.poll(Nanos::new(1_003_000)),
            Some(Event::Error(FrameError::TimeOut {
                cmd: 0xF5,
                received: 2
            }))
        );
        assert!(!d.in_frame());
        // The next frame decodes normally.
        assert_eq!(
            feed(&mut d, Nanos::new(2_000_000), &[0xFF, 0x00]),
            vec![Event::Message(Message::Watchdog)]
        );
    }

    #[test]
    fn late_byte_reports_time_out_then_starts_a_new_frame() {
        let mut d = Decoder::new().with_timeout(Nanos::new(1000));
        assert_eq!(d.push(Nanos::ZERO, 0xF3), None);
        assert_eq!(
            d.push(Nanos::new(5000), 0xFF),
            Some(Event::Error(FrameError::TimeOut {
                cmd: 0xF3,
                received: 0
            }))
        );
        assert_eq!(
            d.push(Nanos::new(5100), 0x00),
            Some(Event::Message(Message::Watchdog))
        );
    }

    #[test]
    fn unknown_subcode_is_an_invalid_parameter() {
        let mut d = Decoder::new();
        let ev = feed(&mut d, Nanos::ZERO, &[0xF5, 0x0A, 0x07]);
        assert!(matches!(ev[..], [Event::Error(FrameError::Params(_))]));
        assert!(!d.in_frame());
    }

    #[test]
    fn a_pic_block_write_reports_each_256_bytes_as_they_arrive() {
        let data: Box<[u8; wire::PIC_BLOCK]> = Box::new(core::array::from_fn(|i| (i / 256) as u8));
        let bytes = Message::PicWrite { block: 2, data }.to_bytes().unwrap();
        let mut d = Decoder::new();
        let events = feed(&mut d, Nanos::ZERO, &bytes);
        assert_eq!(events.len(), 16);
        for (i, e) in events[..15].iter().enumerate() {
            let Event::PicChunk { block, index, data } = e else {
                panic!("chunk {i}: {e:?}");
            };
            assert_eq!((*block, *index as usize), (2, i));
            assert!(data.iter().all(|&b| b as usize == i));
        }
        assert!(matches!(
            events[15],
            Event::Message(Message::PicWrite { block: 2, .. })
        ));
    }

    #[test]
    fn user_commands_take_their_declared_length() {
        let mut d = Decoder::new();
        d.set_user_len(0x10, 2);
        let ev = feed(&mut d, Nanos::ZERO, &[0x10, 0xEF, 1, 2, 0x11, 0xEE]);
        assert_eq!(
            ev,
            vec![
                Event::Message(Message::User {
                    cmd: 0x10,
                    params: vec![1, 2]
                }),
                Event::Message(Message::User {
                    cmd: 0x11,
                    params: vec![]
                }),
            ]
        );
    }
}
