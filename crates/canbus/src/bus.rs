//! A CAN bus interface in the spirit of python-can's `BusABC`: send frames, receive
//! timestamped messages (and, when asked for, error frames), filter by ID and mask, ask for the
//! error state.

use std::time::Duration;

use buslab_can::Frame;

/// The bus vocabulary lives in `buslab-bus`; these paths stay for the users of this crate.
pub use buslab_bus::bus::{
    BusError, BusEvent, BusState, ErrorMessage, Filter, Human, Message, matches_any,
};

/// One bus: a socketcand connection, a managed SJA1000, a simulated node.
///
/// Like python-can: `recv(None)` blocks until a message arrives, `recv(Some(t))` returns
/// `Ok(None)` when `t` passes without one. An empty filter list accepts every frame.
///
/// Error frames are off by default; after `set_error_frames(true)` [`CanBus::recv_event`]
/// gives them in order with the frames, while `recv` keeps giving frames only (and drops the
/// error frames it passes).
pub trait CanBus {
    /// Queues `frame` for transmission (does not wait for it to reach the bus).
    fn send(&mut self, frame: &Frame) -> Result<(), BusError>;
    /// Queues `frames` in order, as [`CanBus::send`] on each would; a backend may hand them
    /// over at once (socketcand: one write for all, so a fast sender is not one system call
    /// and one wake-up of the server per frame).
    fn send_all(&mut self, frames: &[Frame]) -> Result<(), BusError> {
        frames.iter().try_for_each(|f| self.send(f))
    }
    /// The next message that passes the filters, or `None` after `timeout`.
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError>;
    /// The next frame that passes the filters or error frame, in the order they happened, or
    /// `None` after `timeout`. Backends without error frames give frames only.
    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<BusEvent>, BusError> {
        Ok(self.recv(timeout)?.map(BusEvent::Frame))
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
    fn state(&mut self) -> Result<BusState, BusError>;
    /// A human-readable description of the channel (like python-can's `channel_info`).
    fn channel_info(&self) -> String;
    /// The bus's administration side (node list, status, registers), if it has one.
    fn admin(&mut self) -> Option<&mut dyn crate::admin::BusAdmin> {
        None
    }
}
