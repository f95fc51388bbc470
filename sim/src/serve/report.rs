//! Judging the session once it ends: one [`PauseReport`] per pause tracked, plus the pauses a
//! host made by itself (a parked standstill between extruding moves).

use super::track::PauseTrack;
use crate::exec::PrinterExec;
use crate::metrics::{max_abs_diff, PauseReport};
use crate::port::{Executive, Lane, State};
use crate::recorder::{Recorder, Scale};
use crate::run::Scenario;
use crate::session::{extrusion_layers, first_boundary_after, SessionReport};
use firmware::motion::PauseMode;
use firmware::printer::Record;

/// What `sim serve --record` writes: the whole session, and one object per pause.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ServeRecord {
    /// Lines, moves, lost/duplicated, cancelled, finished: with or without a pause.
    pub session: SessionReport,
    /// One object per pause (the fields of `sim run --json`).
    pub pauses: Vec<PauseReport>,
    /// One object per port (USB, and TFT with `--tft`).
    pub ports: Vec<PortReport>,
    /// Where the head was when the session ended (the sim's steps, X Y Z E).
    pub end_position_steps: [i32; 4],
}

/// What one port's host did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PortReport {
    /// `USB` or `TFT`.
    pub port: String,
    /// Complete lines received.
    pub lines_received: u64,
    /// Of those, the numbered ones.
    pub numbered_lines_received: u64,
    /// Lines taken while the printer was parked (job lines a host streams into it, console
    /// lines, temperature polling) whose `ok` was seen: how many waited for it.
    pub parked_host_waits: u64,
    /// The longest such wait, virtual seconds, from when the line was read from the device
    /// to the `ok` answering it (the firmware answers a port's lines in order). A host that
    /// sends one line per `ok` (printcore, OctoPrint) sends a console line it queues at any
    /// moment right after the `ok` of its line in flight (printcore sends its priority lines
    /// first), so this plus twice the host's own reaction (tens of ms; `--host-paced` keeps
    /// it so in virtual time) bounds the console line's delivery. The time a host with
    /// nothing to send stays quiet is not a wait.
    pub parked_host_wait_max_s: f64,
    /// Numbered lines (job lines) answered with a refusal — `echo:refused: …`, `echo:Line too
    /// long …`, or an `Error:` not followed by `Resend:` — as the host read them.
    pub refused_numbered_lines: u64,
}

pub(super) fn reports(
    pauses: &[PauseTrack],
    rec: &Recorder,
    fw: &PrinterExec,
    sc: &Scenario,
    t0_us: u64,
    end_us: u64,
    moves: &crate::session::MoveCounts,
) -> Vec<PauseReport> {
    let scale = Scale::from_config(&sc.machine);
    let layers = extrusion_layers(&rec.records);
    let cancelled_last = fw.notes.iter().rev().find_map(|r| match *r {
        Record::State { state, .. } => Some(state == firmware::printer::State::Cancelled),
        _ => None,
    }) == Some(true);
    // What every record of the session shares.
    let base = PauseReport {
        policy: sc.policy.name().into(),
        lost_moves: moves.lost.0,
        duplicated_moves: moves.duplicated.0,
        lost_segments: moves.lost.1,
        duplicated_segments: moves.duplicated.1,
        executed_in_order: moves.lost.1 == 0 && moves.duplicated.1 == 0,
        print_time_s: end_us.saturating_sub(t0_us) as f64 * 1e-6,
        finished: fw.status().state == State::Idle
            && !cancelled_last
            && !moves.running_at_end
            && moves.lost.0 == 0,
        steps: rec.steps,
        ..PauseReport::default()
    };
    let mut out: Vec<PauseReport> = pauses
        .iter()
        .filter(|p| !p.cancelled)
        .map(|p| {
            let mut r = PauseReport {
                mode: match p.mode {
                    Some(PauseMode::Now) => "now".into(),
                    _ => "layer".into(),
                },
                request_s: Some(p.t_req_us as f64 * 1e-6),
                parked_s: p.parked_us.map(|t| t as f64 * 1e-6),
                ..base.clone()
            };
            if let Some((t_stop, pos, layer, mid)) = p.stopped {
                r.stop_s = Some(t_stop.saturating_sub(p.t_req_us) as f64 * 1e-6);
                r.reaction_s =
                    Some(p.reaction_us.unwrap_or(t_stop).saturating_sub(p.t_req_us) as f64 * 1e-6);
                r.pause_point_steps = Some(pos);
                r.stopped_at_layer_boundary = layer.is_some() && !mid;
                r.stop_layer = layer.and_then(|l| l.checked_sub(1));
                // Judged from the extrusion heights, not from the firmware's layer detector.
                r.first_boundary_after_request =
                    first_boundary_after(&rec.records, &layers, p.t_req_us, t_stop) == Some(true);
                r.extrusion_after_request_mm = Some(scale.e_mm(&p.pos_req, &pos));
                // Travel: block pieces between the request and the stop.
                let mut travel = 0.0;
                let mut at = p.pos_req;
                for s in rec.records.iter().skip(p.rec_idx_req.saturating_sub(1)) {
                    if s.t_start_us > t_stop {
                        break;
                    }
                    if s.tag.lane != Lane::Job {
                        continue;
                    }
                    let from = if s.t_start_us < p.t_req_us {
                        at
                    } else {
                        s.start
                    };
                    travel += scale.xyz_dist_mm(&from, &s.end);
                    at = s.end;
                }
                r.travel_after_request_mm = Some(travel);
                if let Some((t_res, start)) = p.resumed {
                    r.resumed_s = Some(t_res as f64 * 1e-6);
                    r.paused_s = Some(t_res.saturating_sub(t_stop) as f64 * 1e-6);
                    r.resume_position_error_steps = Some(max_abs_diff(&pos, &start));
                }
            }
            r
        })
        .collect();
    out.extend(host_stops(pauses, rec, fw, &base, sc));
    out
}

