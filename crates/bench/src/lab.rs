//! The lab's bench (`buslab lab`): simulated nodes with periodic and bursty traffic, and the
//! seed's SLIO bench (three demo boards and the PowerPC node running MoniCAN), on a virtual bus
//! server clients join. The binary starts it, prints its banner and serves the terminals.

use std::io;
use std::net::SocketAddr;

use buslab_can::controller::ControllerConfig;
use buslab_can::node::BusNode;
use buslab_can::{Frame, Nanos};
use buslab_ppc::PpcError;
use buslab_sim::{BitTime, Simulation, Traffic};
use buslab_slio::{SlioError, SlioId};
use buslab_vbus::{ServerConfig, ServerError, ServerHandle};

/// The bus name clients open.
pub const CHANNEL: &str = "vcan0";

/// Where the lab's bus listens unless told otherwise (socketcand's port, on loopback).
pub const DEFAULT_LISTEN: SocketAddr = SocketAddr::V4(std::net::SocketAddrV4::new(
    std::net::Ipv4Addr::LOCALHOST,
    29536,
));

/// Why the lab's bus could not start.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    #[error("a SLIO demo board cannot join the lab's bus: {0}")]
    Slio(#[from] SlioError),
    #[error("the PowerPC node cannot join the lab's bus: {0}")]
    Ppc(#[from] PpcError),
    #[error("starting the lab's bus server: {0}")]
    Server(#[from] ServerError),
}

/// Simulated nodes for a server, by name (`ServerConfig::devices`).
pub type Devices = Vec<(String, Box<dyn BusNode>)>;

/// The names of the bench's simulated nodes, in the order they join.
pub const SIMULATED: [&str; 4] = ["brakes", "engine", "body", "dash"];

/// The frame each simulated node sends ([`SIMULATED`]'s order), as can-utils writes it.
pub const TRAFFIC: [&str; 4] = [
    "080#0140",
    "0C0#0FA0003C00000000",
    "18FF0010#A5",
    "300#D1D2D3D4",
];

/// The lab's DBC database: its simulated nodes' frames, the counter's, the SLIO bench's
/// (calibration, each board's commands and replies, register by register), the mail and
/// loader frames, with names, units and value tables. `buslab lab` decodes with it unless
/// given `--dbc`, and writes it to `DIR/lab.dbc` for the other tools.
pub const LAB_DBC: &str = include_str!("lab.dbc");

/// The simulated nodes of the bench ([`SIMULATED`]) and their traffic ([`TRAFFIC`]).
pub fn lab_nodes(bitrate: u32, seed: u64) -> Simulation {
    let mut bus = Simulation::new(bitrate, seed);
    let ms = |m: u64| Nanos::from_millis(m).bit_times_at(bitrate);
    let f = |text: &str| -> Frame { text.parse().expect("built-in frame") };
    let plain = ControllerConfig::default();
    let [brakes, engine, body, dash] = SIMULATED.map(|name| bus.add_node(name, plain));
    let [brakes_frame, engine_frame, body_frame, dash_frame] = TRAFFIC.map(f);
    bus.add_traffic(brakes, periodic(brakes_frame, ms(20), BitTime::ZERO));
    bus.add_traffic(engine, periodic(engine_frame, ms(10), ms(1)));
    bus.add_traffic(body, periodic(body_frame, ms(100), ms(3)));
    bus.add_traffic(
        dash,
        Traffic::Burst {
            frame: dash_frame,
            count: 4,
            period: ms(250),
            start: ms(5),
        },
    );
    bus
}

fn periodic(frame: Frame, period: BitTime, start: BitTime) -> Traffic {
    Traffic::Periodic {
        frame,
        period,
        start,
        count: None,
    }
}

/// The seed's SLIO bench (002 §3.2, §4.3): three demo boards and the PowerPC node running
/// MoniCAN. SLIOs follow 20..125 kbit/s only; on a faster bus the bench has none.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlioBench {
    ids: Vec<SlioId>,
}

/// The demo boards' numbers: three, as the seed's figure shows a few of its 16.
const LAB_SLIOS: [u8; 3] = [0, 3, 10];

impl SlioBench {
    /// The bench for a bus at `bitrate` (empty if SLIOs cannot follow it).
    pub fn new(bitrate: u32) -> Self {
        let fits =
            (buslab_slio::slio::MIN_BITRATE..=buslab_slio::slio::MAX_BITRATE).contains(&bitrate);
        let ids = if fits {
            LAB_SLIOS
                .iter()
                .map(|&n| SlioId::new(n).expect("0..15"))
                .collect()
        } else {
            Vec::new()
        };
        Self { ids }
    }

    /// The demo boards' SLIO numbers (none on a bus SLIOs cannot follow).
    pub fn ids(&self) -> &[SlioId] {
        &self.ids
    }

    /// Whether the bench has its boards and the PowerPC node.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The names of the bench's nodes on the bus: the boards, then the PowerPC node.
    pub fn names(&self) -> Vec<String> {
        if self.ids.is_empty() {
            return Vec::new();
        }
        let mut names: Vec<String> = self.ids.iter().map(|&id| crate::board::name(id)).collect();
        names.push(crate::ppc::NAME.to_string());
        names
    }

    /// The boards and the PowerPC node, fresh for a server.
    pub fn devices(&self, bitrate: u32) -> Result<Devices, LabError> {
        let mut devices = Devices::new();
        if self.ids.is_empty() {
            return Ok(devices);
        }
        for &id in &self.ids {
            devices.push((
                crate::board::name(id),
                Box::new(crate::board::lab_board(id, bitrate)?),
            ));
        }
        devices.push((
            crate::ppc::NAME.to_string(),
            Box::new(crate::ppc::node(bitrate)?),
        ));
        Ok(devices)
    }
}

/// Starts the lab's bus server with the simulated nodes (`seed`) and the SLIO bench; on the
/// default address ([`DEFAULT_LISTEN`], `listen` being `None`), a taken port falls back to a
/// free one.
pub fn start_server(
    listen: Option<SocketAddr>,
    bitrate: u32,
    seed: u64,
    slio_bench: &SlioBench,
) -> Result<ServerHandle, LabError> {
    let config = |addr| -> Result<ServerConfig, LabError> {
        Ok(ServerConfig {
            channel: CHANNEL.to_string(),
            scenario: Some(lab_nodes(bitrate, seed)),
            devices: slio_bench.devices(bitrate)?,
            ..ServerConfig::new(addr, bitrate)
        })
    };
    match buslab_vbus::spawn(config(listen.unwrap_or(DEFAULT_LISTEN))?) {
        Err(ServerError::Listen { source, .. })
            if listen.is_none() && source.kind() == io::ErrorKind::AddrInUse =>
        {
            Ok(buslab_vbus::spawn(config(([127, 0, 0, 1], 0).into())?)?)
        }
        other => Ok(other?),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slio_bench_is_there_at_the_rates_slios_follow_only() {
        let bench = SlioBench::new(125_000);
        assert_eq!(bench.names(), ["slio0", "slio3", "slioA", "ppc"]);
        assert_eq!(bench.devices(125_000).unwrap().len(), 4);
        let fast = SlioBench::new(500_000);
        assert!(fast.is_empty() && fast.names().is_empty());
        assert!(fast.devices(500_000).unwrap().is_empty());
    }
}
