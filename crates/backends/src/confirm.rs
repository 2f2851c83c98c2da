//! Waiting until the frames a client handed to a bus were transmitted or given up: a
//! socketcand `send` has no confirmation, and a tool that leaves earlier pulls its node off the
//! bus with frames still queued.

use std::time::Duration;

use buslab_bus::{BusError, CanBus, Human, NodeStatus};
use buslab_can::wire::LONGEST_FRAME_BITS;

/// What could be confirmed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Confirmation {
    /// Every frame was transmitted.
    AllSent,
    /// The bus cannot tell (no administration side: a plain socketcand, a SocketCAN interface,
    /// an SLCAN adapter — the last two took the frames into their queue, as cansend leaves
    /// it).
    Unconfirmable,
}

/// Why the frames were not all confirmed.
#[derive(Debug, thiserror::Error)]
pub enum ConfirmError {
    #[error("{failed} of {count} frames were not sent; the node's status:\n{status}")]
    NotSent {
        failed: u64,
        count: u64,
        status: Box<NodeStatus>,
    },
    #[error(
        "only {sent} of {count} frames were sent within {} (no other node to acknowledge them, or a bit rate mismatch?); the node's status:\n{status}",
        Human(*within)
    )]
    Timeout {
        sent: u64,
        count: u64,
        within: Duration,
        status: Box<NodeStatus>,
    },
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// Waits until the `count` frames this client sent were transmitted or given up, for
/// `timeout` beyond the time the frames still queued need on the bus at its bit rate (each
/// counted as the longest classic frame).
pub fn confirm_sent(
    bus: &mut (dyn CanBus + Send),
    count: u64,
    timeout: Duration,
) -> Result<Confirmation, ConfirmError> {
    let Some(admin) = bus.admin() else {
        return Ok(Confirmation::Unconfirmable);
    };
    let before = admin.node_status(None)?;
    let done = before.counters.sent + before.counters.tx_failed;
    let pending = count.saturating_sub(done);
    let on_the_bus = Duration::from_secs_f64(
        (pending * LONGEST_FRAME_BITS) as f64 / f64::from(before.bus.bitrate.max(1)),
    );
    let within = timeout.saturating_add(on_the_bus);
    match admin.flush(within) {
        Ok(report) if report.failed > 0 => Err(ConfirmError::NotSent {
            failed: report.failed,
            count,
            status: Box::new(admin.node_status(None)?),
        }),
        Ok(_) => Ok(Confirmation::AllSent),
        Err(BusError::Timeout { .. }) => {
            let status = admin.node_status(None)?;
            Err(ConfirmError::Timeout {
                sent: status.counters.sent,
                count,
                within,
                status: Box::new(status),
            })
        }
        Err(e) => Err(e.into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_bus::{
        BusAdmin, BusSummary, ErrorState, Filter, Message, NodeCounters, NodeInfo, NodeRef,
        NodeRegisters, TxReport,
    };
    use buslab_can::Frame;

    /// A bus whose flush answers as told, at 125 kbit/s; `admin: false` has no admin side.
    struct Flushing {
        admin: bool,
        answer: Option<TxReport>,
        asked_within: Option<Duration>,
    }

    impl CanBus for Flushing {
        fn send(&mut self, _: &Frame) -> Result<(), BusError> {
            Ok(())
        }
        fn recv(&mut self, _: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
            Ok(None)
        }
        fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
            Ok(())
        }
        fn state(&mut self) -> Result<ErrorState, BusError> {
            Ok(ErrorState::Active)
        }
        fn channel_info(&self) -> String {
            "flushing".into()
        }
        fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
            if self.admin { Some(self) } else { None }
        }
    }

    impl BusAdmin for Flushing {
        fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError> {
            Ok(Vec::new())
        }
        fn node_status(&mut self, _: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
            Ok(NodeStatus {
                number: 1,
                name: "me".into(),
                state: ErrorState::Passive,
                errors: None,
                sr: None,
                timing: None,
                counters: NodeCounters {
                    sent: 2,
                    ..NodeCounters::default()
                },
                tx_queued: 8,
                bus: BusSummary {
                    bitrate: 125_000,
                    ..BusSummary::default()
                },
            })
        }
        fn register_dump(&mut self, _: Option<&NodeRef>) -> Result<NodeRegisters, BusError> {
            Err(BusError::Other("no registers".into()))
        }
        fn set_name(&mut self, _: &str) -> Result<(), BusError> {
            Ok(())
        }
        fn set_btr(&mut self, _: u8, _: u8) -> Result<(), BusError> {
            Ok(())
        }
        fn flush(&mut self, timeout: Duration) -> Result<TxReport, BusError> {
            self.asked_within = Some(timeout);
            self.answer.ok_or(BusError::Timeout {
                what: "flush".into(),
                after: timeout,
            })
        }
        fn abort(&mut self) -> Result<(), BusError> {
            Ok(())
        }
    }

    #[test]
    fn the_wait_covers_the_queued_frames_and_each_outcome_is_typed() {
        let mut bus = Flushing {
            admin: true,
            answer: Some(TxReport {
                sent: 10,
                failed: 0,
            }),
            asked_within: None,
        };
        let got = confirm_sent(&mut bus, 10, Duration::from_secs(1)).unwrap();
        assert_eq!(got, Confirmation::AllSent);
        // 8 frames still to go at 125 kbit/s, 160 bits each: 10.24 ms beyond the timeout.
        assert_eq!(
            bus.asked_within,
            Some(Duration::from_secs(1) + Duration::from_micros(10_240))
        );
        bus.answer = Some(TxReport { sent: 7, failed: 3 });
        let e = confirm_sent(&mut bus, 10, Duration::from_secs(1)).unwrap_err();
        assert!(
            matches!(
                e,
                ConfirmError::NotSent {
                    failed: 3,
                    count: 10,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string().starts_with("3 of 10 frames were not sent"),
            "{e}"
        );
        bus.answer = None;
        let e = confirm_sent(&mut bus, 10, Duration::from_secs(1)).unwrap_err();
        assert!(
            matches!(
                e,
                ConfirmError::Timeout {
                    sent: 2,
                    count: 10,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string()
                .starts_with("only 2 of 10 frames were sent within 1.01"),
            "{e}"
        );
        let mut plain = Flushing {
            admin: false,
            answer: None,
            asked_within: None,
        };
        let got = confirm_sent(&mut plain, 10, Duration::from_secs(1)).unwrap();
        assert_eq!(got, Confirmation::Unconfirmable);
    }
}
