//! `host-tools preview` (not built yet).

/// Arguments of `host-tools preview`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`preview` is not built yet; see the README's table of what works")
}
