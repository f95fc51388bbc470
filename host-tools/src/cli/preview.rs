//! `host-tools preview FILE.gcode -o OUT.svg|OUT.png`: top, side and isometric views coloured
//! by speed or cross-section, with the bed outline; `host-tools preview --html FILE.gcode -o
//! OUT.html` (also `preview FILE.gcode -o OUT.html`, and the older `preview --html OUT.html
//! FILE.gcode`): a self-contained 3D page to turn and zoom, coloured by speed, cross-section,
//! layer or time, travels on demand, a layer range.

use crate::design::profile::Profile;
use crate::job::preview::{render, ColorBy, PreviewOptions};
use anyhow::Context;
use std::path::PathBuf;

/// Arguments of `host-tools preview`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// G-code file.
    pub file: Option<PathBuf>,
    /// Output picture: `.svg`, `.png` or `.html` (the 3D page).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Write the self-contained 3D page (HTML, no network): `--html FILE.gcode -o OUT.html`,
    /// or with the page's name, `--html OUT.html FILE.gcode`.
    #[arg(long, num_args = 0..=1, value_name = "FILE")]
    pub html: Option<Option<PathBuf>>,
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
    let (file, outputs) = files(&args)?;
    let targets: Vec<&std::path::Path> = outputs.iter().map(PathBuf::as_path).collect();
    crate::fileio::refuse_inputs_as_outputs(
        &targets,
        &[&file, std::path::Path::new(&args.printer)],
    )?;
    let data = crate::fileio::read_bounded(&file, crate::fileio::Limit::Gcode)?;
    for target in &outputs {
        let spinner = indicatif::ProgressBar::new_spinner();
        spinner.set_message("drawing");
        spinner.enable_steady_tick(std::time::Duration::from_millis(120));
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
        let s = s.with_context(|| format!("previewing {}", file.display()))?;
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

/// The input and the outputs, however `--html` was typed: as a flag (`--html FILE.gcode -o
/// OUT.html`, `FILE.gcode --html -o OUT.html`) or with the page's name (`--html OUT.html
/// FILE.gcode`); of `--html`'s value and the file, the one named `.html` is the page.
fn files(args: &Args) -> anyhow::Result<(PathBuf, Vec<PathBuf>)> {
    let html = args.html.as_ref().and_then(Option::as_ref);
    let (file, page) = match (html, &args.file) {
        (Some(h), Some(f)) if has_html_ext(h) => (f.clone(), Some(h.clone())),
        (Some(h), Some(f)) if has_html_ext(f) => (h.clone(), Some(f.clone())),
        (Some(h), Some(f)) => anyhow::bail!(
            "--html {} {}: one of them must be the page (named .html), or write `--html {} -o \
             PAGE.html`",
            h.display(),
            f.display(),
            f.display()
        ),
        (Some(h), None) => (h.clone(), None),
        (None, Some(f)) => (f.clone(), None),
        (None, None) => anyhow::bail!("give the G-code file to preview"),
    };
    let mut outputs: Vec<PathBuf> = page.into_iter().collect();
    outputs.extend(args.output.iter().cloned());
    if outputs.is_empty() {
        anyhow::bail!(if args.html.is_some() {
            "--html: name the page with -o PAGE.html"
        } else {
            "name the picture with -o OUT.svg, OUT.png or OUT.html"
        });
    }
    if args.html.is_some() && !outputs.iter().any(|o| has_html_ext(o)) {
        anyhow::bail!(
            "--html: the page's name must end in .html (got {})",
            outputs[0].display()
        );
    }
    Ok((file, outputs))
}

fn has_html_ext(p: &std::path::Path) -> bool {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .is_some_and(|e| e == "html" || e == "htm")
}
