//! `--dbc FILE`: the DBC database every tool that shows frames can decode them with.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use buslab_dbc::Database;

/// A DBC file larger than this is refused: the largest real databases are a few MiB.
const MAX_DBC_BYTES: u64 = 64 << 20;

/// The option, for every command that takes a database.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct DbcArg {
    /// A DBC database: frames of its messages are shown as named, scaled signals.
    #[arg(long, value_name = "FILE")]
    pub dbc: Option<PathBuf>,
}

impl DbcArg {
    /// The database, if one was given.
    #[expect(
        dead_code,
        reason = "the tools' --dbc options are being wired (issue 29)"
    )]
    pub fn load(&self) -> anyhow::Result<Option<Arc<Database>>> {
        self.dbc.as_deref().map(load).transpose()
    }
}

/// Reads and resolves a DBC file (a regular file, bounded); errors name the file and the line.
pub fn load(path: &Path) -> anyhow::Result<Arc<Database>> {
    let bytes = buslab_link::fs::read_limited(path, MAX_DBC_BYTES)?;
    let database =
        Database::from_bytes(&bytes).with_context(|| format!("DBC file {}", path.display()))?;
    Ok(Arc::new(database))
}
