//! Operations on the rest of a job at a paused layer boundary (SPEC §1): continue with a
//! re-sliced file, insert a template at the current top, skip or replace layers, change filament.
//!
//! Every operation takes `at`, the index of the first layer not yet sent to the printer: layers
//! `..at` are printed (or in the printer's queue) and never touched. Wherever code from another
//! source is spliced in, the modal state the next code expects is restored explicitly (E mode,
//! `G92 E`, feed rate), so absolute-E files continue without a blob or a long retract.

use super::modal::{fmt_mm, Modal, E, X, Y, Z};
use super::{gcode, Job, JobError, Layer};

/// Heights closer than this are the same plane, mm.
pub const Z_TOL_MM: f64 = 0.005;

/// Lowest flow factor a Z-matching correction applies (a thinner remainder is printed at this
/// flow rather than as a near-empty layer).
pub const MIN_FLOW: f64 = 0.5;
/// Highest flow factor a Z-matching correction applies.
pub const MAX_FLOW: f64 = 2.0;

/// Host-side prompt line: the sender does not send it; it waits for the user (resume key or
/// `--resume-after`). OctoPrint spells host commands with a leading `@` the same way.
pub const PROMPT_PREFIX: &str = "@pause";

/// The printed top at a boundary: the highest layer height among layers `..at`, mm (0 before
/// the first layer).
pub fn top_at(job: &Job, at: usize) -> f64 {
    job.layers
        .iter()
        .take(at)
        .filter_map(Layer::top_mm)
        .fold(0.0, f64::max)
}

fn check_at(job: &Job, at: usize) -> Result<(), JobError> {
    if at > job.layers.len() {
        return Err(JobError::Op(format!(
            "boundary {at} is past the last layer ({} layers)",
            job.layers.len()
        )));
    }
    Ok(())
}

/// What [`continue_with`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct SwapReport {
    /// Printed top at the boundary, mm.
    pub top_mm: f64,
    /// Index in the new job of the first layer used.
    pub first_new_layer: usize,
    /// Layers of the new job skipped because the print already covers them.
    pub skipped_covered: usize,
    /// Height of the first new layer above the printed top divided by its sliced height: 1.0
    /// when the planes line up; other values are applied as a flow override (M221) on that layer
    /// to fill exactly the missing height.
    pub flow_factor: f64,
    /// Layers appended from the new job.
    pub layers_added: usize,
}

/// Continues the job from boundary `at` with a re-sliced file: layers of `new` that the print
/// already covers are skipped (Z ≤ top), and when the first remaining layer's plane does not
/// line up with the printed top, its extrusion is scaled to the missing height (a layer thinner
/// than half its sliced height is merged into the next one, which then fills the missing height
/// with more flow), within [`MIN_FLOW`]..=[`MAX_FLOW`]. The end code becomes `new`'s end code.
pub fn continue_with(job: &mut Job, at: usize, new: &Job) -> Result<SwapReport, JobError> {
    check_at(job, at)?;
    let top = top_at(job, at);
    let heights: Vec<Option<f64>> = new.layers.iter().map(Layer::top_mm).collect();
    let mut k = heights
        .iter()
        .position(|z| matches!(z, Some(z) if *z > top + Z_TOL_MM))
        .ok_or_else(|| {
            JobError::Op(format!(
                "the new file has no layer above the printed top Z {}",
                fmt_mm(top)
            ))
        })?;
    let height_of = |k: usize| -> (f64, f64) {
        let z = heights.get(k).copied().flatten().unwrap_or(top);
        let below = heights
            .iter()
            .take(k)
            .filter_map(|z| *z)
            .fold(0.0, f64::max);
        (z, (z - below).max(1e-6))
    };
    let (z, h) = height_of(k);
    if z - top < 0.5 * h - Z_TOL_MM && k + 1 < new.layers.len() {
        k += 1;
    }
    let (z, h) = height_of(k);
    let mut flow = ((z - top) / h).clamp(MIN_FLOW, MAX_FLOW);
    if (flow - 1.0).abs() < 0.02 {
        flow = 1.0;
    }
    let skipped = k;
    let range_len = new.layers.len() - k;
    replace_layers(job, at, job.layers.len() - at, new, k, range_len)?;
    if flow != 1.0 {
        set_layer_flow(job, at, flow);
    }
    job.end = new.end.clone();
    Ok(SwapReport {
        top_mm: top,
        first_new_layer: k,
        skipped_covered: skipped,
        flow_factor: flow,
        layers_added: range_len,
    })
}

