//! `host-tools cure-check` (not built yet).

/// Arguments of `host-tools cure-check`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`cure_check` is not built yet; see the README's table of what works")
}
