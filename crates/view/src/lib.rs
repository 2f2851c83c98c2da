//! What a person watching a CAN bus wants to see, as one sans-IO model shared by the web
//! dashboard (`buslab web`) and the terminal monitor (`buslab monitor`):
//!
//! - a per-ID table (count, period, DLC, data, the bytes that changed lately: cansniffer's and
//!   SavvyCAN's view), bounded in size;
//! - a frame log: a bounded ring with sequence numbers, frames and error frames (with their
//!   class and meaning in can-utils' words), read through a [`LogFilter`];
//! - the bus load over time (from the bus's own figure when it has one, else estimated from
//!   the frames' lengths on the wire at a known bit rate);
//! - every node's error state over time (TEC, REC, error-active/passive/bus-off) with its
//!   latest typed status (STATUS bits, ALC and ECC);
//! - the faults put on the wire through the consumer ([`FaultMark`]), for the time charts;
//! - with a DBC database ([`ViewConfig::dbc`]), its messages' signals: per message seen, the
//!   latest value of each signal with the ones that changed lately ([`MessageRow`]), and any
//!   signal's values over time ([`BusView::series`]).
//!
//! The load, the histories and the marks go back [`ViewConfig::retention`]; a new consumer
//! asks for the time window its charts show ([`BusView::delta_within`]), never for the whole
//! age of the view.
//!
//! Frames, error frames and node statuses go in with the instant they were seen
//! ([`BusView::frame`], [`BusView::error_frame`], [`BusView::nodes`], [`BusView::tick`]); what
//! changed since a [`Cursor`] comes out ([`BusView::delta`]). A consumer keeps one cursor and advances it only when it actually
//! delivered the delta, so a viewer that missed updates simply gets a larger one next time.
//! Time is explicit: a [`Duration`] since the view started, given by the adapter.

mod filter;

mod model;
mod signals;

pub use buslab_can::wire::frame_bits;
pub use filter::{FilterError, LogFilter};
pub use model::{
    BusView, Cursor, Delta, ErrorEntry, ErrorSample, FaultMark, IdRow, LoadSample, LogEntry,
    NodeView, ViewConfig,
};
pub use signals::{
    MIN_SIGNAL_POINTS, MessageRow, Series, SignalError, SignalKey, SignalRow, number_text,
};

pub use std::time::Duration;
