//! `buslab`: the command-line front end. Each subcommand lives in `cmd/<name>.rs`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cmd;

/// CAN, CPU196 and ZELLE devices as faithful software models, and the host tools that talk to
/// them (or to the real hardware).
#[derive(Parser)]
#[command(name = "buslab", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Start the whole virtual bench: a simulated CAN bus with nodes, paced to real time.
    Lab(cmd::lab::Args),
    /// Encode a frame into CAN wire bits, or decode wire bits back into a frame.
    Wire(cmd::wire::Args),
    /// Run a bus simulation scenario in virtual time.
    Sim(cmd::sim::Args),
    /// ZELLE measurement cell: serve the model on a pseudo-terminal, or talk to a cell.
    Zelle(cmd::zelle::Args),
    /// CPU196 controller board: serve the model on a pseudo-terminal, or talk to a board.
    Cpu196(cmd::cpu196::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Errors are for people: one line with the chain of causes, never a backtrace.
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Lab(args) => cmd::lab::run(args),
        Command::Wire(args) => cmd::wire::run(args),
        Command::Sim(args) => cmd::sim::run(args),
        Command::Zelle(args) => cmd::zelle::run(args),
        Command::Cpu196(args) => cmd::cpu196::run(args),
    }
}
