//! The two traits a bus implements: [`CanBus`] (frames, filters, error state, in the spirit
//! of python-can's `BusABC`) and, for a bus that has more to tell than frames,
//! [`BusAdmin`] (nodes, status, registers, this client's own controller).

use std::sync::Arc;
use std::time::Duration;

use buslab_can::{FdFrame, Frame};
use buslab_chips::slio::SlioId;

use crate::admin::{
    BoardInput, BoardState, NodeInfo, NodeRef, NodeRegisters, NodeStatus, TxReport, WireFault,
};
use crate::bus::{BusError, ErrorState, FdSupport, Filter, Message};
use crate::settings::{BusOffRecovery, ControllerSettings};

/// One bus: a socketcand connection, a managed SJA1000, a simulated node.
///
/// Like python-can: `recv(None)` blocks until a message arrives, `recv(Some(t))` returns
/// `Ok(None)` when `t` passes without one. An empty filter list accepts every frame.
///
/// Error frames are off by default; after `set_error_frames(true)` [`CanBus::recv_event`]
/// gives them in order with the frames, while `recv` keeps giving frames only (and drops the
/// error frames it passes).
///
/// CAN FD frames travel on buses that carry them ([`CanBus::fd_support`]): they are sent with
/// [`CanBus::send_fd`] and received from [`CanBus::recv_event`] as
/// [`Record::Fd`](crate::Record::Fd). `recv` gives classic frames only and passes FD frames
/// by, as it passes error frames (its type has no room for them). A bus that carries no FD
/// (buslab's bit-level bus, socketcand, a classic SocketCAN interface or SLCAN adapter)
/// refuses an FD frame with [`BusError::ClassicOnly`], naming itself and why.
pub trait CanBus {
    /// Queues `frame` for transmission (does not wait for it to reach the bus).
    fn send(&mut self, frame: &Frame) -> Result<(), BusError>;
    /// Queues `frames` in order, as [`CanBus::send`] on each would; a backend may hand them
    /// over at once (socketcand: one write for all, so a fast sender is not one system call
    /// and one wake-up of the server per frame).
    fn send_all(&mut self, frames: &[Frame]) -> Result<(), BusError> {
        frames.iter().try_for_each(|f| self.send(f))
    }
    /// Whether this bus carries CAN FD frames, and if not, why.
    fn fd_support(&self) -> FdSupport {
        FdSupport::Classic(crate::NoFd::Backend)
    }
    /// Queues a CAN FD frame for transmission; a bus that carries none refuses it with
    /// [`BusError::ClassicOnly`].
    fn send_fd(&mut self, frame: &FdFrame) -> Result<(), BusError> {
        let _ = frame;
        Err(match self.fd_support() {
            FdSupport::Classic(why) => BusError::ClassicOnly {
                bus: self.channel_info(),
                why,
            },
            FdSupport::Carried => BusError::Unsupported {
                what: "sending CAN FD frames",
                backend: self.channel_info(),
            },
        })
    }
    /// The next classic frame that passes the filters, or `None` after `timeout` (FD frames
    /// are passed by: [`CanBus::recv_event`] gives them).
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError>;
    /// The next frame (classic or FD) that passes the filters or error frame, in the order
    /// they happened, or `None` after `timeout`. Backends without error frames give frames
    /// only.
    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        Ok(self.recv(timeout)?.map(Message::into_record))
    }
    /// Asks for error frames (bus errors, lost arbitrations, state changes) too; a backend
    /// that cannot deliver them refuses with [`BusError::Unsupported`].
    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        if on {
            Err(BusError::Unsupported {
                what: "error frames",
                backend: self.channel_info(),
            })
        } else {
            Ok(())
        }
    }
    /// Replaces the receive filters; `&[]` accepts everything.
    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError>;
    /// The controller's error state.
    fn state(&mut self) -> Result<ErrorState, BusError>;
    /// A human-readable description of the channel (like python-can's `channel_info`).
    fn channel_info(&self) -> String;
    /// The bus's administration side (node list, status, registers), if it has one.
    fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
        None
    }
    /// A handle that ends this bus's wait in [`CanBus::recv`] or [`CanBus::recv_event`] from
    /// another thread (the wait then returns `Ok(None)` early), if the backend has one. A
    /// thread that owns a bus and also takes frames to send from others wakes itself with it
    /// when a frame comes, instead of waiting out a timeout (`buslab_backends::Pump`).
    fn recv_waker(&mut self) -> Option<Arc<dyn RecvWaker>> {
        None
    }
}