/// Wraps layer `i` in a flow override `M221 S<pct>` … `M221 S100`.
fn set_layer_flow(job: &mut Job, i: usize, factor: f64) {
    if let Some(l) = job.layers.get_mut(i) {
        let pct = (factor * 100.0).round().clamp(10.0, 999.0);
        l.lines
            .insert(0, format!("M221 S{pct} ; fill the missing height"));
        l.lines.push("M221 S100".to_string());
    }
}

/// Replaces layers `at..at+count` of `job` with layers `from..from+n` of `src`. The modal state
/// `src` has at `from` is set up before them, and the state `job` had at `at+count` is restored
/// after them, so both files keep their own E positions and modes.
pub fn replace_layers(
    job: &mut Job,
    at: usize,
    count: usize,
    src: &Job,
    from: usize,
    n: usize,
) -> Result<(), JobError> {
    check_at(job, at)?;
    if at + count > job.layers.len() || from + n > src.layers.len() {
        return Err(JobError::Op(format!(
            "layer range out of bounds: replace {at}..{} of {} with {from}..{} of {}",
            at + count,
            job.layers.len(),
            from + n,
            src.layers.len()
        )));
    }
    let after = job.modal_at(at + count);
    let mut inserted: Vec<Layer> = src.layers[from..from + n].to_vec();
    if let Some(first) = inserted.first_mut() {
        let restore = src.modal_at(from).restore_lines();
        first.lines.splice(0..0, restore);
    }
    let tail_exists = at + count < job.layers.len();
    job.layers.splice(at..at + count, inserted);
    if tail_exists {
        if let Some(next) = job.layers.get_mut(at + n) {
            next.lines.splice(0..0, after.restore_lines());
        }
    } else {
        // Restore before the end code, which was written for `job`'s state.
        let mut end = after.restore_lines();
        end.append(&mut job.end);
        job.end = end;
    }
    Ok(())
}

/// What [`skip_layers`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct SkipReport {
    /// Height left unprinted by the skipped layers, mm.
    pub gap_mm: f64,
    /// Flow factor applied to the next layer to fill the gap (1.0 without compensation).
    pub flow_factor: f64,
}

/// Skips layers `at..at+count` (e.g. to make a rough surface). With `compensate`, the next layer
/// is printed with extra flow for the skipped height (SPEC §1), capped at `max_flow`.
pub fn skip_layers(
    job: &mut Job,
    at: usize,
    count: usize,
    compensate: bool,
    max_flow: f64,
) -> Result<SkipReport, JobError> {
    check_at(job, at)?;
    if count == 0 || at + count > job.layers.len() {
        return Err(JobError::Op(format!(
            "cannot skip {count} layers from {at}: the job has {} layers",
            job.layers.len()
        )));
    }
    let top = top_at(job, at);
    let after = job.modal_at(at + count);
    let next_z = job.layers.get(at + count).and_then(Layer::top_mm);
    let prev_z = job
        .layers
        .get(at + count - 1)
        .and_then(Layer::top_mm)
        .unwrap_or(top);
    job.layers.drain(at..at + count);
    let mut flow = 1.0;
    let gap = (prev_z - top).max(0.0);
    if let Some(l) = job.layers.get_mut(at) {
        l.lines.splice(0..0, after.restore_lines());
        if let Some(z) = next_z {
            let h = (z - prev_z).max(1e-6);
            if compensate {
                flow = ((z - top) / h).min(max_flow);
            }
        }
    } else {
        let mut end = after.restore_lines();
        end.append(&mut job.end);
        job.end = end;
    }
    if flow != 1.0 {
        set_layer_flow(job, at, flow);
    }
    Ok(SkipReport {
        gap_mm: gap,
        flow_factor: flow,
    })
}

/// Values a template may use: `{x}`, `{y}`, `{z}` (last commanded position at the boundary),
/// `{top}` (printed top), `{e}` (logical E), each optionally with an offset: `{top+1.5}`,
/// `{x-10}`. Unknown names are left as written (and then fail to parse).
pub fn expand_template(template: &str, m: &Modal, top: f64) -> Vec<String> {
    template.lines().map(|l| expand_line(l, m, top)).collect()
}