/// A standstill of at least this long between two extruding moves of a job, with no firmware
/// pause in it, is a pause the host made (the paper's host-side method: it stops sending,
/// parks with ordinary G-code and later returns) — if the head stood parked the way a host
/// parks ([`HOST_LIFT_MIN_MM`], [`HOST_PARK_TOL_MM`]). A standstill where a job move ended is a
/// host too slow for the virtual clock (a loaded machine at `--speed 20`), not a pause.
/// Virtual µs.
pub const HOST_STOP_MIN_US: u64 = 5_000_000;
/// A host pause lifts the head at least this much above the last extrusion (host-tools' host
/// pause lifts 1 mm; slicers' Z-hops on travel are smaller), mm ...
pub const HOST_LIFT_MIN_MM: f64 = 0.9;
/// ... or parks it within this distance of the machine's park corner (the paper's sequence,
/// which does not lift), mm.
pub const HOST_PARK_TOL_MM: f64 = 2.0;

/// Pauses the host made by itself (no realtime request, no firmware pause), found in the
/// executed blocks: the head stood still for [`HOST_STOP_MIN_US`] or more between two
/// extruding moves. Reported with mode `host`: the stop is the end of the last extruding move
/// before the standstill; it was at a layer boundary when the firmware's layer counter differs
/// between that move and the first extruding move after (no layer extruded on both sides); the
/// resume error compares that first move's start with the stop point (all four axes, so an
/// un-retract that does not restore E shows).
fn host_stops(
    pauses: &[PauseTrack],
    rec: &Recorder,
    fw: &PrinterExec,
    base: &PauseReport,
    sc: &Scenario,
) -> Vec<PauseReport> {
    let scale = Scale::from_config(&sc.machine);
    let park = (
        f64::from(sc.machine.pause.park_x_mm),
        f64::from(sc.machine.pause.park_y_mm),
    );
    // The host's park pattern, seen where the head stood still: lifted at least
    // HOST_LIFT_MIN_MM above the last extrusion, or at the machine's park corner. A host that
    // is merely slow (the firmware starved of lines) leaves the head where a job move ended.
    let parked = |last: &[i32; 4], still: &[i32; 4]| {
        let (a, b) = (scale.mm(last), scale.mm(still));
        b[2] - a[2] >= HOST_LIFT_MIN_MM
            || ((b[0] - park.0).abs() <= HOST_PARK_TOL_MM
                && (b[1] - park.1).abs() <= HOST_PARK_TOL_MM)
    };
    let layers: Vec<(u64, u32)> = fw
        .notes
        .iter()
        .filter_map(|r| match *r {
            Record::Layer { layer, t_us } => Some((t_us, layer)),
            _ => None,
        })
        .collect();
    let layer_at = |t_us: u64| -> Option<u32> {
        layers
            .iter()
            .take_while(|(t, _)| *t <= t_us)
            .last()
            .map(|x| x.1)
    };
    let fw_stop_in = |a: u64, b: u64| {
        pauses.iter().any(|p| {
            p.stopped.is_some_and(|(t, ..)| t >= a && t <= b)
                || (p.t_req_us >= a && p.t_req_us <= b)
        })
    };
    let extrudes = |r: &crate::recorder::SegRecord| {
        r.tag.lane == Lane::Job
            && r.end[3] > r.start[3]
            && (r.end[0] != r.start[0] || r.end[1] != r.start[1])
    };
    let mut out = Vec::new();
    let mut last_ext: Option<&crate::recorder::SegRecord> = None;
    let mut longest_gap = (0u64, 0u64); // (length, start) since the last extruding move
    let mut still_at = [0i32; 4]; // where the head stood during that standstill
    let mut prev_end: Option<u64> = None;
    let mut prev_pos = [0i32; 4];
    // Block end positions after the longest standstill since the last extruding move.
    let mut after_gap: Vec<[i32; 4]> = Vec::new();
    for r in &rec.records {
        if let Some(pe) = prev_end {
            let gap = r.t_start_us.saturating_sub(pe);
            if last_ext.is_some() && gap > longest_gap.0 {
                longest_gap = (gap, pe);
                still_at = prev_pos;
                after_gap.clear();
            }
        }
        prev_end = Some(r.t_end_us);
        prev_pos = r.end;
        if !extrudes(r) {
            after_gap.push(r.end);
            continue;
        }
        if let Some(le) = last_ext {
            let (gap, gap_start) = longest_gap;
            if gap >= HOST_STOP_MIN_US
                && parked(&le.end, &still_at)
                && !fw_stop_in(le.t_end_us, r.t_start_us)
            {
                let before = layer_at(le.t_start_us);
                let after = layer_at(r.t_start_us);
                // The host's return: the closest any position after the standstill (up to the
                // start of this extruding move) comes to the stop point.
                let err = after_gap
                    .iter()
                    .chain(std::iter::once(&r.start))
                    .map(|p| max_abs_diff(&le.end, p))
                    .min()
                    .unwrap_or(0);
                out.push(PauseReport {
                    mode: "host".into(),
                    stopped_at_layer_boundary: before != after,
                    first_boundary_after_request: before != after,
                    stop_layer: before,
                    pause_point_steps: Some(le.end),
                    resume_position_error_steps: Some(err),
                    parked_s: Some(gap_start as f64 * 1e-6),
                    resumed_s: Some(r.t_start_us as f64 * 1e-6),
                    paused_s: Some(gap as f64 * 1e-6),
                    ..base.clone()
                });
            }
        }
        last_ext = Some(r);
        longest_gap = (0, 0);
        after_gap.clear();
    }
    out
}

