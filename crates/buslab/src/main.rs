//! `buslab`: the command-line front end. Each subcommand lives in `cmd/<name>.rs`.

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

mod cmd;
mod config;
mod dbc;
mod logging;
mod status_line;
mod terminal;
mod units;

/// CAN, CPU196 and ZELLE devices as faithful software models, and the host tools that talk to
/// them (or to the real hardware).
#[derive(Parser)]
#[command(name = "buslab", version, about)]
struct Cli {
    #[command(flatten)]
    verbosity: logging::Verbosity,
    #[command(flatten)]
    config: config::ConfigArgs,
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
    /// P82C150 SLIO I/O nodes on a bus: calibrate, list, read/write registers, outputs, ADC,
    /// DPM.
    Slio(cmd::slio::Args),
    /// Copy frames between two buses (like cangw): a real adapter joins the virtual bench.
    Bridge(cmd::bridge::Args),
    /// SLCAN (Lawicel) adapters: serve an adapter model on a pseudo-terminal.
    Slcan(cmd::slcan::Args),
    /// MoniCAN in this terminal: calibrate, find and drive up to 16 SLIO boards on a bus.
    Monican(cmd::monican::Args),
    /// CAN log files (candump, ASC, BLF, TRC, CSV, pcap, pcapng, SQLite): convert, info, cat.
    Log(cmd::log::Args),
    /// Send a program (an S-record file) to the PowerPC node's CAN loader, like JerryCAN.
    Load(cmd::load::Args),
    /// The mail notifier: new mail in an IMAP mailbox announced on the bus and sent to
    /// MoniCAN when its user asks (Ctrl R).
    Mail(cmd::mail::Args),
    /// Send a file with the file protocol (8 bytes a frame on one ID, the last shorter).
    Sendfile(cmd::sendfile::Args),
    /// Receive one file sent with the file protocol and write it atomically.
    Recvfile(cmd::recvfile::Args),
    /// Replay a log onto a bus at the pace of its timestamps, like canplayer.
    Play(cmd::play::Args),
    /// The bus as web pages (the seed's CAN WebServer) and a live dashboard.
    Web(cmd::web::Args),
    /// The bus in this terminal: per-ID table with changed bytes, frame log, load, node
    /// error state and registers.
    Monitor(cmd::monitor::Args),
    /// The configuration file (buslab.toml): show the effective configuration and where each
    /// value came from, or write one step by step.
    Config(cmd::config::Args),
}

fn main() -> ExitCode {
    // The configuration first: options take their defaults from it.
    let args: Vec<OsString> = std::env::args_os().collect();
    config::init(&config::Lookup::scan(&args));
    let mut command = command();
    let cli = Cli::from_arg_matches(&command.clone().get_matches_from(args))
        .unwrap_or_else(|e| e.format(&mut command).exit());
    let chatty = matches!(
        &cli.command,
        Command::Bus(cmd::bus::Args {
            command: cmd::bus::BusCommand::Serve(_)
        }) | Command::Bridge(_)
            | Command::Slcan(_)
    );
    logging::init(&cli.verbosity, chatty);
    // Errors are for people: one line with the chain of causes, never a backtrace.
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            // Errors may quote a server or a file: their control characters are written out
            // (the message's own line breaks kept), so they cannot drive the terminal.
            let text: Vec<String> = describe(&err)
                .split('\n')
                .map(|line| buslab_device::printable(line.as_bytes()))
                .collect();
            eprintln!("error: {}", text.join("\n"));
            ExitCode::FAILURE
        }
    }
}

/// The command line's definition: the derived one, each `-q` with its own command's help, the
/// commands of the features this build lacks marked in --help.
fn command() -> clap::Command {
    cmd::absent::mark_missing(logging::quiet_help(Cli::command()))
}

