//! `buslab status [--node N]`: error state, STATUS bits, error counters, ALC and ECC in words.

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