/// What the session saw besides the firmware: for [`session_record`].
pub(super) struct Seen<'a> {
    pub(super) pauses: &'a [PauseTrack],
    pub(super) cancel_marks: &'a [usize],
    /// Lines and numbered lines received, over every port.
    pub(super) lines: (u64, u64),
    /// Numbered lines the firmware refused, over every port (see
    /// [`PortReport::refused_numbered_lines`]).
    pub(super) refused_numbered: u64,
    /// Virtual time of the first host byte.
    pub(super) first_byte_us: Option<u64>,
    /// Real seconds the session ran.
    pub(super) wall_s: f64,
}

/// The whole session judged once it ends: moves lost or duplicated, whether the job
/// finished, and one report per pause.
pub(super) fn session_record(
    fw: &mut PrinterExec,
    rec: &Recorder,
    sc: &Scenario,
    seen: &Seen,
) -> ServeRecord {
    let end_us = rec.last_step_us;
    let t0_us = seen.first_byte_us.unwrap_or(0);
    let moving_at_end = fw.printer.next_step_us().is_some();
    let moves = crate::session::MoveLog {
        executed: &fw.executed,
        cancel_marks: seen.cancel_marks,
        moving_at_end,
        cold_refused: &fw.cold_refused,
    }
    .counts();
    let mut pauses = reports(seen.pauses, rec, fw, sc, t0_us, end_us, &moves);
    // Wall time of the session and virtual time per wall second (≈ `--speed`).
    for r in &mut pauses {
        r.sim_wall_s = seen.wall_s;
        r.realtime_factor = if seen.wall_s > 0.0 {
            end_us as f64 * 1e-6 / seen.wall_s
        } else {
            0.0
        };
    }
    let layers = extrusion_layers(&rec.records);
    let cancelled_last = seen
        .cancel_marks
        .last()
        .is_some_and(|&m| m >= fw.executed.len());
    ServeRecord {
        session: SessionReport {
            lines_received: seen.lines.0,
            numbered_lines_received: seen.lines.1,
            moves_executed: moves.moves,
            segments_executed: moves.segments,
            lost_moves: moves.lost.0 + seen.refused_numbered as usize,
            refused_job_lines: seen.refused_numbered,
            duplicated_moves: moves.duplicated.0,
            lost_segments: moves.lost.1,
            duplicated_segments: moves.duplicated.1,
            cancelled_moves: moves.cancelled,
            running_at_end: moves.running_at_end,
            cancelled: !seen.cancel_marks.is_empty(),
            finished: fw.status().state == State::Idle
                && !cancelled_last
                && !moves.running_at_end
                && moves.lost.0 == 0
                && seen.refused_numbered == 0
                && moves.moves > 0,
            layers_extruded: layers.last().map_or(0, |l| l.1 + 1),
            pauses: pauses.len(),
            print_time_s: end_us.saturating_sub(t0_us) as f64 * 1e-6,
        },
        pauses,
        ports: Vec::new(),
        end_position_steps: rec.pos,
    }
}
