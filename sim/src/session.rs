//! What a `sim serve` session did as a whole, judged from the executed steps rather than from
//! the firmware's own opinion of them: lines received, moves executed, lost and duplicated
//! (with or without a pause), whether the job was cancelled or finished, and — for each pause —
//! whether the stop was at the first layer boundary after the request, with layers derived from
//! the heights at which the head actually extruded (not from the firmware's layer detector).

use crate::port::Lane;
use crate::recorder::SegRecord;
use std::collections::BTreeMap;

/// The session summary written under `"session"` in `sim serve --record`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SessionReport {
    /// Complete lines received from the host (any kind, numbered or not).
    pub lines_received: u64,
    /// Of those, lines with a line number (`N…`).
    pub numbered_lines_received: u64,
    /// Job moves of which at least one segment ran.
    pub moves_executed: usize,
    /// Job segments executed (a move cut into pieces counts each piece).
    pub segments_executed: usize,
    /// Moves with a segment that never ran, other than those a cancel dropped and the one
    /// still running when the session ended; a move whose extrusion the firmware dropped (a
    /// cold nozzle); and every job line the firmware refused (`refused_job_lines`).
    pub lost_moves: usize,
    /// Numbered lines (a host's job lines) the firmware answered with a refusal, read from
    /// the link's output as the host saw it: each is lost from the job, and the session is
    /// not `finished`.
    pub refused_job_lines: u64,
    /// Moves with a segment that ran more than once.
    pub duplicated_moves: usize,
    /// Segments missing (same exclusions as `lost_moves`).
    pub lost_segments: usize,
    /// Segments run more than once.
    pub duplicated_segments: usize,
    /// Moves left unfinished because a cancel dropped them (not lost: the user asked).
    pub cancelled_moves: usize,
    /// A move was still running when the session ended (its missing segments are not lost).
    pub running_at_end: bool,
    /// The firmware cancelled a job during the session.
    pub cancelled: bool,
    /// The last job ran to its end: the printer is idle, nothing was cancelled after the last
    /// move, no move is missing.
    pub finished: bool,
    /// Layers extruded, counted from the extrusion heights.
    pub layers_extruded: u32,
    /// Pauses recorded (the `pauses` array).
    pub pauses: usize,
    /// First host byte → last step, virtual seconds.
    pub print_time_s: f64,
}

/// Executed job segments `(seq, seg, segs)` in order, with where cancels cut them.
pub struct MoveLog<'a> {
    /// The firmware's executed job segments, in order.
    pub executed: &'a [(u32, u32, u32)],
    /// `executed.len()` at each moment the firmware entered `Cancelled`.
    pub cancel_marks: &'a [usize],
    /// The step generator still had steps to run when the session ended.
    pub moving_at_end: bool,
    /// Job moves whose extrusion the firmware dropped (cold nozzle at the planner), by
    /// sequence number: lost, though their X/Y/Z ran.
    pub cold_refused: &'a [u32],
}

/// Lost / duplicated / cancelled accounting of a [`MoveLog`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MoveCounts {
    /// Moves with at least one segment executed.
    pub moves: usize,
    /// Segments executed.
    pub segments: usize,
    /// Lost moves / segments.
    pub lost: (usize, usize),
    /// Duplicated moves / segments.
    pub duplicated: (usize, usize),
    /// Moves a cancel cut short.
    pub cancelled: usize,
    /// The last move was still running at the end.
    pub running_at_end: bool,
}

impl MoveLog<'_> {
    /// Count. A move with missing segments is *cancelled* when its last executed segment is
    /// the last one before a cancel (the move in flight), *running* when it is the last move executed and the
    /// printer was still moving at the end, and *lost* otherwise.
    pub fn counts(&self) -> MoveCounts {
        // seq → (segs, counts per segment, index of its last executed segment)
        let mut moves: BTreeMap<u32, (u32, BTreeMap<u32, u32>, usize)> = BTreeMap::new();
        for (i, &(seq, seg, segs)) in self.executed.iter().enumerate() {
            let e = moves.entry(seq).or_insert((segs, BTreeMap::new(), i));
            *e.1.entry(seg).or_default() += 1;
            e.2 = i;
        }
        let last_seq = self.executed.last().map(|x| x.0);
        let mut c = MoveCounts {
            moves: moves.len(),
            segments: self.executed.len(),
            ..MoveCounts::default()
        };
        for (seq, (segs, counts, last_i)) in &moves {
            let missing = (0..*segs).filter(|s| !counts.contains_key(s)).count();
            let dups: usize = counts.values().map(|n| n.saturating_sub(1) as usize).sum();
            if dups > 0 {
                c.duplicated.0 += 1;
                c.duplicated.1 += dups;
            }
            if missing == 0 {
                continue;
            }
            if self.cancel_marks.contains(&(last_i + 1)) {
                c.cancelled += 1;
            } else if Some(*seq) == last_seq && self.moving_at_end {
                c.running_at_end = true;
            } else {
                c.lost.0 += 1;
                c.lost.1 += missing;
            }
        }
        let cold: std::collections::BTreeSet<u32> = self.cold_refused.iter().copied().collect();
        c.lost.0 += cold.len();
        c
    }
}

