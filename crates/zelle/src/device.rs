//! The cell as a [`ByteDevice`] the link crate paces to the wall clock, and as a
//! [`Persistent`] device whose battery-backed RAM is kept in its state file.

use buslab_device::{ByteDevice, Changes, LineSettings, Nanos, Persistent, ReplayError, SimPort};

use crate::Cell;
use crate::timing::LINE;

impl ByteDevice for Cell {
    fn receive(&mut self, now_ns: Nanos, byte: u8) {
        Cell::receive(self, now_ns, byte);
    }

    fn poll(&mut self, now_ns: Nanos, out: &mut Vec<u8>) {
        Cell::poll(self, now_ns, out);
    }

    fn next_deadline(&self) -> Option<Nanos> {
        Cell::next_deadline(self)
    }
}

impl Persistent for Cell {
    type Snapshot = crate::BatteryRam;

    fn state_generation(&self) -> u64 {
        self.ram_generation()
    }

    fn snapshot(&self) -> crate::BatteryRam {
        self.ram().clone()
    }

    /// The state file (TOML).
    fn file_bytes(ram: &crate::BatteryRam) -> Vec<u8> {
        ram.to_state_file().into_bytes()
    }

    /// RAM writes: `[address high, address low, bytes…]`.
    fn take_changes(&mut self) -> Changes {
        self.take_ram_changes()
    }

    fn replay(ram: &mut crate::BatteryRam, record: &[u8]) -> Result<(), ReplayError> {
        Cell::replay_ram_change(ram, record)
    }
}

impl Cell {
    /// The cell's line: 9600 8N2.
    pub fn line(&self) -> LineSettings {
        LINE
    }

    /// A port to this cell in virtual time, from the cell's current time, so the host client
    /// runs against the model as fast as the CPU allows with the line's exact timing.
    pub fn into_sim_port(self) -> SimPort<Cell> {
        let now = self.now();
        SimPort::new(self, LINE, now)
    }
}
