//! `buslab status [--node N]`: error state, STATUS bits, error counters, ALC and ECC in words;
//! for a bus joined through MQTT (`--bus mqtt://BROKER/PREFIX`), every member's status and
//! counters (sent, lost, reordered per peer) as the broker keeps them.

use buslab_canbus::{NodeRef, NodeStatus};
use buslab_device::printable;

use super::busopt::{BusOpt, admin, node_ref, open};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The node: its number (connection order from 1) or its name; every other node if
    /// absent.
    #[arg(long, value_name = "NODE")]
    pub node: Option<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let url = &args.bus.bus;
    match url {
        buslab_backends::BusUrl::Mqtt {
            host,
            port,
            prefix,
            tls,
        } => return join_members(url, host, *port, prefix, *tls),
        buslab_backends::BusUrl::Cannelloni { .. } => anyhow::bail!(
            "{url}: cannelloni has no channel for counters: the process that joined prints them (`bus serve --join` when it stops, `bridge` in its log)"
        ),
        _ => {}
    }
    let mut bus = open(url)?;
    let admin = admin(&mut bus, url, "node status")?;
    let nodes = match &args.node {
        Some(n) => vec![node_ref(n)],
        None => {
            // Every node but this command's own.
            let me = admin.node_status(None)?.number;
            admin
                .nodes()?
                .into_iter()
                .filter(|n| n.number != me)
                .map(|n| NodeRef::Number(n.number))
                .collect()
        }
    };
    for (i, node) in nodes.iter().enumerate() {
        if i > 0 {
            println!();
        }
        print!("{}", shown(admin.node_status(Some(node))?));
    }
    Ok(())
}

/// A node's status as it may be printed: its name comes from the server, and a name with
/// an escape sequence in it must not drive the user's terminal (`\x1B[2J` is shown as that).
pub fn shown(mut status: NodeStatus) -> NodeStatus {
    status.name = printable(status.name.as_bytes());
    status
}

/// Every member of an MQTT join: online or not, what it sent and what it lost from whom.
fn join_members(
    url: &buslab_backends::BusUrl,
    host: &str,
    port: u16,
    prefix: &str,
    tls: bool,
) -> anyhow::Result<()> {
    let options = super::busopt::open_options();
    let broker = buslab_backends::mqtt::Broker {
        host,
        port,
        tls,
        credentials: options.mqtt_credentials.as_ref(),
    };
    let members = buslab_backends::mqtt::members(broker, prefix, options.connect_timeout)
        .map_err(|e| anyhow::anyhow!("{url}: {e}"))?;
    if members.is_empty() {
        println!("{url}: no member has joined");
    }
    for m in members {
        let state = match m.online {
            Some(true) => "online",
            Some(false) => "offline",
            None => "status unknown",
        };
        println!("member {}: {state}", printable(m.origin.as_bytes()));
        if let Some(r) = m.report {
            println!(
                "  sent {}, unsent {}, echoes dropped {}, garbage {}",
                r.sent, r.unsent, r.echoes, r.garbage
            );
            for p in r.peers {
                println!(
                    "  from {}: received {}, lost {}, reordered {}, duplicates {}, late {}, too many hops {}",
                    printable(p.origin.as_bytes()),
                    p.received,
                    p.lost,
                    p.reordered,
                    p.duplicates,
                    p.late,
                    p.too_many_hops
                );
            }
        }
    }
    Ok(())
}
