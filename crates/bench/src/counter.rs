//! The lab's counter node: a client of the lab's bus sending `200#` and a 32-bit counter
//! (little-endian) every 50 ms, traffic a user's first script can watch and check for gaps.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use buslab_bus::{BusError, CanBus};
use buslab_can::{Frame, Id, StandardId};
use buslab_socketcand::{ClientError, SocketcandBus};

use crate::lab::CHANNEL;

/// The counter's identifier (standard).
pub const COUNTER_ID: u16 = 0x200;

/// How often the counter sends.
pub const COUNTER_PERIOD: Duration = Duration::from_millis(50);

/// Why a lab client could not join or went on no longer.
#[derive(Debug, thiserror::Error)]
pub enum ClientNodeError {
    #[error("the {name} cannot join the lab's bus at {addr}: {source}")]
    Join {
        name: &'static str,
        addr: SocketAddr,
        source: Box<ClientError>,
    },
    #[error("the counter node: {0}")]
    Send(#[from] BusError),
    #[error("the counter node's thread panicked")]
    Panicked,
}

/// Joins the lab's bus at `addr` as a client named `name` (where the server names nodes).
pub fn join(addr: SocketAddr, name: &'static str) -> Result<SocketcandBus, ClientNodeError> {
    let joining = |source| ClientNodeError::Join {
        name,
        addr,
        source: Box::new(source),
    };
    let mut bus = SocketcandBus::connect(addr, CHANNEL).map_err(joining)?;
    if bus.enable_extensions().map_err(joining)? {
        bus.set_name(name).map_err(joining)?;
    }
    Ok(bus)
}

/// The counter node's thread.
pub struct CounterNode {
    thread: JoinHandle<Result<(), ClientNodeError>>,
}

impl CounterNode {
    /// Joins the bus at `addr` and sends until `stop` is set.
    pub fn spawn(addr: SocketAddr, stop: Arc<AtomicBool>) -> Result<Self, ClientNodeError> {
        let mut bus = join(addr, "counter")?;
        let thread = thread::spawn(move || {
            let mut value = 0u32;
            let mut next = Instant::now();
            while !stop.load(Ordering::SeqCst) {
                bus.send(&counter_frame(value))?;
                value = value.wrapping_add(1);
                next += COUNTER_PERIOD;
                thread::sleep(next.saturating_duration_since(Instant::now()));
            }
            Ok(())
        });
        Ok(Self { thread })
    }

    /// Waits for the thread (after `stop` was set): how its sending ended.
    pub fn join(self) -> Result<(), ClientNodeError> {
        self.thread.join().map_err(|_| ClientNodeError::Panicked)?
    }
}

/// The counter's frame carrying `value`.
pub fn counter_frame(value: u32) -> Frame {
    let id = StandardId::new(COUNTER_ID).expect("0x200 is a standard identifier");
    Frame::data(Id::Standard(id), &value.to_le_bytes()).expect("4 bytes fit a frame")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_counter_frame_carries_its_value_little_endian_under_0x200() {
        assert_eq!(counter_frame(0x0403_0201).to_string(), "200#01020304");
        assert_eq!(counter_frame(u32::MAX).to_string(), "200#FFFFFFFF");
    }
}
