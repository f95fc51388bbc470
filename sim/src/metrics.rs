//! Pause figures from the executed record of a run (A) and its reference without the pause (B).
//!
//! Definitions (all times are virtual, from the moment the host wrote the request):
//! - **reaction**: the first step that differs from the reference in time, axis or direction
//!   (a speed-up makes steps come earlier, braking later). Found in lock-step, see
//!   [`crate::run`].
//! - **pause point**: where the last job block before the first service block (retract, lift,
//!   park — the firmware's own, or the host's pause sequence for host-split) ended.
//! - **stop time**: request → the last step of that job block (the head is at rest at the pause
//!   point from then on).
//! - **travel / extrusion after the request**: XYZ path length (sum of straight block pieces)
//!   and E advance from the position at the request to the pause point.
//! - **layer boundary**: the stop is at a boundary when every extruding move up to the pause
//!   point is complete and no extruding move of a later layer has begun (travel, Z moves and
//!   retracts between layers may have run). The stop layer is the layer of the last completed
//!   extruding move. "First boundary after the request": the stop layer is the layer of the
//!   first extruding move not finished at the request (or the request's own layer when that
//!   was already complete).
//! - **resume position error**: the largest per-axis difference (steps, X Y Z E) between the
//!   pause point and where the first job block after the resume starts.
//! - **lost / duplicated**: the executed job blocks of A against those of B, as multisets of
//!   (job line, segment); a segment interrupted by the pause and finished after it counts once.

use crate::engine::Engine;
use crate::job::JobInfo;
use crate::port::Executive;
use crate::recorder::{Scale, SegRecord};
use crate::scenario::{Mode, PauseWhen, Scenario};
use crate::stream::{Comparison, Key, LineEnds, HOMING_LINE};
use firmware::motion::StepPos;
use layerref::{Comments, Model};

/// Margin of the first-reachable-boundary judgement beyond the braking distance, mm: the
/// segment executing at the request (≤ 0.2 mm), the speed estimate (the average over that
/// block) and the speed-up a `layer` request starts (as `tests/tests/layer_corpus.rs`).
pub const REACH_MARGIN_MM: f64 = 2.0;

/// What the run loop observed, for [`compute`].
#[derive(Clone, Debug, Default)]
pub struct RunFacts {
    /// When the request was written, µs.
    pub t_req_us: Option<u64>,
    /// Position at the request, steps.
    pub pos_at_req: StepPos,
    /// Number of records when the request was made.
    pub records_before_req: usize,
    /// Reaction time (first differing step), µs.
    pub reaction_us: Option<u64>,
    /// Parked (last parking step), µs.
    pub t_parked_us: Option<u64>,
    /// Resume requested, µs.
    pub t_resume_us: Option<u64>,
    /// Run A reached the end of the job.
    pub finished: bool,
    /// Run B reached the end of the job.
    pub reference_finished: bool,
    /// Wall-clock seconds spent.
    pub wall_s: f64,
}

