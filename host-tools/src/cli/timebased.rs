//! `host-tools timebased` (not built yet).

/// Arguments of `host-tools timebased`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`timebased` is not built yet; see the README's table of what works")
}
