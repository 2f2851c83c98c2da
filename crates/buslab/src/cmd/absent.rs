//! The commands of the cargo features a build was made without (`--no-default-features`, or
//! `--features` naming only some). Each stays a subcommand, listed in `--help` as not in this
//! build, takes whatever follows it, and fails naming the feature and how to build it in,
//! rather than with clap's "unrecognized subcommand" (docs/decisions.md, "Lean build").

// With every feature on, only the tests use the generic parts.
#![cfg_attr(
    all(feature = "web", feature = "mail", feature = "tui"),
    allow(dead_code)
)]

use std::ffi::OsString;

/// A cargo feature of the `buslab` crate and the commands that need it.
pub struct Feature {
    pub name: &'static str,
    /// Whether this build has it.
    pub built: bool,
    /// The subcommands that need it, each as its path (`["config", "wizard"]`).
    pub commands: &'static [&'static [&'static str]],
}

/// Every feature that takes commands away when it is off (`sqlite` takes none: a `.db` log
/// is refused by `buslab-logs`, with the reason).
pub const FEATURES: &[Feature] = &[
    Feature {
        name: "web",
        built: cfg!(feature = "web"),
        commands: &[&["web"]],
    },
    Feature {
        name: "mail",
        built: cfg!(feature = "mail"),
        commands: &[&["mail"]],
    },
    Feature {
        name: "tui",
        built: cfg!(feature = "tui"),
        commands: &[&["monitor"], &["config", "wizard"]],
    },
];

/// A command, or an option, that needs a feature this build lacks.
#[derive(Debug, thiserror::Error)]
#[error(
    "{what}: this build was made without the `{feature}` feature; to have it: cargo install --locked --path crates/buslab --features {feature}"
)]
pub struct NotBuilt {
    pub what: &'static str,
    pub feature: &'static str,
}

/// The arguments of a command this build lacks: anything, so that whatever was typed, the
/// answer is the missing feature.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Not read: this build lacks the command.
    #[arg(num_args = 0.., allow_hyphen_values = true, trailing_var_arg = true, hide = true)]
    ignored: Vec<OsString>,
}

/// `command` with the commands of the features this build lacks marked as such in the help.
pub fn mark_missing(command: clap::Command) -> clap::Command {
    mark(command, FEATURES.iter().filter(|f| !f.built))
}

/// `command` with each of `absent`'s commands described as not in this build.
pub fn mark<'a>(
    mut command: clap::Command,
    absent: impl Iterator<Item = &'a Feature>,
) -> clap::Command {
    for feature in absent {
        for path in feature.commands {
            command = mark_one(command, path, feature.name);
        }
    }
    command
}

fn mark_one(command: clap::Command, path: &[&str], feature: &str) -> clap::Command {
    let Some((name, rest)) = path.split_first() else {
        return command;
    };
    command.mut_subcommand(*name, |sub| {
        if !rest.is_empty() {
            return mark_one(sub, rest, feature);
        }
        let about = sub.get_about().map(|a| a.to_string()).unwrap_or_default();
        sub.about(format!(
            "[not in this build: no `{feature}` feature] {about}"
        ))
        .long_about(None)
    })
}

/// `buslab web` and the lab's web pages, without the `web` feature.
#[cfg(not(feature = "web"))]
pub mod web {
    use std::path::Path;

    use buslab_slio::SlioId;

    pub use super::Args;
    use super::NotBuilt;
    use crate::cmd::lab::WebOptions;

    pub fn run(_: Args, _quiet: bool) -> anyhow::Result<()> {
        Err(NotBuilt {
            what: "buslab web",
            feature: "web",
        }
        .into())
    }

    /// The lab's web pages: none in this build (there is no value of this type).
    pub enum WebServer {}

    impl WebServer {
        pub fn stop(self) {
            match self {}
        }
    }

    /// The lab without its web pages: the banner says so, unless `--no-web`; an error if
    /// they were asked for by `--web ADDR` or `--allow-host`.
    pub fn lab_pages(
        options: &WebOptions,
        _url: &str,
        _slios: &[SlioId],
        _ports: Option<(&Path, &Path)>,
        _dbc: std::sync::Arc<buslab_dbc::Database>,
    ) -> anyhow::Result<Option<WebServer>> {
        if options.listen.is_some() || !options.hosts.allow_host.is_empty() {
            return Err(NotBuilt {
                what: "buslab lab --web/--allow-host (the web pages)",
                feature: "web",
            }
            .into());
        }
        if !options.no_web {
            eprintln!("  web pages:  none (this build was made without the `web` feature)");
        }
        Ok(None)
    }
}

/// `buslab mail`, without the `mail` feature.
#[cfg(not(feature = "mail"))]
pub mod mail {
    pub use super::Args;
    use super::NotBuilt;

    pub fn run(_: Args) -> anyhow::Result<()> {
        Err(NotBuilt {
            what: "buslab mail",
            feature: "mail",
        }
        .into())
    }
}

/// `buslab monitor`, without the `tui` feature.
#[cfg(not(feature = "tui"))]
pub mod monitor {
    pub use super::Args;
    use super::NotBuilt;

    pub fn run(_: Args) -> anyhow::Result<()> {
        Err(NotBuilt {
            what: "buslab monitor",
            feature: "tui",
        }
        .into())
    }
}

/// `buslab config wizard`, without the `tui` feature.
#[cfg(not(feature = "tui"))]
pub mod wizard {
    use super::NotBuilt;

    pub fn run(_: crate::cmd::config::WizardArgs) -> anyhow::Result<()> {
        Err(NotBuilt {
            what: "buslab config wizard",
            feature: "tui",
        }
        .into())
    }
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, FromArgMatches};

    use super::*;

    /// Every command a feature takes away exists under that name, and its help says it is
    /// not in the build (a renamed command would otherwise lose its mark silently).
    #[test]
    fn absent_commands_are_listed_as_not_in_this_build() {
        let marked = mark(crate::Cli::command(), FEATURES.iter());
        for feature in FEATURES {
            for path in feature.commands {
                let mut sub = &marked;
                for name in *path {
                    sub = sub
                        .find_subcommand(name)
                        .unwrap_or_else(|| panic!("no subcommand {path:?}"));
                }
                let about = sub.get_about().expect("a description").to_string();
                assert!(
                    about.starts_with(&format!(
                        "[not in this build: no `{}` feature] ",
                        feature.name
                    )),
                    "{path:?}: {about}"
                );
                assert!(about.len() > 40, "the description is kept: {about}");
            }
        }
    }

    /// Whatever follows an absent command, the user gets the missing feature, not an
    /// argument error.
    #[test]
    fn an_absent_command_takes_any_arguments() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(subcommand)]
            command: Sub,
        }
        #[derive(clap::Subcommand)]
        enum Sub {
            Web(Args),
        }
        let command = Cli::command();
        for args in [
            &["buslab", "web"][..],
            &["buslab", "web", "--bus", "vcan0", "--token"],
            &[
                "buslab",
                "web",
                "--no-such-option",
                "-x",
                "value",
                "--",
                "more",
            ],
        ] {
            let matches = command
                .clone()
                .try_get_matches_from(args)
                .unwrap_or_else(|e| panic!("{args:?}: {e}"));
            Cli::from_arg_matches(&matches).expect("parsed");
        }
    }

    #[test]
    fn not_built_names_the_feature_and_how_to_get_it() {
        let text = NotBuilt {
            what: "buslab web",
            feature: "web",
        }
        .to_string();
        assert_eq!(
            text,
            "buslab web: this build was made without the `web` feature; to have it: cargo install --locked --path crates/buslab --features web"
        );
    }
}