/// The figures for one pause (the JSON of `sim run --json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PauseReport {
    /// Policy name.
    pub policy: String,
    /// Mode name.
    pub mode: String,
    /// When the request was made, s (`None` for a pause scheduled before the job).
    pub request_s: Option<f64>,
    /// Request → first change of motion, s.
    pub reaction_s: Option<f64>,
    /// Request → head at rest at the pause point, s.
    pub stop_s: Option<f64>,
    /// XYZ travel from the request to the pause point, mm.
    pub travel_after_request_mm: Option<f64>,
    /// Filament fed from the request to the pause point, mm.
    pub extrusion_after_request_mm: Option<f64>,
    /// The stop was at a layer boundary.
    pub stopped_at_layer_boundary: bool,
    /// Layer of the last completed extruding move at the stop.
    pub stop_layer: Option<u32>,
    /// Layer whose end is the first boundary after the request.
    pub request_layer: Option<u32>,
    /// Stopped at the first boundary after the request (or at the scheduled layer).
    pub first_boundary_after_request: bool,
    /// `layer` pauses: stopped at the *first reachable* boundary — the first one not passed
    /// at the request whose end (the end of its layer's last extruding move) lies farther
    /// along the path than the braking distance `v²/2a` + [`REACH_MARGIN_MM`] from the
    /// request (`v`: the speed of the block executing then, `a`: the X axis's acceleration);
    /// boundaries nearer than that may be passed. Judged from the executed path and the
    /// job's layers, not from the planner. `None` for `now` pauses and runs without a pause.
    pub first_reachable_boundary: Option<bool>,
    /// Pause point position, steps (X Y Z E).
    pub pause_point_steps: Option<StepPos>,
    /// Largest per-axis difference between the pause point and the resume start, steps.
    pub resume_position_error_steps: Option<i64>,
    /// Job moves (lines) with a segment never executed, a move whose extrusion the firmware
    /// dropped (a cold nozzle at the planner), and — `sim run` — every job line the printer
    /// refused (`refused_job_lines`).
    pub lost_moves: usize,
    /// `sim run`: job lines the printer answered with `echo:refused: …` (the host's own
    /// count, from the answers it read): each is lost from the job (issue 27). `sim run` also
    /// fails for them unless `--allow-refused`, and lists them under `refused_lines`.
    pub refused_job_lines: usize,
    /// Job moves (lines) with a segment executed more than once.
    pub duplicated_moves: usize,
    /// Segments never executed.
    pub lost_segments: usize,
    /// Segments executed more than once.
    pub duplicated_segments: usize,
    /// The executed job segments equal the reference's, in order.
    pub executed_in_order: bool,
    /// Parked (last parking step), s.
    pub parked_s: Option<f64>,
    /// First job step after the resume, s.
    pub resumed_s: Option<f64>,
    /// Time at the pause point, s (from stop to resumed).
    pub paused_s: Option<f64>,
    /// Whole run, first byte to last step, including the pause, s.
    pub print_time_s: f64,
    /// The same job without a pause, s.
    pub print_time_unpaused_s: f64,
    /// Print time with this segmentation minus without segmentation (same firmware), s.
    pub segmentation_cost_s: Option<f64>,
    /// The run reached the end of the job.
    pub finished: bool,
    /// Steps executed.
    pub steps: u64,
    /// Wall-clock time the simulation took (both runs), s.
    pub sim_wall_s: f64,
    /// Simulated seconds (both runs) per wall-clock second.
    pub realtime_factor: f64,
}

pub(crate) fn max_abs_diff(a: &StepPos, b: &StepPos) -> i64 {
    a.iter()
        .zip(b.iter())
        .map(|(x, y)| (i64::from(*x) - i64::from(*y)).abs())
        .max()
        .unwrap_or(0)
}

/// What of runs A and B the pause figures read: A's records from the request to the resume
/// (its whole record when records are kept), their keys, where lines end in B, and the
/// comparison of the executed blocks ([`crate::stream`]).
#[derive(Clone, Debug, Default)]
pub struct RunView {
    /// A's records (from the request on; all of them when the run kept them).
    pub records: Vec<SegRecord>,
    /// Their job blocks.
    pub keys: Vec<Option<Key>>,
    /// Where job lines end in B (the lines around the pause).
    pub b_line_ends: LineEnds,
    /// A's executed job blocks against B's.
    pub comparison: Comparison,
}

