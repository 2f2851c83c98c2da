//! Buses joined across machines, sans-IO: what makes loss and order visible when frames
//! travel through a broker or a network.
//!
//! - [`envelope`]: a batch of frames from one origin: the origin's ID, the 64-bit sequence
//!   number of its first frame, hop count, wall time and the origin's bus time of each frame;
//!   the frames as cannelloni records.
//! - [`batch`]: frames gathered for a few milliseconds into one envelope.
//! - [`track`]: the receiving side: its own echoes and duplicates dropped, gaps and
//!   reorderings counted per origin ([`PeerStats`]).
//!
//! What is guaranteed (docs/transports.md): frames of one origin are numbered in the order it
//! sent them, so a receiver knows each gap and each late frame; there is no order between
//! origins; at MQTT QoS 0 or over UDP a frame can be lost: it is counted, not resent.

pub mod batch;
pub mod envelope;
pub mod track;

pub use batch::{BATCH_INTERVAL_US, Batcher, MAX_BATCH_FRAMES};
pub use envelope::{Envelope, EnvelopeError, MAX_ENVELOPE, MAX_HOPS, Stamped};
pub use track::{Accepted, JoinReport, MAX_GAPS, PeerStats, Tracker};

pub use buslab_cannelloni::CanFrame;