fn expand_line(line: &str, m: &Modal, top: f64) -> String {
    let mut out = String::new();
    let mut rest = line;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let Some(close) = after.find('}') else {
            out.push_str(&rest[open..]);
            return out;
        };
        let inner = &after[..close];
        let split = inner.find(['+', '-']).unwrap_or(inner.len());
        let (name, off) = inner.split_at(split);
        let base = match name.trim() {
            "x" => Some(m.pos_mm[X]),
            "y" => Some(m.pos_mm[Y]),
            "z" => Some(m.pos_mm[Z]),
            "e" => Some(m.pos_mm[E]),
            "top" => Some(top),
            _ => None,
        };
        let offset = if off.is_empty() {
            Some(0.0)
        } else {
            off.replace(' ', "").parse::<f64>().ok()
        };
        match (base, offset) {
            (Some(b), Some(o)) => out.push_str(&fmt_mm(b + o)),
            _ => {
                out.push('{');
                out.push_str(inner);
                out.push('}');
            }
        }
        rest = &after[close + 1..];
    }
    out.push_str(rest);
    out
}

/// Inserts G-code at the current top, before layer `at`: the template's placeholders are
/// expanded, then the head returns to the boundary position (XY above, then Z) and the modal
/// state of the boundary is restored. Every template line must parse with the firmware's parser.
pub fn insert_template(
    job: &mut Job,
    at: usize,
    template: &str,
    safe_z_lift_mm: f64,
) -> Result<usize, JobError> {
    check_at(job, at)?;
    let m = job.modal_at(at);
    let top = top_at(job, at);
    let mut lines = expand_template(template, &m, top);
    for (i, l) in lines.iter().enumerate() {
        if l.trim_start().starts_with(PROMPT_PREFIX) {
            continue;
        }
        gcode::parse(l).map_err(|e| JobError::Op(format!("template line {}: {}", i + 1, e.0)))?;
    }
    let n = lines.len();
    lines.extend(return_lines(&m, top + safe_z_lift_mm));
    lines.extend(m.restore_lines());
    match job.layers.get_mut(at) {
        Some(l) => {
            l.lines.splice(0..0, lines);
        }
        None => {
            lines.append(&mut job.end);
            job.end = lines;
        }
    }
    Ok(n)
}

/// Travel back to the boundary position: up to `safe_z`, XY, then down to Z.
fn return_lines(m: &Modal, safe_z: f64) -> Vec<String> {
    vec![
        "G90".into(),
        format!("G0 Z{} F600", fmt_mm(safe_z.max(m.pos_mm[Z]))),
        format!("G0 X{} Y{} F3600", fmt_mm(m.pos_mm[X]), fmt_mm(m.pos_mm[Y])),
        format!("G0 Z{} F600", fmt_mm(m.pos_mm[Z])),
    ]
}

/// A purge-and-wipe template: lift 2 mm above the top, go to `(x, y)`, extrude `purge_mm`
/// slowly, wipe 20 mm along X, retract 1 mm. Relative E inside; the insert restores the job's E
/// afterwards.
pub fn purge_template(x: f64, y: f64, purge_mm: f64) -> String {
    format!(
        "G90\nG0 Z{{top+2}} F600\nG0 X{} Y{} F3600\nM83\nG1 E{} F120\nG1 X{} E1 F1200\nG1 E-1 F2400\n",
        fmt_mm(x),
        fmt_mm(y),
        fmt_mm(purge_mm),
        fmt_mm(x + 20.0)
    )
}

