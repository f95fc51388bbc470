//! `sim lab`: the latency experiments as a grid (move length × feed × buffer size × segment
//! length × policy × mode) on the paper's zigzag: lines of equal length L, pause requested
//! halfway through the 3rd line. Every cell is a full [`crate::run::run`] (with its reference
//! run), so every figure comes from the firmware code itself.

use crate::exec::PrinterFactory;
use crate::metrics::PauseReport;
use crate::patterns::Zigzag;
use crate::plot::{self, Series};
use crate::run::{self, Mode, PauseWhen, Policy, Scenario};
use std::fmt::Write as _;
use std::path::Path;

/// The grid.
#[derive(Clone, Debug)]
pub struct Grid {
    /// Line lengths L, mm.
    pub lengths_mm: Vec<f64>,
    /// Print speeds, mm/s.
    pub feeds_mm_s: Vec<f64>,
    /// Queue sizes of the conventional policies (moves).
    pub buffers: Vec<usize>,
    /// Segment lengths of the `firmware` policy, mm.
    pub segments_mm: Vec<f32>,
    /// Policies.
    pub policies: Vec<Policy>,
    /// Modes.
    pub modes: Vec<Mode>,
    /// Host-split piece length, mm.
    pub split_mm: f64,
    /// Lines per layer of the zigzag.
    pub lines_per_layer: usize,
}

impl Default for Grid {
    fn default() -> Self {
        Self {
            lengths_mm: vec![1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0],
            feeds_mm_s: vec![30.0],
            buffers: vec![16],
            segments_mm: vec![0.2],
            policies: vec![Policy::Fifo, Policy::HostSplit, Policy::Firmware],
            modes: vec![Mode::Layer, Mode::Now],
            split_mm: 0.2,
            lines_per_layer: 30,
        }
    }
}

/// One cell of the grid.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// Line length, mm.
    pub len_mm: f64,
    /// Speed, mm/s.
    pub feed_mm_s: f64,
    /// Queue size (conventional policies), moves.
    pub buffer: Option<usize>,
    /// Segment length (firmware policy), mm.
    pub segment_mm: Option<f32>,
    /// The paper's arithmetic for a FIFO of `buffer` moves: buffer × L / v, s.
    pub paper_fifo_s: Option<f64>,
    /// The measured pause.
    pub report: PauseReport,
}

/// One cell: (L mm, v mm/s, buffer, segment mm, policy, mode).
pub type Cell = (f64, f64, Option<usize>, Option<f32>, Policy, Mode);

