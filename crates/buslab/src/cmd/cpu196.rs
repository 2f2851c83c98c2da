//! `buslab cpu196`.

#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`buslab cpu196` is not built yet")
}
