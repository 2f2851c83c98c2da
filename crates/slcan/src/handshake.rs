//! Opening an adapter, sans-IO: what to send, and how to read the answers so that nothing the
//! adapter still had queued from an earlier session is taken for one.
//!
//! The adapters in use answer differently (`docs/decisions.md`, "SLCAN open"): a Lawicel
//! CANUSB or CAN232 answers every command with CR or BEL and `V` with `V1013`; CANable's slcan
//! firmware answers nothing but `V`, with a line of text (`8ca5d39 https://github.com/…`); a
//! variant of it answers every line with CR or BEL; the CANable 2 fork answers like Lawicel
//! with a text version (`VL2K0 …`); buslab's model answers like Lawicel. What every one of
//! them does is answer `V` with a line no other command produces.
//!
//! So each command goes out followed by `V`, and its answer is the **last** CR or BEL before
//! the version line: an adapter answers in order, so whatever was left over (a CR from the last
//! session's `C`, a BEL, a frame) comes before, never after, and cannot shift the answers. No
//! CR or BEL before it: the adapter does not acknowledge commands (CANable).
//!
//! The first exchange is `C` then `V`: `C` ends a line a previous user left half-typed (as
//! garbage) and closes the channel; a bare CR is not used because CANable's firmware runs its
//! previous command again on an empty line (a frame left there would go out once more). The
//! version line that answers marks where the leftovers end; in case a leftover was itself a
//! version line, the client then reads until the line stays quiet ([`Handshake::settled`])
//! and the last version line wins.

use std::collections::VecDeque;

use crate::codec::{Command, Reply, format_command};

/// What the adapter said it is, answering `V`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Firmware {
    /// `Vhhss`: Lawicel CANUSB/CAN232, buslab's model, slcanpty and most clones.
    Lawicel([u8; 4]),
    /// A line of text: CANable's slcan firmware (`<git describe> <repository>`).
    Text(String),
}

impl Firmware {
    /// `1013`, or the text.
    pub fn as_str(&self) -> &str {
        match self {
            Firmware::Lawicel(v) => std::str::from_utf8(v).unwrap_or("?"),
            Firmware::Text(t) => t,
        }
    }
}

/// What the host wants of the channel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plan {
    /// The bit rate in bit/s and the Lawicel command that sets it (`S6`, `s031C`; `None` for
    /// 750 kbit/s, which only CANable's `S7` reaches); `None` keeps what the adapter has.
    pub bitrate: Option<(u32, Option<Command>)>,
    /// Open with `L` (receive only).
    pub listen_only: bool,
    /// The CAN FD data bit rate code to set (`Yn`, [`crate::codec::DATA_BITRATES`]); `None`
    /// keeps what the adapter has.
    pub data_bitrate: Option<u8>,
}

/// What the adapter did with the acceptance code and mask (`M`/`m`, Lawicel's SJA1000 ACR
/// and AMR) asked with [`Handshake::with_acceptance`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcceptanceAnswer {
    /// Not sent: none asked, or the adapter is not Lawicel's kind (CANable's `M` is its
    /// silent mode).
    NotSent,
    /// Both answered CR.
    Taken,
    /// One answered BEL: the adapter has no such filter.
    Refused,
    /// Sent; the adapter answers no command.
    Unconfirmed,
}

/// Why the channel was not opened.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum HandshakeError {
    #[error("the adapter refused {command:?} (answered BEL)")]
    Refused { command: String },
    #[error(
        "bit rate {bitrate} bit/s cannot be set on CANable's slcan firmware: it takes S0..S8 only (10000, 20000, 50000, 100000, 125000, 250000, 500000, 750000, 1000000; its S7 is 750 kbit/s, not Lawicel's 800)"
    )]
    CanableBitrate { bitrate: u32 },
    #[error(
        "bit rate {bitrate} bit/s cannot be set: it is CANable's S7, and this adapter is no CANable (Lawicel's S7 is 800 kbit/s, and no SJA1000 timing at 8 MHz reaches {bitrate})"
    )]
    NotCanable { bitrate: u32 },
}

/// The bit rates of CANable's `S0`..`S8` (its firmware's table: `S7` is 750 kbit/s).
pub const CANABLE_BITRATES: [u32; 9] = [
    10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 750_000, 1_000_000,
];