/// Ends a bus's current or next wait for frames ([`CanBus::recv_waker`]). A wake that comes
/// while nobody waits ends the next wait at once, so a wake is never lost; waits for answers
/// to requests are not ended by it.
pub trait RecvWaker: Send + Sync {
    fn wake(&self);
}

/// The administration side of a bus: nodes, status, registers, and settings of this client's
/// own node. Backends that have none of it return `None` from
/// [`CanBus::admin`].
pub trait BusAdmin {
    /// Every node on the bus.
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError>;
    /// A node's status (this client's own node if `None`).
    fn node_status(&mut self, node: Option<&NodeRef>) -> Result<NodeStatus, BusError>;
    /// A node's registers (this client's own node if `None`).
    fn register_dump(&mut self, node: Option<&NodeRef>) -> Result<NodeRegisters, BusError>;
    /// Names this client's node.
    fn set_name(&mut self, name: &str) -> Result<(), BusError>;
    /// Reprograms this client's chip with BTR0/BTR1.
    fn set_btr(&mut self, btr0: u8, btr1: u8) -> Result<(), BusError>;
    /// Waits until every frame this client sent so far was transmitted or given up, and says
    /// how many of each since it joined; an error after `timeout`.
    fn flush(&mut self, timeout: Duration) -> Result<TxReport, BusError>;
    /// Gives up the frame this client's controller is trying (as CMR.AT: a frame already on
    /// the wire finishes its attempt but is not retried) and the frames queued behind it.
    fn abort(&mut self) -> Result<(), BusError>;
    /// How this client's chip comes back after bus-off (the bus's policy until then). Only
    /// a virtual bus lets a client choose.
    fn set_bus_off_recovery(&mut self, recovery: BusOffRecovery) -> Result<(), BusError> {
        let _ = recovery;
        Err(BusError::Unsupported {
            what: "choosing the bus-off recovery",
            backend: "this bus".into(),
        })
    }
    /// Puts a fault on the wire from now on, for `lasting` (until [`BusAdmin::repair`] if
    /// `None`). Only a virtual bus has a wire to break.
    fn inject_fault(
        &mut self,
        fault: &WireFault,
        lasting: Option<Duration>,
    ) -> Result<(), BusError> {
        let _ = (fault, lasting);
        Err(BusError::Unsupported {
            what: "fault injection",
            backend: "this bus".into(),
        })
    }
    /// Ends every fault on the wire now (injected or from a scenario).
    fn repair(&mut self) -> Result<(), BusError> {
        Err(BusError::Unsupported {
            what: "fault injection",
            backend: "this bus".into(),
        })
    }
    /// Reprograms this client's own controller with the parts of `settings` that are given
    /// (mode, bit timing, acceptance filter, output control, clock output), the others kept.
    /// Only a bus whose clients have a controller of their own has one to program.
    fn configure(&mut self, settings: &ControllerSettings) -> Result<(), BusError> {
        let _ = settings;
        Err(BusError::Unsupported {
            what: "controller settings",
            backend: "this bus".into(),
        })
    }
    /// A SLIO demo board on the bus, after `change` to its inputs if given (a switch flipped,
    /// the potentiometer turned). Only a virtual bus has boards to reach.
    fn demo_board(
        &mut self,
        slio: SlioId,
        change: Option<BoardInput>,
    ) -> Result<BoardState, BusError> {
        let _ = (slio, change);
        Err(BusError::Unsupported {
            what: "demo boards",
            backend: "this bus".into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NoFd;

    /// A bus that implements only what every backend must: classic frames.
    struct Classic;

    impl CanBus for Classic {
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
            "a classic test bus".into()
        }
    }

    #[test]
    fn a_bus_that_says_nothing_about_fd_refuses_fd_frames_by_name() {
        let mut bus = Classic;
        assert_eq!(bus.fd_support(), FdSupport::Classic(NoFd::Backend));
        let frame = "123##1112233".parse().unwrap();
        let err = bus.send_fd(&frame).unwrap_err();
        assert!(
            matches!(&err, BusError::ClassicOnly { bus, why: NoFd::Backend } if bus == "a classic test bus"),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "a classic test bus is classic CAN: this backend sends classic CAN frames only"
        );
    }
}
