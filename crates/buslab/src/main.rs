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
    /// Virtual CAN bus server (socketcand protocol; every client gets an SJA1000).
    Bus(cmd::bus::Args),
    /// Print the frames on a CAN bus, like candump.
    Dump(cmd::dump::Args),
    /// Send frames in cansend syntax (123#1122).
    Send(cmd::send::Args),
    /// Generate CAN traffic, like cangen.
    Gen(cmd::r#gen::Args),
    /// A node's SJA1000 registers (names and values).
    Regs(cmd::regs::Args),
    /// A node's error state, STATUS bits, counters, ALC and ECC in words.
    Status(cmd::status::Args),
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
        Command::Bus(args) => cmd::bus::run(args),
        Command::Dump(args) => cmd::dump::run(args),
        Command::Send(args) => cmd::send::run(args),
        Command::Gen(args) => cmd::r#gen::run(args),
        Command::Regs(args) => cmd::regs::run(args),
        Command::Status(args) => cmd::status::run(args),
    }
}
