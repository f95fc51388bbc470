//! `host-tools timebased`: resample a toolpath at a fixed period (time-based G-code).

use crate::design::motion::{MotionLimits, Trajectory};
use crate::design::profile::Profile;
use crate::paste::timebased::{first_temperatures, with_start_end, write_timebased, TimedPath};
use std::path::PathBuf;

/// Arguments of `host-tools timebased`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input G-code (ours or a slicer's).
    pub input: PathBuf,
    /// Output time-based G-code.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Sample period, ms.
    #[arg(long, default_value_t = 100.0)]
    pub period_ms: f64,
    /// Printer profile whose motion limits time the moves (built-in name or TOML path).
    #[arg(long, default_value = "ender3")]
    pub printer: String,
}

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    if !a.period_ms.is_finite() || a.period_ms <= 0.0 {
        anyhow::bail!("--period-ms must be a positive number");
    }
    let profile = Profile::load(&a.printer)?;
    let input = crate::fileio::read_bounded(&a.input, crate::fileio::Limit::Gcode)?;
    let traj = Trajectory::from_gcode(&input, MotionLimits::from_profile(&profile))
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.input.display()))?;
    let period_s = a.period_ms / 1000.0;
    let n = (traj.duration_s() / period_s).floor() + 1.0;
    if n > 50e6 {
        anyhow::bail!(
            "{:.0} samples at {} ms: choose a longer --period-ms",
            n,
            a.period_ms
        );
    }
    let samples = traj.samples(period_s);
    // The source's heating and homing are not motion: the printer's start and end code go
    // around the samples, at the source's first temperatures (else the profile's).
    let (hotend_c, bed_c) = first_temperatures(&input);
    let hotend_c = hotend_c.unwrap_or(profile.hotend_c);
    let bed_c = bed_c.unwrap_or(profile.bed_c);
    let text = with_start_end(
        &write_timebased(&samples, period_s, &a.input.display().to_string()),
        &profile.start_code(hotend_c, bed_c),
        &profile.end_code(hotend_c, bed_c),
    );
    crate::fileio::write_bytes(&a.output, text.as_bytes())?;
    let deposited = samples.iter().filter(|s| s.extruding).count();
    crate::fileio::say(format_args!(
        "{} samples every {} ms over {:.1} s ({} depositing) -> {} ({} bytes)",
        samples.len(),
        a.period_ms,
        traj.duration_s(),
        deposited,
        a.output.display(),
        text.len()
    ))
}