/// An extruding job segment: X or Y moved and E advanced.
fn extrudes(r: &SegRecord) -> bool {
    r.tag.lane == Lane::Job
        && r.end[3] > r.start[3]
        && (r.end[0] != r.start[0] || r.end[1] != r.start[1])
}

/// The layer of every extruding segment, from the heights the head extruded at: a new layer
/// starts when a segment extrudes higher than every extruding segment before it (a Z-hop does
/// not extrude; a lower extrusion — a non-planar or wiping move — stays in the current layer),
/// or back at the height of the session's first extrusion or below (the next print of a
/// session: its layers count on). Returns `(index into records, layer from 0)`.
pub fn extrusion_layers(records: &[SegRecord]) -> Vec<(usize, u32)> {
    let mut out = Vec::new();
    let mut top: Option<i32> = None;
    let mut first: Option<i32> = None;
    let mut layer = 0u32;
    for (i, r) in records.iter().enumerate() {
        if !extrudes(r) {
            continue;
        }
        let z = r.start[2].max(r.end[2]);
        let base = *first.get_or_insert(z);
        match top {
            None => top = Some(z),
            Some(t) if z > t || (z < t && z <= base) => {
                top = Some(z);
                layer += 1;
            }
            _ => {}
        }
        out.push((i, layer));
    }
    out
}

