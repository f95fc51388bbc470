//! `host-tools timebased`: resample a toolpath at a fixed period (time-based G-code).

use crate::design::motion::{MotionLimits, Trajectory};
use crate::design::profile::Profile;
use crate::paste::timebased::{
    approach, timed_lines, with_start_end, write_timebased, TimedLine, TimedPath, PERIOD_MS,
};
use crate::paste::window::{design_window, fan_duty, last_fan_duty};
use std::path::{Path, PathBuf};

/// Arguments of `host-tools timebased`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input G-code (ours or a slicer's).
    pub input: PathBuf,
    /// Output time-based G-code.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Sample period, ms (1 to 60,000).
    #[arg(long, default_value_t = 100.0, value_parser = super::range::within(PERIOD_MS.0, PERIOD_MS.1))]
    pub period_ms: f64,
    /// Printer profile whose motion limits time the moves (built-in name or TOML path).
    #[arg(long, default_value = "ender3")]
    pub printer: String,
}

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    crate::fileio::refuse_inputs_as_outputs(&[&a.output], &[&a.input, Path::new(&a.printer)])?;
    let profile = Profile::load(&a.printer)?;
    let input = crate::fileio::read_bounded(&a.input, crate::fileio::Limit::Gcode)?;
    let traj = Trajectory::from_gcode(&input, MotionLimits::from_profile(&profile))
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.input.display()))?;
    let w = design_window(&traj, &input)
        .ok_or_else(|| anyhow::anyhow!("{}: nothing is printed", a.input.display()))?;
    let (t0, t1) = (w.t0_s, w.t1_s);
    let period_s = a.period_ms / 1000.0;
    let n = ((t1 - t0) / period_s).ceil() + 1.0;
    if n > 50e6 {
        anyhow::bail!(
            "{:.0} samples at {} ms: choose a longer --period-ms",
            n,
            a.period_ms
        );
    }
    // Only the design is resampled: the source's own start and end code (heating, homing,
    // purge, park) are not motion of the design; the printer's go around the samples, at the
    // temperatures in force where the design starts (else the profile's), with an approach
    // from where the start code leaves the head to the first sample. The design's state
    // lines (fan, temperatures, pauses, raw commands) and layer marks come through at their
    // times, after the fan the source had on when the design started.
    let samples = traj.samples_between(t0, t1, period_s);
    let hotend_c = w.hotend_c.unwrap_or(profile.hotend_c);
    let bed_c = w.bed_c.unwrap_or(profile.bed_c);
    let mut start = profile.start_code(hotend_c, bed_c);
    // The fan the source had on where the design starts, unless the start code leaves it so.
    let mut lines: Vec<TimedLine> = w
        .fan
        .iter()
        .filter(|f| fan_duty(f.as_bytes()) != last_fan_duty(&start))
        .map(|f| TimedLine {
            t_s: t0,
            text: f.clone(),
        })
        .collect();
    lines.extend(timed_lines(&traj, &w));
    if let Some(first) = samples.first() {
        let from = crate::additive::job::start_position(&profile).ok();
        if !start.is_empty() && !start.ends_with('\n') {
            start.push('\n');
        }
        start.push_str(&approach(
            from,
            first.pos,
            profile.travel_speed_mm_s,
            profile.limits.max_feed_z_mm_s,
        ));
    }
    let text = with_start_end(
        &write_timebased(
            &samples,
            period_s,
            &a.input.display().to_string(),
            t0,
            &lines,
        ),
        &start,
        &profile.end_code(hotend_c, bed_c),
    );
    crate::fileio::write_bytes(&a.output, text.as_bytes())?;
    let deposited = samples.iter().filter(|s| s.extruding).count();
    crate::fileio::say(format_args!(
        "{} samples every {} ms over the design's {:.1} s ({} depositing, {} state lines kept; the source's start and end code, {:.1} s, left out) -> {} ({} bytes)",
        samples.len(),
        a.period_ms,
        t1 - t0,
        deposited,
        w.state.len(),
        traj.duration_s() - (t1 - t0),
        a.output.display(),
        text.len()
    ))
}
