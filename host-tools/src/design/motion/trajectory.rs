//! Driving the planner from G-code (read with the firmware's reader), and the whole job as a
//! time-parameterised trajectory that can be queried and sampled.

use super::{MotionLimits, PlanMove, Planner, Segment};
use crate::gcode::read::{default_reader, Event, GcodeReader, LayerSource, Pos4, ReadError};

/// Drives a planner from G-code: reads `input` with the default reader and calls `out` with
/// every segment, `layer` with every layer start (the firmware's layer number, height if known,
/// time). Segments carry the count of layer starts before them ([`Segment::layer`]).
pub fn plan_gcode(
    input: &[u8],
    limits: MotionLimits,
    out: &mut dyn FnMut(Segment),
    layer: &mut dyn FnMut(u32, Option<f64>, f64),
) -> Result<PlanTotals, ReadError> {
    plan_gcode_with(&mut default_reader(), input, limits, out, layer)
}

/// [`plan_gcode`] with a given reader (e.g. one that skips rejected lines).
pub fn plan_gcode_with(
    reader: &mut crate::gcode::read::FirmwareReader,
    input: &[u8],
    limits: MotionLimits,
    out: &mut dyn FnMut(Segment),
    layer: &mut dyn FnMut(u32, Option<f64>, f64),
) -> Result<PlanTotals, ReadError> {
    plan_marks(reader, input, limits, out, &mut |m| {
        layer(m.number, m.z_mm, m.t_s)
    })
}

/// A layer start as the planner meets it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerMark {
    /// The firmware's layer number.
    pub number: u32,
    /// Height, when the mark gives it, mm.
    pub z_mm: Option<f64>,
    /// Time of the mark, s.
    pub t_s: f64,
    /// What made it: a slicer comment, a command, a Z rise, the end of printing, a turn.
    pub source: LayerSource,
    /// Source line (1-based).
    pub line: u32,
}

/// How many of `marks` are a prelude: height-rule marks before the firmware's count starts
/// again at 1 — at the first explicit marker, or (the height rule's own restart) right after
/// a single layer left downwards. A count that starts again after a job's end (a file of
/// several jobs: the last layer was not 1) is a new job, not a prelude.
pub fn prelude_marks(marks: &[LayerMark]) -> usize {
    let mut prelude = 0;
    for k in 1..marks.len() {
        let (before, m) = (&marks[k - 1], &marks[k]);
        if before.source != LayerSource::ZRise {
            break;
        }
        if m.number == 1 && (m.source != LayerSource::ZRise || before.number == 1) {
            prelude = k;
        }
    }
    prelude
}

/// [`plan_gcode_with`] with every layer mark in full.
pub fn plan_marks(
    reader: &mut crate::gcode::read::FirmwareReader,
    input: &[u8],
    limits: MotionLimits,
    out: &mut dyn FnMut(Segment),
    layer: &mut dyn FnMut(LayerMark),
) -> Result<PlanTotals, ReadError> {
    let mut planner = Planner::new(limits);
    let mut cur_layer = 0u32;
    let mut moves = 0u64;
    let mut dwell_s = 0.0;
    let mut explicit_layers = false;
    let counts = reader.read(input, &mut |ev| match ev {
        Event::Move {
            from,
            to,
            feed_mm_s,
            line,
        } => {
            moves += 1;
            planner.push(
                PlanMove {
                    from,
                    to,
                    feed_mm_s,
                    layer: cur_layer,
                    line,
                },
                out,
            );
        }
        Event::Layer {
            z_mm,
            source,
            number,
            line,
        } => {
            cur_layer += 1;
            explicit_layers |= source != LayerSource::ZRise;
            layer(LayerMark {
                number,
                z_mm,
                t_s: planner.time_s(),
                source,
                line,
            });
        }
        Event::Dwell(s) => {
            dwell_s += s;
            planner.dwell(s, out);
        }
        Event::Accel {
            print_mm_s2,
            travel_mm_s2,
        } => planner.set_accel(print_mm_s2, travel_mm_s2),
    })?;
    planner.finish(out);
    Ok(PlanTotals {
        time_s: planner.time_s(),
        moves,
        layer_marks: cur_layer,
        explicit_layers,
        lines: counts.lines,
        skipped: counts.skipped,
        bad_lines: counts.bad,
        dwell_s,
    })
}

/// Totals of one planning run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlanTotals {
    /// Total time including dwells, s.
    pub time_s: f64,
    /// Moves read.
    pub moves: u64,
    /// Layer marks found by the firmware's layer detector (slicer markers, or Z rises in a
    /// file without any).
    pub layer_marks: u32,
    /// At least one mark came from an explicit marker (comment or command), not a Z rise.
    pub explicit_layers: bool,
    /// Lines read.
    pub lines: u64,
    /// Commands skipped as not affecting motion.
    pub skipped: u64,
    /// Lines the firmware would reject, skipped (only with a skipping reader).
    pub bad_lines: u64,
    /// Time spent in dwells, s.
    pub dwell_s: f64,
}

/// A whole job as a time-parameterised trajectory (for the time-based resampler and tests).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    /// Segments in time order (dwells are gaps between them).
    pub segments: Vec<Segment>,
    /// Total time, s.
    pub duration_s: f64,
    /// The layer marks, in time order.
    pub layers: Vec<LayerMark>,
}

impl Trajectory {
    /// Plans a G-code job.
    pub fn from_gcode(input: &[u8], limits: MotionLimits) -> Result<Trajectory, ReadError> {
        let mut segments = Vec::new();
        let mut layers = Vec::new();
        let totals = plan_marks(
            &mut default_reader(),
            input,
            limits,
            &mut |s| segments.push(s),
            &mut |m| layers.push(m),
        )?;
        Ok(Trajectory {
            segments,
            duration_s: totals.time_s,
            layers,
        })
    }

    /// Index of the segment active at `t_s` (the last one starting at or before it).
    pub fn segment_at(&self, t_s: f64) -> Option<usize> {
        if self.segments.is_empty() {
            return None;
        }
        let i = self.segments.partition_point(|s| s.t_start_s <= t_s);
        Some(i.saturating_sub(1))
    }

    /// Position at `t_s` (start before 0, end after the end).
    pub fn position_at(&self, t_s: f64) -> Option<Pos4> {
        let i = self.segment_at(t_s)?;
        self.segments.get(i).map(|s| s.position_at(t_s))
    }

    /// Samples every `period_s` from 0 to the end: (time, position, segment index).
    pub fn sample(&self, period_s: f64) -> impl Iterator<Item = (f64, Pos4, usize)> + '_ {
        let period = if period_s.is_finite() && period_s > 0.0 {
            period_s
        } else {
            0.1
        };
        let n = (self.duration_s / period).floor() as usize + 1;
        let mut idx = 0usize;
        (0..n).filter_map(move |k| {
            let t = k as f64 * period;
            while idx + 1 < self.segments.len() && self.segments[idx + 1].t_start_s <= t {
                idx += 1;
            }
            self.segments.get(idx).map(|s| (t, s.position_at(t), idx))
        })
    }
}