/// Where the handshake is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Status {
    /// Waiting for the version line that follows `command` (shown as written, `S6`).
    Waiting {
        command: String,
    },
    /// The first version line came; read until the line is quiet, then call
    /// [`Handshake::settled`].
    Settling,
    /// The channel is open.
    Open,
    Failed(HandshakeError),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Purpose {
    Sync,
    Timestamps,
    Serial,
    /// CANable's own `M0`/`M1` (normal/silent), which it has instead of `L`.
    CanableMode,
    /// Lawicel's `m` and `M` (acceptance mask and code); a refusal does not stop the opening.
    Acceptance,
    Bitrate,
    Open,
}

#[derive(Clone, Debug)]
struct Step {
    purpose: Purpose,
    command: Command,
}

/// The opening exchange: feed it the adapter's replies, send what it gives.
#[derive(Clone, Debug)]
pub struct Handshake {
    plan: Plan,
    steps: VecDeque<Step>,
    current: Option<Step>,
    settling: bool,
    transmit: Vec<u8>,
    /// CR (true) or BEL (false) answers seen in the current step, in order.
    acks: Vec<bool>,
    firmware: Option<Firmware>,
    serial: Option<[u8; 4]>,
    acknowledges: bool,
    trailing_ack: bool,
    timestamps: Option<bool>,
    leftovers: u64,
    failed: Option<HandshakeError>,
    open: bool,
    acceptance: Option<(u32, u32)>,
    acceptance_answer: AcceptanceAnswer,
}

impl Handshake {
    pub fn new(plan: Plan) -> Self {
        let mut hs = Self {
            plan,
            steps: VecDeque::from([
                Step {
                    purpose: Purpose::Timestamps,
                    command: Command::Timestamps(true),
                },
                Step {
                    purpose: Purpose::Serial,
                    command: Command::SerialNumber,
                },
            ]),
            current: None,
            settling: false,
            transmit: Vec::new(),
            acks: Vec::new(),
            firmware: None,
            serial: None,
            acknowledges: false,
            trailing_ack: false,
            timestamps: None,
            leftovers: 0,
            failed: None,
            open: false,
            acceptance: None,
            acceptance_answer: AcceptanceAnswer::NotSent,
        };
        hs.start(Step {
            purpose: Purpose::Sync,
            command: Command::Close,
        });
        hs
    }

    /// Also sets the acceptance code and mask (SJA1000 ACR0..3 and AMR0..3, the first byte
    /// the highest) before the channel opens, on adapters that answer `V` as Lawicel's do.
    pub fn with_acceptance(mut self, code: u32, mask: u32) -> Self {
        self.acceptance = Some((code, mask));
        self
    }

    /// What the adapter did with the acceptance code and mask.
    pub fn acceptance_answer(&self) -> AcceptanceAnswer {
        self.acceptance_answer
    }

    /// Bytes to write to the adapter.
    pub fn poll_transmit(&mut self) -> Option<Vec<u8>> {
        (!self.transmit.is_empty()).then(|| std::mem::take(&mut self.transmit))
    }

    pub fn status(&self) -> Status {
        if let Some(e) = &self.failed {
            return Status::Failed(e.clone());
        }
        if self.open {
            return Status::Open;
        }
        if self.settling {
            return Status::Settling;
        }
        Status::Waiting {
            command: self.current.as_ref().map_or_else(String::new, |s| {
                let mut bytes = Vec::new();
                format_command(&s.command, &mut bytes);
                bytes.pop();
                String::from_utf8_lossy(&bytes).into_owned()
            }),
        }
    }

    /// One reply from the adapter. Frames received once the channel is being opened are given
    /// back to keep; everything before is a leftover and dropped, and so is everything after a
    /// failure.
    pub fn handle(&mut self, reply: Reply) -> Option<Reply> {
        if self.failed.is_some() {
            return None;
        }
        if self.open {
            return Some(reply)
                .filter(|r| matches!(r, Reply::Frame { .. } | Reply::FdFrame { .. }));
        }
        let purpose = self.current.as_ref().map(|s| s.purpose);
        let firmware = match reply {
            Reply::Version(v) => Firmware::Lawicel(v),
            Reply::FirmwareText(t) => Firmware::Text(t),
            Reply::Frame { .. } | Reply::FdFrame { .. }
                if purpose == Some(Purpose::Open) && !self.settling =>
            {
                return Some(reply);
            }
            Reply::Ok | Reply::Error if !self.settling && purpose != Some(Purpose::Sync) => {
                self.acks.push(reply == Reply::Ok);
                return None;
            }
            Reply::SerialNumber(n) if purpose == Some(Purpose::Serial) && !self.settling => {
                self.serial = Some(n);
                return None;
            }
            _ => {
                self.leftovers += 1;
                return None;
            }
        };
        if self.settling {
            // The version line taken first was left over from before.
            self.leftovers += 1;
            self.firmware = Some(firmware);
            return None;
        }
        match purpose {
            Some(Purpose::Sync) => {
                self.firmware = Some(firmware);
                self.settling = true;
            }
            Some(p) => self.finish_step(p),
            None => self.leftovers += 1,
        }
        None
    }