/// Was the stop at `t_stop_us` the first layer boundary after a request at `t_req_us`, judged
/// from the extrusion alone? The target layer is that of the extruding segment running at the
/// request, or, if none was, of the last one finished before it — unless the next one to start
/// is already a higher layer (the request came between layers: the boundary is right there).
/// True when the last extrusion before the stop is of the target layer and the first one after
/// it is of a higher layer. `None` when nothing was extruded after the stop (a job cancelled
/// while paused): whether the layer was complete cannot be seen from the execution.
pub fn first_boundary_after(
    records: &[SegRecord],
    layers: &[(usize, u32)],
    t_req_us: u64,
    t_stop_us: u64,
) -> Option<bool> {
    let before_req = layers
        .iter()
        .rposition(|&(i, _)| records[i].t_end_us <= t_req_us);
    let running = layers
        .iter()
        .position(|&(i, _)| records[i].t_start_us < t_req_us && records[i].t_end_us > t_req_us);
    let target = match (running, before_req) {
        (Some(k), _) => layers[k].1,
        (None, Some(k)) => layers[k].1,
        (None, None) => 0,
    };
    let last_before_stop = layers
        .iter()
        .rposition(|&(i, _)| records[i].t_end_us <= t_stop_us);
    let first_after_stop = layers
        .iter()
        .position(|&(i, _)| records[i].t_start_us > t_stop_us)?;
    let before_layer = last_before_stop.map(|k| layers[k].1);
    let after_layer = layers[first_after_stop].1;
    // Nothing may have extruded across the stop (a segment running through it).
    let straddles = layers
        .iter()
        .any(|&(i, _)| records[i].t_start_us <= t_stop_us && records[i].t_end_us > t_stop_us);
    Some(!straddles && before_layer == Some(target) && after_layer > target)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::port::BlockTag;

    fn seg(t0: u64, t1: u64, z: i32, e0: i32, e1: i32, x1: i32) -> SegRecord {
        SegRecord {
            tag: BlockTag {
                seq: 0,
                segment: 0,
                lane: Lane::Job,
            },
            t_start_us: t0,
            t_end_us: t1,
            start: [100 - x1, 0, z, e0],
            end: [x1, 0, z, e1],
            steps: 1,
        }
    }

    /// Two layers of two extrusions each at z 80 and 160, with a pause between t 25 and 40.
    fn two_layers() -> Vec<SegRecord> {
        vec![
            seg(0, 10, 80, 0, 10, 100),
            seg(10, 20, 80, 10, 20, 0),
            seg(20, 25, 160, 20, 20, 0), // Z move, no extrusion
            seg(40, 50, 160, 20, 30, 100),
            seg(50, 60, 160, 30, 40, 0),
        ]
    }

    #[test]
    fn layers_come_from_the_extrusion_heights() {
        let mut r = two_layers();
        assert_eq!(extrusion_layers(&r), vec![(0, 0), (1, 0), (3, 1), (4, 1)]);
        // A second print in the session starts at the first one's first height: a new layer.
        r.push(seg(70, 80, 80, 40, 50, 100));
        r.push(seg(80, 90, 160, 50, 60, 0));
        assert_eq!(extrusion_layers(&r)[4..], [(5, 2), (6, 3)]);
    }

    #[test]
    fn a_stop_between_the_layers_is_the_first_boundary() {
        let r = two_layers();
        let l = extrusion_layers(&r);
        // Requested during the first extrusion, stopped after the Z move.
        assert_eq!(first_boundary_after(&r, &l, 5, 25), Some(true));
        // Requested between the layers: the boundary is right there.
        assert_eq!(first_boundary_after(&r, &l, 22, 25), Some(true));
    }

    #[test]
    fn a_stop_mid_layer_or_a_layer_late_is_not() {
        let mut r = two_layers();
        // Stop inside layer 0 (between its two extrusions, later extrusion of layer 0 after).
        r[1].t_start_us = 30;
        r[1].t_end_us = 35;
        r[2].t_start_us = 36;
        r[2].t_end_us = 38;
        let l = extrusion_layers(&r);
        assert_eq!(first_boundary_after(&r, &l, 5, 20), Some(false));
        // A request in layer 0 that stops only after layer 1 began is too late.
        let mut r = two_layers();
        r.push(seg(70, 80, 240, 40, 50, 100));
        let l = extrusion_layers(&r);
        assert_eq!(first_boundary_after(&r, &l, 5, 50), Some(false));
        // A segment extruding across the stop time.
        assert_eq!(first_boundary_after(&r, &l, 5, 45), Some(false));
        // Nothing extruded after the stop: cannot be judged.
        assert_eq!(first_boundary_after(&r, &l, 75, 80), None);
    }

    #[test]
    fn a_move_whose_extrusion_was_dropped_is_lost() {
        // Every segment ran (X/Y/Z), but the firmware dropped move 2's E part, twice noted.
        let ex = [(1, 0, 1), (2, 0, 1), (3, 0, 1)];
        let c = MoveLog {
            executed: &ex,
            cancel_marks: &[],
            moving_at_end: false,
            cold_refused: &[2, 2],
        }
        .counts();
        assert_eq!(c.lost, (1, 0));
    }

    #[test]
    fn cancelled_and_running_moves_are_not_lost() {
        // Move 1 complete, move 2 cut by a cancel (mark after its 1st segment), move 3 running.
        let ex = [(1, 0, 1), (2, 0, 3), (3, 0, 2)];
        let c = MoveLog {
            executed: &ex,
            cancel_marks: &[2],
            moving_at_end: true,
            cold_refused: &[],
        }
        .counts();
        assert_eq!(c.moves, 3);
        assert_eq!(c.cancelled, 1);
        assert!(c.running_at_end);
        assert_eq!(c.lost, (0, 0));
        // Without the cancel and with the printer at rest, both are lost.
        let c = MoveLog {
            executed: &ex,
            cancel_marks: &[],
            moving_at_end: false,
            cold_refused: &[],
        }
        .counts();
        assert_eq!(c.lost, (2, 3));
        assert!(!c.running_at_end);
        // A segment run twice is a duplicate.
        let ex = [(1, 0, 2), (1, 1, 2), (1, 1, 2)];
        let c = MoveLog {
            executed: &ex,
            cancel_marks: &[],
            moving_at_end: false,
            cold_refused: &[],
        }
        .counts();
        assert_eq!(c.duplicated, (1, 1));
        assert_eq!(c.lost, (0, 0));
    }
}
