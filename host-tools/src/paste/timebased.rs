//! Time-based G-code (SPEC §4, Nagura et al.): the toolpath resampled at a fixed period, so a
//! sample's index *is* its time (`t = index × period`).
//!
//! Resampling uses the acceleration-aware motion model of `stats`
//! ([`crate::design::motion::Trajectory`], ht-design's), reached through the small [`TimedPath`]
//! trait, so another model can be slotted in without touching the resampler or the cure check.
//!
//! Only the design is resampled ([`design_window`]): from its first printing move to its last,
//! so the source's own start code (homing, heating, purge line) and end code (retract, lift,
//! park) are not replayed in the samples: the printer's start and end code go around them,
//! and an approach (up, across, down) takes the head from where the start code leaves it to
//! the first sample.
//!
//! # Output format
//! ```text
//! ;TIMEBASED period_ms=100 samples=N
//! ;FORMAT line k (k = 0..N-1) of the motion lines below is the head position at t = k*period;
//! ;FORMAT G1 moves reach it in one period (F = distance / period), G4 P<period> = head still
//! (the printer's start code: homing, heating, its purge line — `timebased` writes the profile's)
//! ;TIMEBASED_APPROACH ...     <- up, across, down onto sample 0
//! ;TIMEBASED_BEGIN
//! G90
//! M82
//! G92 E0
//! G1 X.. Y.. Z.. E0 F..       <- sample 0: the design's first printing point
//! ;LAYER_CHANGE / ;Z:..       <- where the source's layer changes (not a sample)
//! G1 X.. Y.. E.. F..          <- sample 1, only changed axes written
//! G4 P100                     <- sample k while the head stands still (dwell, heating)
//! ;TIMEBASED_END              <- after the design's last point (the last sample; reached
//!                                within one period)
//! (the printer's end code)
//! ```
//! Only the lines between `;TIMEBASED_BEGIN` and `;TIMEBASED_END` are samples; start and end
//! code around them may move the head (homing, purge line, parking) without shifting times.
//! E is absolute: the filament pushed since sample 0 (whatever the source's E mode and `G92`
//! resets). A sample is *extruding* when E grows towards it; travels and retractions do not
//! deposit material. The file is ordinary G-code that any firmware runs at the right pace,
//! and `cure-check` reads it back sample by sample (with the same reader as `stats`).

use crate::design::motion::{prelude_marks, MoveKind, PrintHeights, Trajectory};
use crate::gcode::read::{default_reader, Event, GcodeReader, LayerSource};
use crate::paste::window::Window;
use glam::DVec3;
use std::fmt::Write as _;

/// The first line of a time-based file.
pub const HEADER_TAG: &str = ";TIMEBASED";
/// The line before the first sample.
pub const BEGIN_TAG: &str = ";TIMEBASED_BEGIN";
/// The line after the last sample.
pub const END_TAG: &str = ";TIMEBASED_END";

/// One sample of the toolpath.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Head position, mm.
    pub pos: DVec3,
    /// Absolute E (filament pushed so far), mm.
    pub e_mm: f64,
    /// True when material is deposited while reaching this sample.
    pub extruding: bool,
    /// Layer index from the source's layer marks (0 before the first).
    pub layer: u32,
}

/// Shortest and longest sample period `timebased` and `cure-check` take, ms: below 1 ms a
/// printer cannot take one move per period from a file, and a period of a minute already
/// says nothing about where the head went.
pub const PERIOD_MS: (f64, f64) = (1.0, 60_000.0);

/// Anything that can say where the head is at a given time.
pub trait TimedPath {
    /// Length of the job, s.
    fn duration_s(&self) -> f64;
    /// Samples at `t = t0 + k·period_s` from `t0_s` to `t1_s` (the last one at `t1_s` when
    /// the period does not divide the span: the head is there then at the latest). E is the
    /// filament pushed since `t0_s` (G92 resets and absolute/relative E do not show).
    fn samples_between(&self, t0_s: f64, t1_s: f64, period_s: f64) -> Vec<Sample>;
    /// Samples over the whole job.
    fn samples(&self, period_s: f64) -> Vec<Sample> {
        self.samples_between(0.0, self.duration_s(), period_s)
    }
}

impl TimedPath for Trajectory {
    fn duration_s(&self) -> f64 {
        self.duration_s
    }