/// Cells of the grid, skipping combinations a policy ignores (fifo and host-split have no
/// planner segmentation; the firmware policy has no 16-move limit).
pub fn cells(g: &Grid) -> Vec<Cell> {
    let mut out = Vec::new();
    for &l in &g.lengths_mm {
        for &f in &g.feeds_mm_s {
            for &p in &g.policies {
                for &m in &g.modes {
                    match p {
                        Policy::Fifo | Policy::HostSplit => {
                            for &b in &g.buffers {
                                out.push((l, f, Some(b), None, p, m));
                            }
                        }
                        Policy::Firmware => {
                            for &s in &g.segments_mm {
                                out.push((l, f, None, Some(s), p, m));
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

/// Run one cell.
pub fn run_cell(
    g: &Grid,
    len_mm: f64,
    feed_mm_s: f64,
    buffer: Option<usize>,
    segment_mm: Option<f32>,
    policy: Policy,
    mode: Mode,
) -> anyhow::Result<Row> {
    let mut z = Zigzag::paper(len_mm);
    z.feed_mm_s = feed_mm_s;
    z.lines_per_layer = g.lines_per_layer;
    let (lines, idx) = z.gcode();
    let third = idx
        .first()
        .and_then(|l| l.get(2))
        .copied()
        .ok_or_else(|| anyhow::anyhow!("zigzag has fewer than 3 lines"))?;
    let mut sc = Scenario::new(policy, mode);
    sc.pause = Some(PauseWhen::DuringLine {
        line: third,
        fraction: 0.5,
    });
    sc.resume_after_us = Some(1_000_000);
    if let Some(b) = buffer {
        sc.queue_limit = b;
    }
    sc.segment_len_mm = segment_mm;
    sc.split_mm = g.split_mm;
    sc.measure_segmentation_cost = policy == Policy::Firmware;
    // The zigzag models motion only (no heating lines): extrude cold, as M302 P1 allows.
    sc.allow_cold = true;
    let out = run::run(&PrinterFactory, &sc, &lines)?;
    Ok(Row {
        len_mm,
        feed_mm_s,
        buffer,
        segment_mm,
        paper_fifo_s: buffer.map(|b| b as f64 * len_mm / feed_mm_s),
        report: out.report,
    })
}

fn opt(v: Option<f64>, prec: usize) -> String {
    v.map_or_else(|| "-".into(), |x| format!("{x:.prec$}"))
}

/// CSV of the rows.
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "len_mm,feed_mm_s,buffer,segment_mm,policy,mode,request_s,reaction_s,stop_s,\
         paper_fifo_s,travel_after_request_mm,stopped_at_layer_boundary,stop_layer,\
         first_boundary_after_request,resume_position_error_steps,lost_moves,duplicated_moves,\
         print_time_s,print_time_unpaused_s,segmentation_cost_s\n",
    );
    for r in rows {
        let p = &r.report;
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.len_mm,
            r.feed_mm_s,
            r.buffer.map_or(String::new(), |b| b.to_string()),
            r.segment_mm.map_or(String::new(), |b| b.to_string()),
            p.policy,
            p.mode,
            opt(p.request_s, 6),
            opt(p.reaction_s, 6),
            opt(p.stop_s, 6),
            opt(r.paper_fifo_s, 4),
            opt(p.travel_after_request_mm, 4),
            p.stopped_at_layer_boundary,
            p.stop_layer.map_or(String::new(), |l| l.to_string()),
            p.first_boundary_after_request,
            p.resume_position_error_steps
                .map_or(String::new(), |e| e.to_string()),
            p.lost_moves,
            p.duplicated_moves,
            opt(Some(p.print_time_s), 4),
            opt(Some(p.print_time_unpaused_s), 4),
            opt(p.segmentation_cost_s, 4),
        );
    }
    s
}

/// The table printed by `sim lab`.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:>7} {:>5} {:>4} {:>5} {:<10} {:<5} {:>9} {:>9} {:>9} {:>9} {:>5} {:>5} {:>4} {:>4}",
        "L mm",
        "v",
        "buf",
        "seg",
        "policy",
        "mode",
        "react s",
        "stop s",
        "16L/v s",
        "travel",
        "bound",
        "layer",
        "lost",
        "dup"
    );
    for r in rows {
        let p = &r.report;
        let _ = writeln!(
            s,
            "{:>7.1} {:>5.0} {:>4} {:>5} {:<10} {:<5} {:>9} {:>9} {:>9} {:>9} {:>5} {:>5} {:>4} {:>4}",
            r.len_mm,
            r.feed_mm_s,
            r.buffer.map_or("-".into(), |b| b.to_string()),
            r.segment_mm.map_or("-".into(), |b| format!("{b}")),
            p.policy,
            p.mode,
            opt(p.reaction_s, 4),
            opt(p.stop_s, 4),
            opt(r.paper_fifo_s, 3),
            opt(p.travel_after_request_mm, 2),
            if p.stopped_at_layer_boundary { "yes" } else { "no" },
            p.stop_layer.map_or("-".into(), |l| l.to_string()),
            p.lost_moves,
            p.duplicated_moves,
        );
    }
    s
}

/// Checks against the paper and the targets, as text lines (each starting with PASS or MISS).
pub fn verdicts(rows: &[Row]) -> Vec<String> {
    let mut out = Vec::new();
    let find = |pol: &str, mode: &str, l: f64| {
        rows.iter().find(|r| {
            r.report.policy == pol
                && r.report.mode == mode
                && (r.len_mm - l).abs() < 1e-9
                && (r.feed_mm_s - 30.0).abs() < 1e-9
                && r.buffer.is_none_or(|b| b == 16)
        })
    };
    for (l, paper) in [(1.0, 0.5), (100.0, 53.3)] {
        if let Some(r) = find("fifo", "now", l).or_else(|| find("fifo", "layer", l)) {
            if let Some(s) = r.report.stop_s {
                let ok = (s - paper).abs() <= 0.1 * paper;
                out.push(format!(
                    "{} fifo L={l} mm: stop {s:.3} s vs paper ≈{paper} s ({:+.1} %)",
                    if ok { "PASS" } else { "MISS" },
                    (s / paper - 1.0) * 100.0
                ));
            }
        }
    }
    let now_rows: Vec<&Row> = rows
        .iter()
        .filter(|r| r.report.policy == "firmware" && r.report.mode == "now")
        .collect();
    if !now_rows.is_empty() {
        let worst = now_rows
            .iter()
            .filter_map(|r| r.report.stop_s)
            .fold(0.0, f64::max);
        out.push(format!(
            "{} firmware/now: worst stop {worst:.4} s over {} cells (target ≤ 0.1 s)",
            if worst <= 0.1 { "PASS" } else { "MISS" },
            now_rows.len()
        ));
    }
    if let (Some(f), Some(n)) = (find("fifo", "now", 100.0), find("firmware", "now", 100.0)) {
        if let (Some(a), Some(b)) = (f.report.stop_s, n.report.stop_s) {
            let ratio = a / b.max(1e-9);
            out.push(format!(
                "{} L=100 mm: fifo / firmware-now = {ratio:.0}× (target ≥ 500×)",
                if ratio >= 500.0 { "PASS" } else { "MISS" }
            ));
        }
    }
    let layer_rows: Vec<&Row> = rows
        .iter()
        .filter(|r| r.report.policy == "firmware" && r.report.mode == "layer")
        .collect();
    if !layer_rows.is_empty() {
        let bad = layer_rows
            .iter()
            .filter(|r| !r.report.first_boundary_after_request)
            .count();
        out.push(format!(
            "{} firmware/layer: {} of {} cells stopped at the first boundary after the request",
            if bad == 0 { "PASS" } else { "MISS" },
            layer_rows.len() - bad,
            layer_rows.len()
        ));
    }
    let integrity = rows
        .iter()
        .filter(|r| {
            r.report.lost_moves > 0
                || r.report.duplicated_moves > 0
                || r.report.resume_position_error_steps.is_some_and(|e| e != 0)
        })
        .count();
    out.push(format!(
        "{} {} of {} cells resumed with no lost or duplicated move and zero position error",
        if integrity == 0 { "PASS" } else { "MISS" },
        rows.len() - integrity,
        rows.len()
    ));
    out
}

/// Write the CSV and the SVG plot of stop time against move length.
pub fn write_outputs(rows: &[Row], dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("lab.csv"), csv(rows))?;
    type Key = (String, String, Option<usize>, Option<String>, String);
    let mut keys: Vec<Key> = Vec::new();
    for r in rows {
        let k = (
            r.report.policy.clone(),
            r.report.mode.clone(),
            r.buffer,
            r.segment_mm.map(|s| s.to_string()),
            r.feed_mm_s.to_string(),
        );
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    let mut series = Vec::new();
    for k in &keys {
        let mut pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| {
                r.report.policy == k.0
                    && r.report.mode == k.1
                    && r.buffer == k.2
                    && r.segment_mm.map(|s| s.to_string()) == k.3
                    && r.feed_mm_s.to_string() == k.4
            })
            .filter_map(|r| r.report.stop_s.map(|s| (r.len_mm, s)))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut label = format!("{} / {}", k.0, k.1);
        if let Some(b) = k.2 {
            label += &format!(", buffer {b}");
        }
        if let Some(s) = &k.3 {
            label += &format!(", seg {s} mm");
        }
        label += &format!(", {} mm/s", k.4);
        series.push(Series { label, points: pts });
    }
    plot::stop_time_plot(
        &dir.join("lab.svg"),
        "Zigzag: pause sent during the 3rd line — stop time vs line length",
        &series,
    )
}