    /// A line from the adapter that is not a reply (garbage, or the rest of a line cut off).
    pub fn handle_garbage(&mut self) {
        self.leftovers += 1;
    }

    /// The line stayed quiet after the first version line: the leftovers are all read.
    pub fn settled(&mut self) {
        if self.settling {
            self.settling = false;
            self.next();
        }
    }

    /// The version line, once it came.
    pub fn firmware(&self) -> Option<&Firmware> {
        self.firmware.as_ref()
    }

    /// The `N` answer, if any.
    pub fn serial(&self) -> Option<[u8; 4]> {
        self.serial
    }

    /// Whether the adapter answers commands (and frames) with CR or BEL (CANable does not).
    pub fn acknowledges(&self) -> bool {
        self.acknowledges
    }

    /// Whether the adapter follows its version line with a CR (a CANable variant): one is
    /// still on its way after the handshake.
    pub fn trailing_ack(&self) -> bool {
        self.trailing_ack
    }

    /// Whether `Z1` was accepted (`None`: the adapter does not say).
    pub fn timestamps(&self) -> Option<bool> {
        self.timestamps
    }

    /// Lines read that belonged to no command of this handshake.
    pub fn leftovers(&self) -> u64 {
        self.leftovers
    }

    fn start(&mut self, step: Step) {
        format_command(&step.command, &mut self.transmit);
        format_command(&Command::Version, &mut self.transmit);
        self.acks.clear();
        self.current = Some(step);
    }

    /// CANable's own firmware: text for a version, and no answers to commands.
    fn silent_canable(&self) -> bool {
        !self.acknowledges && matches!(self.firmware, Some(Firmware::Text(_)))
    }

    fn finish_step(&mut self, purpose: Purpose) {
        let answer = self.acks.last().copied();
        // An answer to the previous version line and one to this command.
        if self.acks.len() >= 2 {
            self.trailing_ack = true;
        }
        match purpose {
            Purpose::Sync => {}
            Purpose::Timestamps => {
                self.acknowledges = answer.is_some();
                self.timestamps = answer;
                self.plan_the_rest();
            }
            Purpose::Serial | Purpose::CanableMode => {}
            Purpose::Acceptance => {
                self.acceptance_answer = match (self.acceptance_answer, answer) {
                    (AcceptanceAnswer::Refused, _) | (_, Some(false)) => AcceptanceAnswer::Refused,
                    (_, Some(true)) => AcceptanceAnswer::Taken,
                    (_, None) => AcceptanceAnswer::Unconfirmed,
                };
            }
            Purpose::Bitrate | Purpose::Open => {
                if answer == Some(false) {
                    let command = self.current.as_ref().map(|s| s.command.clone());
                    let listen_fallback = purpose == Purpose::Open
                        && command == Some(Command::ListenOnly)
                        && matches!(self.firmware, Some(Firmware::Text(_)));
                    if listen_fallback {
                        // A CANable variant that answers but has no `L`: its own silent mode.
                        self.steps.push_back(canable_mode(true));
                        self.steps.push_back(open_step(false));
                    } else {
                        let Status::Waiting { command } = self.status() else {
                            unreachable!("a step is under way");
                        };
                        self.failed = Some(HandshakeError::Refused { command });
                        return;
                    }
                } else if purpose == Purpose::Open {
                    self.open = true;
                    self.current = None;
                    return;
                }
            }
        }
        self.next();
    }

