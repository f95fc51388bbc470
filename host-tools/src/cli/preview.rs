//! `host-tools preview FILE.gcode -o OUT.svg|OUT.png`: top, side and isometric views coloured
//! by speed or cross-section, with the bed outline.

use crate::design::profile::Profile;
use crate::job::preview::{render, ColorBy, PreviewOptions};
use anyhow::Context;
use std::path::PathBuf;

/// Arguments of `host-tools preview`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// G-code file.
    pub file: PathBuf,
    /// Output picture: `.svg` or `.png`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Colour printing moves by speed or by cross-section.
    #[arg(long, value_enum, default_value = "speed")]
    pub color: ColorBy,
    /// Printer profile (bed outline, filament diameter): built-in name or TOML file.
    #[arg(long, default_value = "ender3")]
    pub printer: String,
    /// Leave travels out.
    #[arg(long)]
    pub no_travels: bool,
    /// Size of each of the three views, pixels.
    #[arg(long, default_value_t = 600)]
    pub size: u32,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let profile = Profile::load(&args.printer)?;
    if !(100..=4000).contains(&args.size) {
        anyhow::bail!("--size must be within 100..=4000 pixels");
    }
    let data = crate::fileio::read_bounded(&args.file, crate::fileio::Limit::Gcode)?;
    let spinner = indicatif::ProgressBar::new_spinner();
    spinner.set_message("drawing");
    spinner.enable_steady_tick(std::time::Duration::from_millis(120));
    let s = render(
        &data,
        &profile,
        &args.output,
        &PreviewOptions {
            color_by: args.color,
            travels: !args.no_travels,
            view_px: args.size,
        },
    );
    spinner.finish_and_clear();
    let s = s.with_context(|| format!("previewing {}", args.file.display()))?;
    crate::fileio::say(format_args!(
        "{}: {} printing moves, {} travels, colour {:?} {:.3}–{:.3}",
        args.output.display(),
        s.print_moves,
        s.travels,
        args.color,
        s.range.0,
        s.range.1
    ))
}
