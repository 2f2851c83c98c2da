//! The device side of the seam.

use buslab_can::Nanos;

/// A device model that talks over one UART, driven in virtual nanoseconds.
pub trait ByteDevice {
    /// A byte has fully arrived on the device's RxD at `now_ns`.
    fn receive(&mut self, now_ns: Nanos, byte: u8);
    /// Advance the model to `now_ns`; append the bytes whose transmission on TxD has completed
    /// by then.
    fn poll(&mut self, now_ns: Nanos, out: &mut Vec<u8>);
    /// When [`poll`](ByteDevice::poll) must be called again even if no byte arrives; `None` if
    /// the device only reacts to input.
    fn next_deadline(&self) -> Option<Nanos>;
    /// Some of the bytes it produced by `now_ns` never reached the client (one that does not
    /// read loses them, as a real port's buffer overflows). A device whose output builds on
    /// what the client already shows (a VT100 screen sent as changes) starts again from
    /// scratch. Nothing by default.
    fn output_lost(&mut self, now_ns: Nanos) {
        let _ = now_ns;
    }
    /// A client opened the device's port at `now_ns` (a terminal program started on the
    /// line). A device that shows a screen sends it whole again, so a terminal opened late
    /// does not stay blank until its user asks for a redraw. Nothing by default.
    fn port_opened(&mut self, now_ns: Nanos) {
        let _ = now_ns;
    }
}

/// A device whose state survives a power cycle (battery-backed RAM, flash): what its state or
/// image file holds. Pure: the host decides when and where the bytes are written.
///
/// Adapters look at [`state_generation`](Persistent::state_generation) between two byte events
/// and, when it moved, take a [`snapshot`](Persistent::snapshot) there (a copy, cheap, so the
/// device's pacing does not suffer), then turn it into the file's bytes
/// ([`file_bytes`](Persistent::file_bytes)) elsewhere.
///
/// So that nothing the device acknowledged is lost, the device also tells each change as it
/// happens ([`take_changes`](Persistent::take_changes)): a host appends the records to a
/// journal and makes them durable before any byte the device sends after them leaves (an
/// acknowledgement always follows the change it acknowledges), and replays the journal over
/// the state file after a crash ([`replay`](Persistent::replay)).
pub trait Persistent {
    /// A copy of the persistent state.
    type Snapshot: Send + 'static;
    /// Changes whenever the persistent state changes (a counter: compared, never interpreted).
    fn state_generation(&self) -> u64;
    /// The persistent state now.
    fn snapshot(&self) -> Self::Snapshot;
    /// A snapshot as the contents of its file.
    fn file_bytes(snapshot: &Self::Snapshot) -> Vec<u8>;
    /// The changes since the last call, oldest first, as journal records. Each record sets part
    /// of the state to a value (never "add" or "toggle"), so replaying records a snapshot
    /// already holds changes nothing.
    fn take_changes(&mut self) -> Changes;
    /// Applies one record from [`take_changes`](Persistent::take_changes) to a snapshot.
    fn replay(snapshot: &mut Self::Snapshot, record: &[u8]) -> Result<(), ReplayError>;
}

/// What changed in a device's persistent state since the host last asked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Changes {
    /// These records, oldest first (none: nothing changed).
    Records(Vec<Vec<u8>>),
    /// More changed than records tell (too many waited, or a change no record describes): the
    /// host must save a whole snapshot before the device's next byte leaves.
    Snapshot,
}

/// A journal record a device cannot apply.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "journal record of {len} bytes starting {head:02X?} is not a change this device makes: {why}"
)]
pub struct ReplayError {
    pub len: usize,
    pub head: Vec<u8>,
    pub why: &'static str,
}

impl ReplayError {
    /// `record` refused for `why`.
    pub fn new(record: &[u8], why: &'static str) -> Self {
        Self {
            len: record.len(),
            head: record.iter().take(4).copied().collect(),
            why,
        }
    }
}

/// The changes a device has made and its host has not taken yet, bounded: beyond
/// [`ChangeLog::MAX_BYTES`] of records waiting (a host that does not journal, or one that
/// looks rarely) they are dropped for a request to save a whole snapshot.
#[derive(Clone, Debug, Default)]
pub struct ChangeLog {
    records: Vec<Vec<u8>>,
    bytes: usize,
    snapshot: bool,
}

impl ChangeLog {
    /// Record bytes kept waiting at most.
    pub const MAX_BYTES: usize = 1 << 20;

    /// Notes a change.
    pub fn record(&mut self, record: Vec<u8>) {
        if self.snapshot {
            return;
        }
        if self.bytes + record.len() > Self::MAX_BYTES {
            self.need_snapshot();
            return;
        }
        self.bytes += record.len();
        self.records.push(record);
    }

    /// The last record, to extend it (contiguous writes make one record).
    pub fn last_mut(&mut self) -> Option<&mut Vec<u8>> {
        if self.snapshot || self.bytes >= Self::MAX_BYTES {
            return None;
        }
        self.records.last_mut()
    }

    /// Counts bytes added to the last record through [`last_mut`](Self::last_mut).
    pub fn extended(&mut self, bytes: usize) {
        self.bytes += bytes;
    }

    /// Notes a change no record describes.
    pub fn need_snapshot(&mut self) {
        self.snapshot = true;
        self.records = Vec::new();
        self.bytes = 0;
    }

    /// What changed since the last call.
    pub fn take(&mut self) -> Changes {
        let changes = if self.snapshot {
            Changes::Snapshot
        } else {
            Changes::Records(std::mem::take(&mut self.records))
        };
        self.snapshot = false;
        self.bytes = 0;
        changes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_change_log_nobody_takes_stays_small_and_asks_for_a_snapshot() {
        let mut log = ChangeLog::default();
        log.record(vec![1, 2, 3]);
        assert_eq!(log.take(), Changes::Records(vec![vec![1, 2, 3]]));
        assert_eq!(log.take(), Changes::Records(vec![]));
        for _ in 0..(ChangeLog::MAX_BYTES / 100 + 1) {
            log.record(vec![0; 100]);
        }
        assert!(log.records.is_empty());
        assert_eq!(log.take(), Changes::Snapshot);
        assert_eq!(log.take(), Changes::Records(vec![]));
    }
}