/// Compute the report of run `a` against reference `b`; `view` holds what was kept of the
/// records (indices in `facts` count from `view.records[0]`).
pub fn compute<E: Executive>(
    sc: &Scenario,
    _info: &JobInfo,
    a: &Engine<E>,
    b: &Engine<E>,
    facts: &RunFacts,
    view: &RunView,
) -> PauseReport {
    let scale = Scale::from_config(&sc.machine);
    let ka = &view.keys;
    let ra = &view.records;
    let mut rep = PauseReport {
        policy: sc.policy.name().into(),
        mode: sc.mode.name().into(),
        request_s: facts.t_req_us.map(|t| t as f64 * 1e-6),
        reaction_s: facts
            .reaction_us
            .zip(facts.t_req_us)
            .map(|(r, t)| r.saturating_sub(t) as f64 * 1e-6),
        parked_s: facts.t_parked_us.map(|t| t as f64 * 1e-6),
        print_time_s: a.rec.last_step_us as f64 * 1e-6,
        print_time_unpaused_s: b.rec.last_step_us as f64 * 1e-6,
        finished: facts.finished,
        steps: a.rec.steps,
        sim_wall_s: facts.wall_s,
        ..PauseReport::default()
    };
    let simulated = if std::ptr::eq(a, b) {
        a.now_us as f64 * 1e-6
    } else {
        (a.now_us + b.now_us) as f64 * 1e-6
    };
    rep.realtime_factor = if facts.wall_s > 0.0 {
        simulated / facts.wall_s
    } else {
        0.0
    };

    // Lost and duplicated, by (line, segment) multisets.
    let c = &view.comparison;
    rep.executed_in_order = c.in_order;
    rep.lost_segments = c.lost_segments;
    rep.duplicated_segments = c.duplicated_segments;
    // A move whose extrusion the firmware dropped ran its X/Y/Z (the comparison sees it): it
    // is lost all the same, and the run is not clean.
    let cold = a.fw.cold_refused();
    rep.lost_moves = c.lost_moves + cold;
    rep.duplicated_moves = c.duplicated_moves;
    if cold > 0 {
        rep.finished = false;
    }

    let complete = |line: usize, pos: &StepPos| view.b_line_ends.get(line).is_none_or(|e| e == pos);
    // The layers of the job as the printer received it, from the independent reference model
    // (`layerref`: no code shared with the firmware's detector). Layers are compared by their
    // index in print order; the report names their numbers (from 1; 0 = a prelude).
    let comments = if sc.link.strip_comments {
        Comments::Strip
    } else {
        Comments::Keep
    };
    // Streamed like the engines' own readers (a job file is never held whole); a job that
    // cannot be read again is judged on the lines read before the error.
    let model = {
        let mut m = Model::stream(comments);
        if let Ok(mut r) = a.host.job().reader() {
            while let Ok(true) = r.next_line() {
                m.feed(r.line());
            }
        }
        m.finish()
    };
    let extrudes = |line: usize| model.extrudes(line);
    let layer_of = |line: usize| model.layer_index(line);
    let number = |k: Option<usize>| k.and_then(|k| model.layers().get(k)).map(|l| l.number);
    let last_extruding_at_or_before = |line: usize| -> Option<usize> {
        (0..=line.min(model.len().saturating_sub(1)))
            .rev()
            .find(|&i| extrudes(i))
    };
    let next_extruding_after = |line: usize| -> Option<usize> {
        (line.saturating_add(1)..model.len()).find(|&i| extrudes(i))
    };

    // The pause point.
    let from = facts.records_before_req.saturating_sub(1);
    let Some(s) = (from..ra.len()).find(|&i| ka[i].is_none()) else {
        return rep;
    };
    // Job lines (a homing move has none of its own: `stream::HOMING_LINE`).
    let line_of = |i: usize| ka[i].map(|k| k.0).filter(|&l| l != HOMING_LINE);
    let j = (0..s).rev().find(|&i| ka[i].is_some());
    let (stop_pos, t_stop, frontier) = match j {
        Some(j) => (ra[j].end, ra[j].t_end_us, (0..=j).rev().find_map(line_of)),
        None => ([0; 4], 0, None),
    };
    rep.pause_point_steps = Some(stop_pos);
    if let Some(t) = facts.t_req_us {
        rep.stop_s = Some(t_stop.saturating_sub(t) as f64 * 1e-6);
        // Motion identical to the reference up to the stop: the stop itself is the first change.
        if let (Some(r), Some(s)) = (rep.reaction_s, rep.stop_s) {
            if r > s {
                rep.reaction_s = Some(s);
            }
        }
        // Travel: the part of the block in progress at the request, then whole blocks.
        let mut travel = 0.0;
        if facts.records_before_req > 0 {
            let k = facts.records_before_req - 1;
            if k < s && ka[k].is_some() {
                travel += scale.xyz_dist_mm(&facts.pos_at_req, &ra[k].end);
            }
        }
        for k in facts.records_before_req..s {
            if ka[k].is_some() {
                travel += scale.xyz_dist_mm(&ra[k].start, &ra[k].end);
            }
        }
        rep.travel_after_request_mm = Some(travel);
        rep.extrusion_after_request_mm = Some(scale.e_mm(&facts.pos_at_req, &stop_pos));
    }

    // Layer at the stop (an index into the model's layers).
    let mut stop_layer: Option<usize> = None;
    if let Some(lf) = frontier {
        let done = complete(lf, &stop_pos);
        if extrudes(lf) && !done {
            stop_layer = layer_of(lf);
            rep.stopped_at_layer_boundary = false;
        } else {
            let last = last_extruding_at_or_before(lf);
            stop_layer = last.and_then(layer_of);
            let next = next_extruding_after(lf);
            rep.stopped_at_layer_boundary = match next {
                None => true,
                Some(n) => layer_of(n) != stop_layer,
            };
        }
    }
    rep.stop_layer = number(stop_layer);

    // The first boundary after the request.
    match sc.pause {
        Some(PauseWhen::AtLayer(n)) => {
            // `M761 L<n>`: the boundary before the first layer numbered n — after the layer
            // before it in print order (a prelude, or nothing when layer n is the first).
            rep.request_layer = n.checked_sub(1);
            let want = model.find(n);
            rep.first_boundary_after_request = rep.stopped_at_layer_boundary
                && want.is_some_and(|w| stop_layer == w.checked_sub(1));
            rep.first_reachable_boundary = Some(rep.first_boundary_after_request);
        }
        _ if facts.t_req_us.is_some() => {
            let k = facts.records_before_req;
            let in_progress = (k.saturating_sub(1)..ra.len())
                .find(|&i| line_of(i).is_some())
                .and_then(|i| line_of(i).map(|l| (i, l)));
            if let Some((i, lr)) = in_progress {
                let done_at_req = i < k && complete(lr, &facts.pos_at_req);
                let first_unfinished = if extrudes(lr) && !done_at_req {
                    Some(lr)
                } else {
                    next_extruding_after(lr)
                };
                let k0 = first_unfinished.and_then(layer_of);
                let prev_done = if done_at_req {
                    last_extruding_at_or_before(lr)
                } else {
                    lr.checked_sub(1).and_then(last_extruding_at_or_before)
                };
                let kprev = prev_done.and_then(layer_of);
                rep.request_layer = number(k0.or(kprev));
                // Requested before the first layer mark (a purge line): its end is the
                // first boundary.
                let prelude = first_unfinished.is_some() && k0.is_none();
                rep.first_boundary_after_request = rep.stopped_at_layer_boundary
                    && match (stop_layer, kprev, k0) {
                        (Some(s), Some(p), Some(k)) => s >= p && s <= k,
                        (Some(s), None, Some(k)) => s <= k,
                        (None, None, None) if prelude => true,
                        (s, _, None) => s.is_some(),
                        (None, _, _) => kprev.is_none(),
                    };
                if sc.mode == Mode::Layer {
                    // Later than the first boundary only past boundaries within braking
                    // distance: the path from the request to each layer's last extrusion.
                    let r = &ra[i];
                    let dt_s = r.t_end_us.saturating_sub(r.t_start_us) as f64 * 1e-6;
                    let v = if dt_s > 0.0 {
                        scale.xyz_dist_mm(&r.start, &r.end) / dt_s
                    } else {
                        0.0
                    };
                    let a = f64::from(sc.machine.axes[0].max_accel_mm_s2);
                    let brake_mm = v * v / (2.0 * a) + REACH_MARGIN_MM;
                    let mut layer_end_mm: Vec<(usize, f64)> = Vec::new();
                    let mut d = 0.0;
                    let upto = j.map_or(0, |j| j + 1);
                    for (idx, key) in ka.iter().enumerate().take(upto).skip(i) {
                        let Some((line, _)) = key else { continue };
                        let from = if idx + 1 == k {
                            facts.pos_at_req
                        } else {
                            ra[idx].start
                        };
                        d += scale.xyz_dist_mm(&from, &ra[idx].end);
                        if let Some(l) = layer_of(*line).filter(|_| extrudes(*line)) {
                            layer_end_mm.retain(|(x, _)| *x != l);
                            layer_end_mm.push((l, d));
                        }
                    }
                    let passed_near = match (stop_layer, k0) {
                        (Some(s), Some(k)) if s > k => layer_end_mm
                            .iter()
                            .filter(|(l, _)| *l >= k && *l < s)
                            .all(|(_, d)| *d <= brake_mm),
                        _ => false,
                    };
                    let above_lower = match (stop_layer, kprev) {
                        (Some(s), Some(p)) => s >= p,
                        _ => true,
                    };
                    rep.first_reachable_boundary = Some(
                        rep.first_boundary_after_request
                            || (rep.stopped_at_layer_boundary && above_lower && passed_near),
                    );
                }
            }
        }
        _ => {}
    }
    // Resume.
    if let Some(r) = (s..ra.len()).find(|&i| ka[i].is_some()) {
        if facts.t_resume_us.is_some() {
            rep.resume_position_error_steps = Some(max_abs_diff(&ra[r].start, &stop_pos));
            rep.resumed_s = Some(ra[r].t_start_us as f64 * 1e-6);
            rep.paused_s = Some((ra[r].t_start_us.saturating_sub(t_stop)) as f64 * 1e-6);
        }
    }
    rep
}
