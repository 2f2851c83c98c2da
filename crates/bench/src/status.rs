//! The lab's bench at a glance, as `buslab lab`'s status line shows it: typed, so each tool
//! words it as it needs.

use buslab_can::controller::ErrorState;
use buslab_sim::BusStats;
use buslab_vbus::VirtualBus;

/// What a virtual bus and its nodes are doing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BenchStatus {
    /// The last complete second (or the first one so far): load, frames, error events.
    pub last_second: BusStats,
    /// Since the bus started.
    pub total: BusStats,
    /// The bench's own simulated nodes.
    pub simulated: usize,
    /// Clients that joined over socketcand (the lab's counter, its web pages, every `dump` or
    /// python-can script).
    pub clients: usize,
    /// Nodes (simulated and clients) per fault-confinement state.
    pub active: usize,
    pub passive: usize,
    pub bus_off: usize,
}

impl BenchStatus {
    pub fn of(bus: &VirtualBus) -> Self {
        let clients = bus
            .nodes()
            .iter()
            .filter(|node| bus.client(node.number).is_ok())
            .count();
        let nodes = bus.sim().nodes();
        let count = |state| nodes.iter().filter(|n| n.state() == state).count();
        Self {
            last_second: bus.last_second(),
            total: *bus.stats(),
            simulated: nodes.len() - clients,
            clients,
            active: count(ErrorState::Active),
            passive: count(ErrorState::Passive),
            bus_off: count(ErrorState::BusOff),
        }
    }
}