    fn samples_between(&self, t0_s: f64, t1_s: f64, period_s: f64) -> Vec<Sample> {
        if self.segments.is_empty() || !(period_s.is_finite() && period_s > 0.0) {
            return Vec::new();
        }
        // Filament pushed before each segment (sums of its E changes: a G92 between two
        // segments is no motion).
        let mut pushed = Vec::with_capacity(self.segments.len() + 1);
        let mut acc = 0.0;
        for s in &self.segments {
            pushed.push(acc);
            acc += s.end[3] - s.start[3];
        }
        let e_at = |idx: usize, p: [f64; 4]| pushed[idx] + (p[3] - self.segments[idx].start[3]);
        let span = (t1_s - t0_s).max(0.0);
        let n = (span / period_s).ceil() as usize;
        let mut idx = self.segment_at(t0_s).unwrap_or(0);
        // A sample belongs to the layer the head printed last: a layer starts with its first
        // printing move, not with the rise, travel or wait before it (the time-based file
        // places its markers there, `timed_lines`).
        let print_layer = |i: usize| {
            let s = &self.segments[i];
            (s.kind == MoveKind::Print).then_some(s.layer)
        };
        let mut layer = (0..=idx).rev().find_map(print_layer).unwrap_or(0);
        let mut e0 = None;
        let mut out = Vec::with_capacity(n + 1);
        for k in 0..=n {
            let t = (t0_s + k as f64 * period_s).min(t1_s.max(t0_s));
            while idx + 1 < self.segments.len() && self.segments[idx + 1].t_start_s <= t {
                idx += 1;
                layer = print_layer(idx).unwrap_or(layer);
            }
            let seg = &self.segments[idx];
            let p = seg.position_at(t);
            let e = e_at(idx, p);
            let e0 = *e0.get_or_insert(e);
            let pos = DVec3::new(p[0], p[1], p[2]);
            // Deposits when E grew while the head moved since the sample before (as the file
            // is read back): the interval that ends a layer's printing in a rise deposits the
            // end of that layer.
            let extruding = out.last().is_some_and(|prev: &Sample| {
                e - e0 > prev.e_mm + 1e-9 && (pos - prev.pos).length_squared() > 1e-18
            });
            out.push(Sample {
                pos,
                e_mm: e - e0,
                extruding,
                layer,
            });
        }
        out
    }
}

/// The head's way from where the printer's start code leaves it (`from`) to the first
/// sample: straight up to 1 mm above both, across, and down onto it (nothing is printed yet;
/// the start code's own moves are its own).
pub fn approach(from: Option<DVec3>, to: DVec3, travel_mm_s: f64, z_mm_s: f64) -> String {
    let f_xy = fmt_num(travel_mm_s * 60.0, 1);
    let f_z = fmt_num(z_mm_s.min(travel_mm_s) * 60.0, 1);
    let (x, y, z) = (fmt_num(to.x, 3), fmt_num(to.y, 3), fmt_num(to.z, 3));
    let safe = from.map_or(to.z, |f| f.z.max(to.z)) + 1.0;
    format!(
        ";TIMEBASED_APPROACH from the start code's last position to the first sample\n\
         G90\nG0 Z{} F{f_z}\nG0 X{x} Y{y} F{f_xy}\nG0 Z{z} F{f_z}\n",
        fmt_num(safe, 3)
    )
}

/// A line of the source kept in the time-based file (a state change, a layer marker) with
/// the time it takes effect.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedLine {
    /// Time, s from the start of the source job.
    pub t_s: f64,
    /// The text (one line or more, without the final line break).
    pub text: String,
}

/// The lines the time-based file carries besides its samples: every state line of the
/// design's window, and a `;LAYER_CHANGE` / `;Z:` marker (the height the layer prints at)
/// where each of the source's layers starts, in the source's order.
pub fn timed_lines(traj: &Trajectory, w: &Window) -> Vec<TimedLine> {
    let heights = PrintHeights::of(&traj.segments);
    let mut out: Vec<(u32, TimedLine)> = w
        .state
        .iter()
        .map(|s| {
            (
                s.line,
                TimedLine {
                    t_s: s.t_s,
                    text: s.text.clone(),
                },
            )
        })
        .collect();
    // Each layer's first printing move: where its marker goes (after the rise, travel or
    // wait that lead to it, so the samples up to there are the layer below's).
    let mut first_print: Vec<Option<f64>> = vec![None; traj.layers.len() + 1];
    for seg in traj.segments.iter().filter(|s| s.kind == MoveKind::Print) {
        if let Some(t @ None) = first_print.get_mut(seg.layer as usize) {
            *t = Some(seg.t_start_s);
        }
    }
    // Marks of a prelude (what prints before the first layer, as the firmware counts it) are
    // no layers: the time-based file has no marker for them either.
    let prelude = prelude_marks(&traj.layers);
    for (k, m) in traj.layers.iter().enumerate().skip(prelude) {
        if m.source == LayerSource::End || m.line < w.lines.0 || m.line > w.lines.1 {
            continue;
        }
        // Segment layer k + 1 starts at mark k.
        let z = heights.get(k as u32 + 1).or(m.z_mm);
        let t_s = first_print[k + 1]
            .unwrap_or_else(|| w.time_of_line(m.line))
            .clamp(w.t0_s, w.t1_s);
        let text = match z {
            Some(z) => format!(";LAYER_CHANGE\n;Z:{}", fmt_num(z, 3)),
            None => ";LAYER_CHANGE".to_string(),
        };
        out.push((m.line, TimedLine { t_s, text }));
    }
    out.sort_by(|a, b| a.1.t_s.total_cmp(&b.1.t_s).then(a.0.cmp(&b.0)));
    out.into_iter().map(|(_, l)| l).collect()
}

