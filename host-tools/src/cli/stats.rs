//! `host-tools stats FILE.gcode [--json] [--printer PROFILE]`: layers (or turns), moves,
//! acceleration-aware print time, filament, bounding box and time per layer.

use crate::design::profile::Profile;
use crate::job::stats::{hms, stats};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::PathBuf;

/// Arguments of `host-tools stats`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// G-code file.
    pub file: PathBuf,
    /// Print JSON (fields: layers, moves, print_time_s, filament_mm, bbox_mm, ...).
    #[arg(long)]
    pub json: bool,
    /// Printer profile whose limits time the moves: built-in name or TOML file
    /// (`--profile help` lists them).
    #[arg(long, alias = "profile", default_value = "ender3")]
    pub printer: String,
    /// List the time of every layer (text output).
    #[arg(long)]
    pub layers: bool,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if super::list_profiles_if_asked(&args.printer)? {
        return Ok(());
    }
    let profile = Profile::load(&args.printer)?;
    let data = crate::fileio::read_bounded(&args.file, crate::fileio::Limit::Gcode)?;
    let s = stats(&data, &profile).map_err(|e| anyhow::anyhow!("{}: {e}", args.file.display()))?;
    for e in &s.bad_line_errors {
        eprintln!(
            "warning: {}: line {}: {} (skipped, as the printer would)",
            args.file.display(),
            e.line,
            e.msg
        );
    }
    if s.bad_lines > s.bad_line_errors.len() as u64 {
        eprintln!(
            "warning: {} more bad lines skipped",
            s.bad_lines - s.bad_line_errors.len() as u64
        );
    }
    if args.json {
        return emit(serde_json::to_string_pretty(&s)? + "\n");
    }
    let mut o = String::new();
    let b = &s.bbox_mm;
    writeln!(o, "file          {}", args.file.display())?;
    writeln!(o, "layers        {} (from {})", s.layers, s.layer_source)?;
    writeln!(
        o,
        "moves         {} ({} printing, {} travel, {} extruder-only)",
        s.moves, s.print_moves, s.travel_moves, s.extruder_moves
    )?;
    writeln!(
        o,
        "print time    {} ({:.1} s, acceleration-aware, profile {})",
        hms(s.print_time_s),
        s.print_time_s,
        profile.name
    )?;
    writeln!(
        o,
        "filament      {:.1} mm, {:.0} mm³, {:.1} g",
        s.filament_mm, s.filament_volume_mm3, s.filament_mass_g
    )?;
    writeln!(
        o,
        "bbox          ({:.2}, {:.2}, {:.2}) – ({:.2}, {:.2}, {:.2}) mm",
        b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]
    )?;
    writeln!(
        o,
        "paths         {:.0} mm printing, {:.0} mm travel",
        s.print_path_mm, s.travel_path_mm
    )?;
    if !s.layer_times.is_empty() {
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for l in &s.layer_times {
            lo = lo.min(l.time_s);
            hi = hi.max(l.time_s);
        }
        writeln!(o, "layer time    {lo:.1} s – {hi:.1} s")?;
    }
    if args.layers {
        // Layer numbers are the firmware's (what `M761 L<n>` and the layer pause use).
        writeln!(o, "  start code   {:>8.2} s", s.before_first_layer_s)?;
        for l in &s.layer_times {
            match l.z_mm {
                Some(z) => writeln!(
                    o,
                    "  layer {:>5}  z {:>8.3}  {:>8.2} s",
                    l.layer, z, l.time_s
                )?,
                None => writeln!(o, "  layer {:>5}  z        ?  {:>8.2} s", l.layer, l.time_s)?,
            }
        }
    }
    emit(o)
}

/// Writes to stdout; a closed pipe (`| head`) is not an error.
fn emit(text: String) -> anyhow::Result<()> {
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => Ok(r?),
    }
}
