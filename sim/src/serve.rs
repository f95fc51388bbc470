//! `sim serve`: the virtual printer on a pseudo-terminal.

/// `sim serve` options.
#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// Virtual seconds per real second.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
}

/// Run the virtual printer.
pub fn serve(_a: ServeArgs) -> anyhow::Result<()> {
    anyhow::bail!("sim serve: not built yet")
}
