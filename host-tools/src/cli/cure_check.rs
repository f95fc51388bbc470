//! `host-tools cure-check`: flag spots laid on material that has not cured long enough.

use crate::design::motion::{MotionLimits, Trajectory};
use crate::design::profile::Profile;
use crate::paste::cure::{check, CureParams};
use crate::paste::cure_report::{heat_map_svg, summary};
use crate::paste::timebased::{is_timebased, read_timebased, TimedPath, PERIOD_MS};
use crate::paste::window::design_window;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `host-tools cure-check`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Time-based G-code (from `timebased`), or any G-code, resampled first.
    pub input: PathBuf,
    /// Required curing time, s.
    #[arg(long)]
    pub cure: f64,
    /// Horizontal search radius for "directly below", mm.
    #[arg(long, default_value_t = 1.0)]
    pub radius: f64,
    /// A sample is below another when lower by at least this, mm.
    #[arg(long, default_value_t = 0.05)]
    pub min_dz: f64,
    /// Sample period when the input is ordinary G-code, ms (1 to 60,000).
    #[arg(long, default_value_t = 100.0, value_parser = super::range::within(PERIOD_MS.0, PERIOD_MS.1))]
    pub period_ms: f64,
    /// Printer profile for resampling ordinary G-code.
    #[arg(long, default_value = "ender3")]
    pub printer: String,
    /// JSON report on stdout (samples, violations, min_elapsed_s, layers, ...).
    #[arg(long)]
    pub json: bool,
    /// Heat map of elapsed time per layer (SVG).
    #[arg(long)]
    pub heatmap: Option<PathBuf>,
    /// Exit with status 2 when there are violations.
    #[arg(long)]
    pub strict: bool,
}

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(h) = &a.heatmap {
        crate::fileio::refuse_inputs_as_outputs(&[h], &[&a.input, Path::new(&a.printer)])?;
    }
    for (name, v) in [
        ("--cure", a.cure),
        ("--radius", a.radius),
        ("--period-ms", a.period_ms),
    ] {
        if !v.is_finite() || v <= 0.0 {
            anyhow::bail!("{name} must be a positive number, got {v}");
        }
    }
    if !a.min_dz.is_finite() || a.min_dz < 0.0 {
        anyhow::bail!("--min-dz must be ≥ 0");
    }
    let input = crate::fileio::read_bounded(&a.input, crate::fileio::Limit::Gcode)?;
    let (period_s, samples) = if is_timebased(&input) {
        read_timebased(&input)?
    } else {
        let profile = Profile::load(&a.printer)?;
        let traj = Trajectory::from_gcode(&input, MotionLimits::from_profile(&profile))
            .map_err(|e| anyhow::anyhow!("{}: {e}", a.input.display()))?;
        let p = a.period_ms / 1000.0;
        // The design only, as `timebased` resamples it.
        let w = design_window(&traj, &input)
            .ok_or_else(|| anyhow::anyhow!("{}: nothing is printed", a.input.display()))?;
        (p, traj.samples_between(w.t0_s, w.t1_s, p))
    };
    let params = CureParams {
        period_s,
        cure_s: a.cure,
        radius_mm: a.radius,
        min_dz_mm: a.min_dz,
    };
    let t0 = std::time::Instant::now();
    let report = check(&samples, &params);
    let check_s = t0.elapsed().as_secs_f64();
    eprintln!(
        "checked {} samples in {:.3} s ({:.1} M samples/s)",
        samples.len(),
        check_s,
        samples.len() as f64 / check_s.max(1e-9) / 1e6
    );
    if let Some(h) = &a.heatmap {
        crate::fileio::write_bytes(h, heat_map_svg(&samples, &report).as_bytes())?;
    }
    let text = if a.json {
        serde_json::to_string_pretty(&report)? + "\n"
    } else {
        summary(&report, true)
    };
    // A closed pipe (`| head`) is not an error.
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
        r => r?,
    }
    if a.strict && report.violation_count > 0 {
        std::process::exit(2);
    }
    Ok(())
}