/// Writes samples as time-based G-code (see the module docs for the format): sample `k` is
/// the head at `t0_s + k × period_s`, and each of `lines` (sorted by time) goes before the
/// first sample at or after its time.
pub fn write_timebased(
    samples: &[Sample],
    period_s: f64,
    source: &str,
    t0_s: f64,
    lines: &[TimedLine],
) -> String {
    let mut out = String::with_capacity(samples.len() * 40 + 512);
    let period_ms = period_s * 1000.0;
    let _ = writeln!(
        out,
        "{HEADER_TAG} period_ms={} samples={} source={}",
        fmt_num(period_ms, 3),
        samples.len(),
        source.replace(['\n', '\r'], " ")
    );
    out.push_str(";FORMAT line k (k = 0..N-1) of the motion lines below is the head position at t = k*period;\n");
    out.push_str(";FORMAT G1 moves reach it in one period (F = distance / period), G4 P<period> = head still\n");
    out.push_str(BEGIN_TAG);
    out.push_str("\nG90\nM82\nG92 E0\n");
    let mut prev: Option<Sample> = None;
    let mut last_f = f64::NAN;
    let mut next_line = lines.iter().peekable();
    for (k, s) in samples.iter().enumerate() {
        // The source's lines that take effect before this sample's time, in their order.
        let t_k = t0_s + k as f64 * period_s;
        while let Some(l) = next_line.next_if(|l| l.t_s <= t_k + 1e-9) {
            out.push_str(&l.text);
            out.push('\n');
        }
        let Some(p) = prev else {
            let _ = writeln!(
                out,
                "G1 X{} Y{} Z{} E{} F{}",
                fmt_num(s.pos.x, 3),
                fmt_num(s.pos.y, 3),
                fmt_num(s.pos.z, 3),
                fmt_num(s.e_mm, 5),
                fmt_num(6000.0, 1)
            );
            last_f = 6000.0;
            prev = Some(*s);
            continue;
        };
        let d = s.pos - p.pos;
        let de = s.e_mm - p.e_mm;
        let (x, y, z, e) = (
            round_to(s.pos.x, 3) != round_to(p.pos.x, 3),
            round_to(s.pos.y, 3) != round_to(p.pos.y, 3),
            round_to(s.pos.z, 3) != round_to(p.pos.z, 3),
            round_to(s.e_mm, 5) != round_to(p.e_mm, 5),
        );
        if !(x || y || z || e) {
            let _ = writeln!(out, "G4 P{}", fmt_num(period_ms, 3));
            prev = Some(*s);
            continue;
        }
        let dist = if x || y || z { d.length() } else { de.abs() };
        let f = round_to(dist / period_s * 60.0, 1).max(0.1);
        out.push_str("G1");
        for (on, axis, v, dec) in [
            (x, 'X', s.pos.x, 3),
            (y, 'Y', s.pos.y, 3),
            (z, 'Z', s.pos.z, 3),
            (e, 'E', s.e_mm, 5),
        ] {
            if on {
                let _ = write!(out, " {axis}{}", fmt_num(v, dec));
            }
        }
        if f != last_f {
            let _ = write!(out, " F{}", fmt_num(f, 1));
            last_f = f;
        }
        out.push('\n');
        prev = Some(*s);
    }
    for l in next_line {
        out.push_str(&l.text);
        out.push('\n');
    }
    out.push_str(END_TAG);
    out.push('\n');
    out
}

