//! `host-tools preview FILE.gcode -o OUT.svg|OUT.png`: top, side and isometric views coloured
//! by speed or cross-section, with the bed outline; `host-tools preview --html OUT.html
//! FILE.gcode` (or `-o OUT.html`): a self-contained 3D page to turn and zoom, coloured by speed,
//! cross-section, layer or time, travels on demand, a layer range.

use crate::design::profile::Profile;
use crate::job::preview::{render, ColorBy, PreviewOptions};
use anyhow::Context;
use std::path::PathBuf;

/// Arguments of `host-tools preview`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// G-code file.
    pub file: PathBuf,
    /// Output picture: `.svg`, `.png` or `.html` (the 3D page).
    #[arg(short, long, required_unless_present = "html")]
    pub output: Option<PathBuf>,
    /// Write the self-contained 3D page (HTML, no network) to this file.
    #[arg(long)]
    pub html: Option<PathBuf>,
    /// Colour printing moves by speed or by cross-section.
    #[arg(long, value_enum, default_value = "speed")]
    pub color: ColorBy,
    /// Printer profile (bed outline, filament diameter): built-in name or TOML file
    /// (`--profile help` lists them).
    #[arg(long, alias = "profile", default_value = "ender3")]
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
    if super::list_profiles_if_asked(&args.printer)? {
        return Ok(());
    }
    let profile = Profile::load(&args.printer)?;
    if !(100..=4000).contains(&args.size) {
        anyhow::bail!("--size must be within 100..=4000 pixels");
    }
    let data = crate::fileio::read_bounded(&args.file, crate::fileio::Limit::Gcode)?;
    let outputs: Vec<&PathBuf> = args.output.iter().chain(args.html.iter()).collect();
    for out in outputs {
        let spinner = indicatif::ProgressBar::new_spinner();
        spinner.set_message("drawing");
        spinner.enable_steady_tick(std::time::Duration::from_millis(120));
        let is_html = args.html.as_ref() == Some(out);
        let target = if is_html && !has_html_ext(out) {
            anyhow::bail!(
                "--html {}: the page's name must end in .html",
                out.display()
            );
        } else {
            out
        };
        let s = render(
            &data,
            &profile,
            target,
            &PreviewOptions {
                color_by: args.color,
                travels: !args.no_travels,
                view_px: args.size,
            },
        );
        spinner.finish_and_clear();
        let s = s.with_context(|| format!("previewing {}", args.file.display()))?;
        if has_html_ext(target) {
            crate::fileio::say(format_args!(
                "{}: {} printing moves, {} travels, {:.1} min (open it in a browser: drag to turn, \
                 wheel to zoom)",
                target.display(),
                s.print_moves,
                s.travels,
                s.range.1 / 60.0
            ))?;
        } else {
            crate::fileio::say(format_args!(
                "{}: {} printing moves, {} travels, colour {:?} {:.3}–{:.3}",
                target.display(),
                s.print_moves,
                s.travels,
                args.color,
                s.range.0,
                s.range.1
            ))?;
        }
    }
    Ok(())
}

fn has_html_ext(p: &std::path::Path) -> bool {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .is_some_and(|e| e == "html" || e == "htm")
}