/// The error and its causes on one line, `a: b: c`. A cause whose text the message already
/// ends with is left out: library errors often show their source in their own text.
fn describe(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.ends_with(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let quiet = cli.verbosity.quiet();
    // A configuration that cannot be used stops every command but `config` (which shows the
    // error, or writes a new file).
    if let Some(Err(e)) = config::loaded()
        && !matches!(cli.command, Command::Config(_))
    {
        anyhow::bail!("{e}");
    }
    match cli.command {
        Command::Lab(args) => cmd::lab::run(args, quiet),
        Command::Wire(args) => cmd::wire::run(args),
        Command::Sim(args) => cmd::sim::run(args, quiet),
        Command::Zelle(args) => cmd::zelle::run(args),
        Command::Cpu196(args) => cmd::cpu196::run(args, quiet),
        Command::Bus(args) => cmd::bus::run(args),
        Command::Dump(args) => cmd::dump::run(args),
        Command::Send(args) => cmd::send::run(args),
        Command::Gen(args) => cmd::r#gen::run(args),
        Command::Regs(args) => cmd::regs::run(args),
        Command::Status(args) => cmd::status::run(args),
        Command::Slio(args) => cmd::slio::run(args),
        Command::Bridge(args) => cmd::bridge::run(args),
        Command::Slcan(args) => cmd::slcan::run(args),
        Command::Monican(args) => cmd::monican::run(args),
        Command::Log(args) => cmd::log::run(args, quiet),
        Command::Play(args) => cmd::play::run(args, quiet),
        Command::Load(args) => cmd::load::run(args),
        Command::Sendfile(args) => cmd::sendfile::run(args),
        Command::Mail(args) => cmd::mail::run(args),
        Command::Recvfile(args) => cmd::recvfile::run(args),
        Command::Web(args) => cmd::web::run(args, quiet),
        Command::Monitor(args) => cmd::monitor::run(args),
        Command::Config(args) => cmd::config::run(args),
    }
}

#[cfg(test)]
mod tests {
    use super::describe;

    /// An error that shows its source in its own text, as many library errors do.
    #[derive(Debug)]
    struct Open {
        source: std::io::Error,
    }

    impl std::fmt::Display for Open {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "cannot open port: {}", self.source)
        }
    }

    impl std::error::Error for Open {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.source)
        }
    }

    #[test]
    fn causes_already_in_the_message_are_not_repeated() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let err = anyhow::Error::new(Open { source: io }).context("opening the cell");
        assert_eq!(
            describe(&err),
            "opening the cell: cannot open port: no such file"
        );
        let plain = anyhow::anyhow!("root cause").context("outer");
        assert_eq!(describe(&plain), "outer: root cause");
    }
}

#[cfg(test)]
mod help_tests {
    /// `-q`'s help in `buslab PATH --help`.
    fn quiet_help(path: &[&str]) -> String {
        let mut command = super::command();
        command.build();
        for name in path {
            command = command.find_subcommand(name).unwrap().clone();
        }
        let quiet = command.get_arguments().find(|a| a.get_id() == "quiet");
        quiet.unwrap().get_help().unwrap().to_string()
    }

    /// Every subcommand's `-q` help mentioned `sim` and `lab`.
    #[test]
    fn each_commands_quiet_help_says_what_it_does_there() {
        for path in [
            &["dump"][..],
            &["bus", "serve"],
            &["log", "info"],
            &["cpu196", "info"],
        ] {
            assert_eq!(
                quiet_help(path),
                "Fewer log lines: errors only (RUST_LOG overrides)",
                "{path:?}"
            );
        }
        assert!(quiet_help(&["lab"]).contains("no status line"));
        assert!(quiet_help(&["sim"]).contains("only the summary"));
        assert!(quiet_help(&["log", "convert"]).contains("No progress bar"));
        assert!(quiet_help(&["web"]).contains("no `Ctrl-C to stop`"));
        assert!(quiet_help(&["cpu196", "serve"]).contains("no `Ctrl-C to stop`"));
        for (path, _) in crate::logging::QUIET_HELP {
            assert!(!quiet_help(path).contains("`sim`"), "{path:?}");
        }
        // The flag still works where its help differs, before and after the subcommand.
        for args in [
            &["buslab", "-q", "sim", "x.toml"][..],
            &["buslab", "sim", "-q", "x.toml"],
        ] {
            let m = super::command().try_get_matches_from(args).unwrap();
            assert!(m.get_flag("quiet"), "{args:?}");
        }
    }

    /// Every argument of every subcommand explains itself in `--help`.
    #[test]
    fn every_argument_has_help_text() {
        fn walk(cmd: &clap::Command, path: &str, missing: &mut Vec<String>) {
            for arg in cmd.get_arguments() {
                let id = arg.get_id().as_str();
                if matches!(id, "help" | "version") {
                    continue;
                }
                if arg.get_help().is_none() && arg.get_long_help().is_none() {
                    missing.push(format!("{path} {id}"));
                }
            }
            for sub in cmd.get_subcommands() {
                if sub.get_about().is_none() && sub.get_long_about().is_none() {
                    missing.push(format!("{path} {} (the subcommand)", sub.get_name()));
                }
                walk(sub, &format!("{path} {}", sub.get_name()), missing);
            }
        }
        let mut missing = Vec::new();
        let cli = super::command();
        // clap's own consistency checks on every subcommand (they otherwise fire only when a
        // user runs that subcommand).
        cli.clone().debug_assert();
        walk(&cli, "buslab", &mut missing);
        assert!(missing.is_empty(), "no help text:\n{}", missing.join("\n"));
    }
}
