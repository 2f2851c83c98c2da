//! The device side of the seam.

/// A device model that talks over one UART, driven in virtual nanoseconds.
pub trait ByteDevice {
    /// A byte has fully arrived on the device's RxD at `now_ns`.
    fn receive(&mut self, now_ns: u64, byte: u8);
    /// Advance the model to `now_ns`; append the bytes whose transmission on TxD has completed
    /// by then.
    fn poll(&mut self, now_ns: u64, out: &mut Vec<u8>);
    /// When [`poll`](ByteDevice::poll) must be called again even if no byte arrives; `None` if
    /// the device only reacts to input.
    fn next_deadline(&self) -> Option<u64>;
}

/// A device whose state survives a power cycle (battery-backed RAM, flash): what its state or
/// image file holds. Pure: the host decides when and where the bytes are written.
///
/// Adapters look at [`state_generation`](Persistent::state_generation) between two byte events
/// and, when it moved, take a [`snapshot`](Persistent::snapshot) there (a copy, cheap, so the
/// device's pacing does not suffer), then turn it into the file's bytes
/// ([`file_bytes`](Persistent::file_bytes)) elsewhere.
pub trait Persistent {
    /// A copy of the persistent state.
    type Snapshot: Send + 'static;
    /// Changes whenever the persistent state changes (a counter: compared, never interpreted).
    fn state_generation(&self) -> u64;
    /// The persistent state now.
    fn snapshot(&self) -> Self::Snapshot;
    /// A snapshot as the contents of its file.
    fn file_bytes(snapshot: &Self::Snapshot) -> Vec<u8>;
}