/// A "hair" template (SPEC §1): short strands pulled outward along the wall normal from points
/// on the outline of the last printed layer. The outline is the farthest extruded point from the
/// layer's centroid in each of `strands` angular sectors; the normal is approximated by the
/// direction from the centroid. Each strand: a dot of `dot_mm` filament on the top, then a slow
/// move `len_mm` outward rising `len_mm/2` with little extrusion, then lift.
pub fn hair_template(
    job: &Job,
    at: usize,
    strands: usize,
    len_mm: f64,
    dot_mm: f64,
) -> Result<String, JobError> {
    check_at(job, at)?;
    let layer = at
        .checked_sub(1)
        .and_then(|i| job.layers.get(i))
        .ok_or_else(|| JobError::Op("no printed layer to grow hair on".into()))?;
    let mut m = job.modal_at(at - 1);
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for l in &layer.lines {
        if let Ok(Some(c)) = gcode::parse(l) {
            if let Some(mv) = m.apply(&c) {
                if mv.extrudes() {
                    pts.push((mv.to_mm[X], mv.to_mm[Y]));
                }
            }
        }
    }
    if pts.is_empty() || strands == 0 {
        return Err(JobError::Op(
            "the last printed layer has no extrusion".into(),
        ));
    }
    let n = pts.len() as f64;
    let cx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let cy = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let mut best: Vec<Option<(f64, f64, f64)>> = vec![None; strands];
    for &(x, y) in &pts {
        let (dx, dy) = (x - cx, y - cy);
        let r = (dx * dx + dy * dy).sqrt();
        let a = dy.atan2(dx) + std::f64::consts::PI;
        let s = ((a / std::f64::consts::TAU) * strands as f64) as usize % strands;
        if best[s].is_none_or(|b| r > b.2) {
            best[s] = Some((x, y, r));
        }
    }
    let mut t = String::from("G90\nM83\n");
    for (x, y, r) in best.into_iter().flatten() {
        if r < 1e-6 {
            continue;
        }
        let (nx, ny) = ((x - cx) / r, (y - cy) / r);
        t.push_str(&format!(
            "G0 Z{{top+1}} F600\nG0 X{} Y{} F3600\nG0 Z{{top}} F600\nG1 E{} F300\nG1 X{} Y{} Z{{top+h}} E{} F300\nG0 Z{{top+1}} F600\n",
            fmt_mm(x),
            fmt_mm(y),
            fmt_mm(dot_mm),
            fmt_mm(x + nx * len_mm),
            fmt_mm(y + ny * len_mm),
            fmt_mm(dot_mm * 0.2),
        ));
    }
    Ok(t.replace("{top+h}", &format!("{{top+{}}}", fmt_mm(len_mm / 2.0))))
}

/// Filament change parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct FilamentChange {
    /// Retract before travelling, mm.
    pub retract_mm: f64,
    /// Lift above the printed top, mm.
    pub lift_mm: f64,
    /// Park position, mm.
    pub park_xy_mm: (f64, f64),
    /// Filament pulled out of the hot end, mm.
    pub unload_mm: f64,
    /// Filament pushed in after the swap, mm.
    pub load_mm: f64,
    /// Filament purged after loading, mm.
    pub purge_mm: f64,
    /// Message shown while waiting for the user.
    pub prompt: String,
}

impl Default for FilamentChange {
    fn default() -> Self {
        FilamentChange {
            retract_mm: 2.0,
            lift_mm: 5.0,
            park_xy_mm: (235.0, 235.0),
            unload_mm: 80.0,
            load_mm: 70.0,
            purge_mm: 30.0,
            prompt: "swap the filament, then resume".into(),
        }
    }
}

/// Inserts a filament change before layer `at`: retract, lift, park, unload, a host prompt,
/// load, purge, retract, return (XY then Z), un-retract and restore the modal state.
pub fn filament_change(job: &mut Job, at: usize, fc: &FilamentChange) -> Result<(), JobError> {
    check_at(job, at)?;
    let m = job.modal_at(at);
    let top = top_at(job, at);
    let mut lines = vec![
        "M83".to_string(),
        format!("G1 E-{} F2400", fmt_mm(fc.retract_mm)),
        "G90".into(),
        format!("G0 Z{} F600", fmt_mm(top.max(m.pos_mm[Z]) + fc.lift_mm)),
        format!(
            "G0 X{} Y{} F3600",
            fmt_mm(fc.park_xy_mm.0),
            fmt_mm(fc.park_xy_mm.1)
        ),
        format!("G1 E-{} F1500", fmt_mm(fc.unload_mm)),
        format!("{PROMPT_PREFIX} {}", fc.prompt),
        format!("G1 E{} F300", fmt_mm(fc.load_mm)),
        format!("G1 E{} F150", fmt_mm(fc.purge_mm)),
        format!("G1 E-{} F2400", fmt_mm(fc.retract_mm)),
    ];
    lines.extend(return_lines(&m, top.max(m.pos_mm[Z]) + fc.lift_mm));
    lines.push("M83".into());
    lines.push(format!("G1 E{} F2400", fmt_mm(fc.retract_mm)));
    lines.extend(m.restore_lines());
    match job.layers.get_mut(at) {
        Some(l) => {
            l.lines.splice(0..0, lines);
        }
        None => {
            lines.append(&mut job.end);
            job.end = lines;
        }
    }
    Ok(())
}
