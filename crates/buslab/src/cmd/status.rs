//! `buslab status [--node N]`: error state, STATUS bits, error counters, ALC and ECC in words.

use super::bus::{BusOpt, node_ref, open};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The node: its number (connection order from 1) or its name; every node if absent.
    #[arg(long)]
    pub node: Option<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut open = open(&args.bus.bus)?;
    if !open.extensions {
        anyhow::bail!(
            "{}: the server reports no node status (not a buslab bus)",
            args.bus.bus
        );
    }
    let nodes = match &args.node {
        Some(n) => vec![node_ref(n)],
        None => {
            let me = open.bus.node_status(None)?.number;
            open.bus
                .nodes()?
                .into_iter()
                .filter(|n| n.number != me)
                .map(|n| buslab_socketcand::NodeRef::Number(n.number))
                .collect()
        }
    };
    for (i, node) in nodes.into_iter().enumerate() {
        if i > 0 {
            println!();
        }
        print!("{}", open.bus.node_status(Some(&node))?);
    }
    Ok(())
}
