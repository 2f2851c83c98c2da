//! `buslab regs [--node N]`: a node's SJA1000 registers with names and values (the seed's
//! regb/regp), read without side effects; without `--node`, this client's own node as the
//! configuration's `[controller]` set it up.

use buslab_device::printable;

use super::busopt::{BusOpt, admin, node_ref, open};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The node: its number (connection order from 1) or its name. Default: this client's
    /// own node, set up as the configuration's [controller] says (docs/config.md).
    #[arg(long, value_name = "NODE")]
    pub node: Option<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    let node = args.node.as_deref().map(node_ref);
    let regs = admin(&mut bus, url, "register access")?.register_dump(node.as_ref())?;
    // The name comes from the server: printed with its control characters written out.
    println!("node {} ({})", regs.number, printable(regs.name.as_bytes()));
    print!("{}", regs.dump);
    Ok(())
}