    /// The steps after the adapter showed how it answers.
    fn plan_the_rest(&mut self) {
        let canable = self.silent_canable();
        // CANable keeps its silent mode (`M1`) until told otherwise, also across `C`; a
        // listen-only open of the variants that answer tries `L` first.
        let text = matches!(self.firmware, Some(Firmware::Text(_)));
        if canable || (text && !self.plan.listen_only) {
            self.steps.push_back(canable_mode(self.plan.listen_only));
        }
        if let Some((bitrate, lawicel)) = self.plan.bitrate.clone() {
            let command = if canable {
                match CANABLE_BITRATES.iter().position(|&r| r == bitrate) {
                    Some(code) => Command::Bitrate(code as u8),
                    None => {
                        self.failed = Some(HandshakeError::CanableBitrate { bitrate });
                        return;
                    }
                }
            } else if let Some(lawicel) = lawicel {
                lawicel
            } else {
                self.failed = Some(HandshakeError::NotCanable { bitrate });
                return;
            };
            self.steps.push_back(Step {
                purpose: Purpose::Bitrate,
                command,
            });
        }
        // After the nominal rate, as python-can sends it; refused (BEL) by an adapter that
        // knows no FD, which fails the opening as a refused bit rate does.
        if let Some(code) = self.plan.data_bitrate {
            self.steps.push_back(Step {
                purpose: Purpose::Bitrate,
                command: Command::DataBitrate(code),
            });
        }
        if let (Some((code, mask)), Some(Firmware::Lawicel(_))) = (self.acceptance, &self.firmware)
        {
            for command in [Command::AcceptanceMask(mask), Command::AcceptanceCode(code)] {
                self.steps.push_back(Step {
                    purpose: Purpose::Acceptance,
                    command,
                });
            }
        }
        self.steps
            .push_back(open_step(self.plan.listen_only && !canable));
    }

    fn next(&mut self) {
        if self.failed.is_some() {
            return;
        }
        match self.steps.pop_front() {
            Some(step) => self.start(step),
            None => {
                self.open = true;
                self.current = None;
            }
        }
    }
}

fn canable_mode(silent: bool) -> Step {
    Step {
        purpose: Purpose::CanableMode,
        command: Command::Other {
            letter: b'M',
            argument: if silent { "1" } else { "0" }.into(),
        },
    }
}