/// Puts a printer's `start` code (homing, heating) before the samples of a time-based file and
/// its `end` code after them: the file then runs as a whole job, and the samples keep their
/// indices (only the lines between the begin and end tags are samples).
pub fn with_start_end(timebased: &str, start: &str, end: &str) -> String {
    let mut out = String::with_capacity(timebased.len() + start.len() + end.len() + 2);
    let (head, body) = match timebased.find(BEGIN_TAG) {
        Some(i) => timebased.split_at(i),
        None => ("", timebased),
    };
    out.push_str(head);
    out.push_str(start);
    if !start.is_empty() && !start.ends_with('\n') {
        out.push('\n');
    }
    out.push_str(body);
    out.push_str(end);
    if !end.is_empty() && !end.ends_with('\n') {
        out.push('\n');
    }
    out
}

/// The sample section of a time-based file: between the begin and end tags when present.
fn sample_section(text: &[u8]) -> &[u8] {
    let find = |hay: &[u8], tag: &str| hay.windows(tag.len()).position(|w| w == tag.as_bytes());
    let Some(b) = find(text, BEGIN_TAG) else {
        return text;
    };
    let body = &text[b..];
    match find(body, END_TAG) {
        Some(e) => &body[..e],
        None => body,
    }
}

fn round_to(v: f64, dec: i32) -> f64 {
    let s = 10f64.powi(dec);
    (v * s).round() / s
}

/// `v` with at most `dec` decimals, trailing zeros trimmed.
fn fmt_num(v: f64, dec: usize) -> String {
    let s = format!("{v:.dec$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// True when `text` starts with the time-based header.
pub fn is_timebased(text: &[u8]) -> bool {
    text.starts_with(HEADER_TAG.as_bytes())
}

/// Period declared in a time-based header, s.
pub fn header_period_s(text: &[u8]) -> Option<f64> {
    let line = text.split(|&b| b == b'\n').next()?;
    let line = std::str::from_utf8(line).ok()?;
    let v = line
        .split_whitespace()
        .find_map(|w| w.strip_prefix("period_ms="))?;
    let ms: f64 = v.parse().ok()?;
    (ms.is_finite() && ms > 0.0).then_some(ms / 1000.0)
}

/// Sample count declared in a time-based header.
pub fn header_samples(text: &[u8]) -> Option<usize> {
    let line = text.split(|&b| b == b'\n').next()?;
    let line = std::str::from_utf8(line).ok()?;
    line.split_whitespace()
        .find_map(|w| w.strip_prefix("samples="))?
        .parse()
        .ok()
}

/// Reads a time-based file back into samples with the tools' G-code reader: every motion
/// event (G1 or G4) after the header is one sample.
pub fn read_timebased(text: &[u8]) -> anyhow::Result<(f64, Vec<Sample>)> {
    let period = header_period_s(text).ok_or_else(|| {
        anyhow::anyhow!("not a time-based file: missing `{HEADER_TAG} period_ms=`")
    })?;
    let mut samples = Vec::new();
    let mut layer = 0u32;
    let mut last = Sample {
        pos: DVec3::ZERO,
        e_mm: 0.0,
        extruding: false,
        layer: 0,
    };
    let declared = header_samples(text);
    let mut first_from: Option<DVec3> = None;
    let mut reader = default_reader();
    reader
        .read(sample_section(text), &mut |ev| match ev {
            Event::Move { from, to, .. } => {
                if first_from.is_none() {
                    first_from = Some(DVec3::new(from[0], from[1], from[2]));
                }
                let moved = (0..3).any(|k| (to[k] - from[k]).abs() > 1e-9);
                last = Sample {
                    pos: DVec3::new(to[0], to[1], to[2]),
                    e_mm: to[3],
                    // The first sample is where the job starts: nothing deposited yet.
                    extruding: !samples.is_empty() && moved && to[3] > from[3] + 1e-9,
                    layer,
                };
                samples.push(last);
            }
            Event::Dwell(_) => {
                last.extruding = false;
                last.layer = layer;
                samples.push(last);
            }
            Event::Layer { .. } => layer += 1,
            _ => {}
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // A first sample at the reader's start position is a zero-length move that the reader
    // does not report: put it back so indices stay times.
    if declared == Some(samples.len() + 1) {
        samples.insert(
            0,
            Sample {
                pos: first_from.unwrap_or(DVec3::ZERO),
                e_mm: 0.0,
                extruding: false,
                layer: 0,
            },
        );
        if let Some(s) = samples.get_mut(1) {
            s.extruding = false;
        }
    }
    if let Some(n) = declared {
        if n != samples.len() {
            anyhow::bail!(
                "time-based file declares {n} samples but holds {}: edited or truncated?",
                samples.len()
            );
        }
    }
    Ok((period, samples))
}
