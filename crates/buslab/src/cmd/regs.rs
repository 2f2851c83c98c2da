//! `buslab regs --node N`: a node's SJA1000 registers with names and values (the seed's
//! regb/regp), read without side effects.

use super::bus::{BusOpt, node_ref, open};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The node: its number (connection order from 1) or its name.
    #[arg(long)]
    pub node: String,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut open = open(&args.bus.bus)?;
    if !open.extensions {
        anyhow::bail!(
            "{}: the server has no register access (not a buslab bus)",
            args.bus.bus
        );
    }
    let regs = open.bus.register_dump(Some(&node_ref(&args.node)))?;
    println!("node {} ({})", regs.number, regs.name);
    print!("{}", regs.dump);
    Ok(())
}
