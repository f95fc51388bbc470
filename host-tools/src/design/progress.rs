//! `M73 P<percent> R<minutes left>` progress lines, as PrusaSlicer writes them for printers
//! whose profile asks for them ([`Profile::progress`]): one where the design starts, one after
//! every layer marker, and `M73 P100 R0` before the end code.
//!
//! The times are those of the written G-code itself, planned by the same acceleration-aware
//! motion model `host-tools stats` uses ([`crate::design::motion`] with the profile's limits),
//! so the printer's display and `stats` agree. Heating in the start code is not counted (as in
//! PrusaSlicer). The lines carry no `L`, so they are not layer markers for the firmware's
//! detector (`M73 L<n>` would be): layer numbering is the markers' alone.

use crate::design::motion::{plan_gcode, MotionLimits};
use crate::design::profile::Profile;
use crate::gcode::read::ReadError;

/// Inserts progress lines into `buf` at the byte offsets `at` (each at the start of a line,
/// ascending, all ≥ `body_start`; the last one is where the end code begins). The G-code from
/// `body_start` to the last offset is planned to find the time at each offset.
pub fn insert_m73(
    buf: &mut Vec<u8>,
    body_start: usize,
    at: &[usize],
    profile: &Profile,
) -> Result<(), ReadError> {
    let Some(&body_end) = at.last() else {
        return Ok(());
    };
    let body = buf.get(body_start..body_end).unwrap_or(&[]);
    // (1-based line of the move, its start time) in file order.
    let mut starts: Vec<(u32, f64)> = Vec::new();
    let totals = plan_gcode(
        body,
        MotionLimits::from_profile(profile),
        &mut |s| starts.push((s.line, s.t_start_s)),
        &mut |_, _, _| {},
    )?;
    let total_s = totals.time_s;
    // Line number (1-based, within the body) of the line starting at each offset.
    let mut lines = Vec::with_capacity(at.len());
    let mut line = 1u32;
    let mut pos = body_start;
    for &off in at {
        let off = off.clamp(pos, body_end);
        line += memchr::memchr_iter(b'\n', buf.get(pos..off).unwrap_or(&[])).count() as u32;
        pos = off;
        lines.push(line);
    }
    let mut out = Vec::with_capacity(buf.len() + at.len() * 16);
    let mut copied = 0usize;
    let mut last: Option<(u32, u32)> = None;
    for (k, (&off, &l)) in at.iter().zip(&lines).enumerate() {
        let is_last = k + 1 == at.len();
        let t = if is_last {
            total_s
        } else {
            let i = starts.partition_point(|(sl, _)| *sl < l);
            starts.get(i).map_or(total_s, |(_, t)| *t)
        };
        let (pct, left_min) = if is_last {
            (100, 0)
        } else if total_s <= 0.0 {
            (0, 0)
        } else {
            (
                ((t / total_s) * 100.0).floor().clamp(0.0, 99.0) as u32,
                ((total_s - t) / 60.0).round().max(0.0) as u32,
            )
        };
        if last == Some((pct, left_min)) {
            continue;
        }
        last = Some((pct, left_min));
        let off = off.clamp(copied, buf.len());
        out.extend_from_slice(buf.get(copied..off).unwrap_or(&[]));
        copied = off;
        out.extend_from_slice(format!("M73 P{pct} R{left_min}\n").as_bytes());
    }
    out.extend_from_slice(buf.get(copied..).unwrap_or(&[]));
    *buf = out;
    Ok(())
}
