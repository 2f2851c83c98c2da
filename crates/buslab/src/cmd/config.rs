//! `buslab config show`: the effective configuration and where each value came from;
//! `buslab config wizard`: JerryCAN's configuration assistant, on the terminal.

use std::path::PathBuf;

use anyhow::bail;

use crate::config;

#[cfg(not(feature = "tui"))]
use super::absent::wizard;
#[cfg(feature = "tui")]
mod wizard;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: ConfigCommand,
}

#[derive(clap::Subcommand)]
pub enum ConfigCommand {
    /// Print the effective configuration as TOML, each value with where it came from (default,
    /// FILE:LINE, environment, command line), then the controller's registers.
    Show,
    /// Ask step by step for the controller (mode, acceptance filter, bit timing, output
    /// control, clock out) and the other keys, then write the file.
    Wizard(WizardArgs),
}

#[derive(clap::Args)]
pub struct WizardArgs {
    /// The file to write (default: the configuration file in use, else buslab.toml in the
    /// user's configuration directory).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        ConfigCommand::Show => show(),
        ConfigCommand::Wizard(a) => wizard::run(a),
    }
}

fn show() -> anyhow::Result<()> {
    match config::loaded() {
        Some(Ok(loaded)) => {
            print!("{}", config::render_show(loaded));
            Ok(())
        }
        Some(Err(e)) => bail!("{e}"),
        None => bail!("the configuration was not loaded"),
    }
}
