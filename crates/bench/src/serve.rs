//! The bench `buslab bus serve` puts on the wire beside its clients: SLIO demo boards on
//! analog sources, the PowerPC node running MoniCAN, a scenario's nodes, traffic and faults.
//! The binary reads the options and the files; this puts the nodes into the server's
//! configuration.

use buslab_analog::Source;
use buslab_ppc::PpcError;
use buslab_slio::{SlioError, SlioId};
use buslab_vbus::ServerConfig;

use crate::{Scenario, ScenarioError};

/// What `bus serve` puts on the bus besides its clients.
#[derive(Debug, Default)]
pub struct ServeBench {
    /// Demo boards with these SLIO numbers, named `slio<N>` ([`crate::board::name`]).
    pub slios: Vec<SlioId>,
    /// Every board's ADC1 input (P5) and potentiometer (P6).
    pub adc1: Source,
    pub potentiometer: Source,
    /// The PowerPC node, named [`crate::ppc::NAME`].
    pub ppc: bool,
    /// A scenario's nodes, traffic and faults on the same wire (at the bus's bit rate).
    pub scenario: Option<Scenario>,
}

/// Why the bench cannot join the bus.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// (The message leaves the SLIO number to the caller, who knows where it came from.)
    #[error("the SLIO cannot join this bus: {source}")]
    Slio { id: SlioId, source: SlioError },
    #[error("the PowerPC node cannot join this bus: {0}")]
    Ppc(PpcError),
    #[error("the scenario runs at {scenario} bit/s but the bus at {bus} bit/s")]
    ScenarioBitrate { scenario: u32, bus: u32 },
    #[error(transparent)]
    Scenario(ScenarioError),
}

impl ServeBench {
    /// Puts the bench into `config` (its bit rate is the bus's): the boards and the PowerPC
    /// node as devices, the scenario's simulation (its events not recorded: the server reports
    /// what happens).
    pub fn install(self, config: &mut ServerConfig) -> Result<(), ServeError> {
        let bitrate = config.bitrate;
        for &id in &self.slios {
            let board = crate::board::demo_board(
                id,
                bitrate,
                self.adc1.clone(),
                self.potentiometer.clone(),
            )
            .map_err(|source| ServeError::Slio { id, source })?;
            config
                .devices
                .push((crate::board::name(id), Box::new(board)));
        }
        if self.ppc {
            let node = crate::ppc::node(bitrate).map_err(ServeError::Ppc)?;
            config
                .devices
                .push((crate::ppc::NAME.to_string(), Box::new(node)));
        }
        if let Some(scenario) = &self.scenario {
            if scenario.bitrate != bitrate {
                return Err(ServeError::ScenarioBitrate {
                    scenario: scenario.bitrate,
                    bus: bitrate,
                });
            }
            let mut sim = scenario.build().map_err(ServeError::Scenario)?;
            sim.set_record_events(buslab_sim::RecordedEvents::empty());
            config.scenario = Some(sim);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(bitrate: u32) -> ServerConfig {
        ServerConfig::new("127.0.0.1:0".parse().unwrap(), bitrate)
    }

    #[test]
    fn the_boards_and_the_powerpc_node_join_by_name() {
        let mut c = config(125_000);
        let bench = ServeBench {
            slios: vec![SlioId::new(0).unwrap(), SlioId::new(10).unwrap()],
            ppc: true,
            ..ServeBench::default()
        };
        bench.install(&mut c).unwrap();
        let names: Vec<&str> = c.devices.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["slio0", "slioA", "ppc"]);
    }

    #[test]
    fn what_cannot_join_says_why() {
        let slio = ServeBench {
            slios: vec![SlioId::new(3).unwrap()],
            ..ServeBench::default()
        };
        let e = slio.install(&mut config(500_000)).unwrap_err();
        assert!(matches!(e, ServeError::Slio { id, .. } if id.number() == 3));
        assert!(
            e.to_string()
                .starts_with("the SLIO cannot join this bus: bit rate 500000"),
            "{e}"
        );
        let scenario = Scenario::from_toml("bitrate = 125000\n[[nodes]]\nname = \"a\"").unwrap();
        let e = ServeBench {
            scenario: Some(scenario),
            ..ServeBench::default()
        }
        .install(&mut config(500_000))
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "the scenario runs at 125000 bit/s but the bus at 500000 bit/s"
        );
    }
}
