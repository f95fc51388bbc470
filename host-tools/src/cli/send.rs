//! `host-tools send` (not built yet).

/// Arguments of `host-tools send`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`send` is not built yet; see the README's table of what works")
}