fn open_step(listen_only: bool) -> Step {
    Step {
        purpose: Purpose::Open,
        command: if listen_only {
            Command::ListenOnly
        } else {
            Command::Open
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{Line, LineSplitter, MAX_REPLY_LINE, parse_reply};

    fn plan(bitrate: Option<u32>, listen_only: bool) -> Plan {
        Plan {
            bitrate: bitrate.map(|b| {
                let code = crate::codec::STANDARD_BITRATES
                    .iter()
                    .position(|&r| r == b)
                    .unwrap();
                (b, Some(Command::Bitrate(code as u8)))
            }),
            listen_only,
            data_bitrate: None,
        }
    }

    /// Feeds `bytes` as the adapter's output; the frames kept.
    fn feed(hs: &mut Handshake, bytes: &[u8]) -> Vec<Reply> {
        let mut splitter = LineSplitter::with_limit(MAX_REPLY_LINE);
        let mut kept = Vec::new();
        for &b in bytes {
            let parsed = match splitter.push(b) {
                None => continue,
                Some(Line::Text(t)) => parse_reply(t, false),
                Some(Line::Bell(t)) => parse_reply(t, true),
                Some(Line::TooLong) => {
                    hs.handle_garbage();
                    continue;
                }
            };
            match parsed {
                Ok(r) => kept.extend(hs.handle(r)),
                Err(_) => hs.handle_garbage(),
            }
        }
        kept
    }

    fn sent(hs: &mut Handshake) -> String {
        String::from_utf8(hs.poll_transmit().unwrap_or_default()).unwrap()
    }

    #[test]
    fn a_lawicel_adapter_with_leftovers_opens() {
        let mut hs = Handshake::new(plan(Some(500_000), false));
        assert_eq!(sent(&mut hs), "C\rV\r");
        // The last session's close answered late, a BEL and a frame before it; a half line.
        feed(&mut hs, b"\r\x07t1232AABB\r23AA\r\x07V1013\r");
        assert_eq!(hs.status(), Status::Settling);
        hs.settled();
        assert_eq!(sent(&mut hs), "Z1\rV\r");
        feed(&mut hs, b"\rV1013\r");
        assert_eq!(sent(&mut hs), "N\rV\r");
        feed(&mut hs, b"NA123\rV1013\r");
        assert_eq!(sent(&mut hs), "S6\rV\r");
        feed(&mut hs, b"\rV1013\r");
        assert_eq!(sent(&mut hs), "O\rV\r");
        let kept = feed(&mut hs, b"\rt1230\rV1013\r");
        assert_eq!(hs.status(), Status::Open);
        assert_eq!(kept.len(), 1, "a frame after O is the bus's");
        assert_eq!(hs.firmware(), Some(&Firmware::Lawicel(*b"1013")));
        assert_eq!(hs.serial(), Some(*b"A123"));
        assert!(hs.acknowledges() && !hs.trailing_ack());
        assert_eq!(hs.timestamps(), Some(true));
        assert_eq!(hs.leftovers(), 5);
    }

    #[test]
    fn a_stale_version_line_is_replaced_while_settling() {
        let mut hs = Handshake::new(plan(None, false));
        sent(&mut hs);
        feed(&mut hs, b"V0101\r\x07\rV1013\r");
        hs.settled();
        assert_eq!(hs.firmware(), Some(&Firmware::Lawicel(*b"1013")));
        assert_eq!(hs.leftovers(), 3);
    }

    #[test]
    fn a_refused_open_is_an_error_naming_it() {
        let mut hs = Handshake::new(plan(None, false));
        sent(&mut hs);
        feed(&mut hs, b"\rV1013\r");
        hs.settled();
        feed(&mut hs, b"\rV1013\rNA123\rV1013\r");
        assert_eq!(sent(&mut hs), "Z1\rV\rN\rV\rO\rV\r");
        feed(&mut hs, b"\x07V1013\r");
        assert_eq!(
            hs.status(),
            Status::Failed(HandshakeError::Refused {
                command: "O".into()
            })
        );
    }

    #[test]
    fn canable_firmware_answers_only_v_and_gets_its_own_commands() {
        let text = b"8ca5d39 https://github.com/normaldotcom/canable-fw.git\r";
        let mut hs = Handshake::new(plan(Some(500_000), true));
        sent(&mut hs);
        feed(&mut hs, text);
        hs.settled();
        for _ in 0..2 {
            sent(&mut hs);
            feed(&mut hs, text);
        }
        assert!(!hs.acknowledges());
        // Listen-only is its M1; 500k its S6; then O.
        assert_eq!(sent(&mut hs), "M1\rV\r");
        feed(&mut hs, text);
        assert_eq!(sent(&mut hs), "S6\rV\r");
        feed(&mut hs, text);
        assert_eq!(sent(&mut hs), "O\rV\r");
        feed(&mut hs, text);
        assert_eq!(hs.status(), Status::Open);
        assert_eq!(hs.timestamps(), None);

        let mut hs = Handshake::new(plan(Some(800_000), false));
        sent(&mut hs);
        feed(&mut hs, text);
        hs.settled();
        feed(&mut hs, text);
        feed(&mut hs, text);
        let Status::Failed(e) = hs.status() else {
            panic!("{:?}", hs.status());
        };
        assert!(e.to_string().contains("its S7 is 750 kbit/s"), "{e}");
    }

    #[test]
    fn a_canable_variant_that_acknowledges_and_has_no_l() {
        // Every line gets CR or BEL, the version text is followed by a CR; Z, N and L unknown.
        let text = b"8ca5d39 https://github.com/normaldotcom/canable-fw.git\r\r";
        let mut hs = Handshake::new(plan(None, true));
        sent(&mut hs);
        feed(&mut hs, b"\r");
        feed(&mut hs, text);
        hs.settled();
        feed(&mut hs, b"\x07");
        feed(&mut hs, text);
        feed(&mut hs, b"\x07");
        feed(&mut hs, text);
        assert!(hs.acknowledges() && hs.trailing_ack());
        assert_eq!(sent(&mut hs), "Z1\rV\rN\rV\rL\rV\r");
        feed(&mut hs, b"\x07");
        feed(&mut hs, text);
        assert_eq!(sent(&mut hs), "M1\rV\r");
        feed(&mut hs, b"\r");
        feed(&mut hs, text);
        assert_eq!(sent(&mut hs), "O\rV\r");
        feed(&mut hs, b"\r");
        feed(&mut hs, text);
        assert_eq!(hs.status(), Status::Open);
    }
}
