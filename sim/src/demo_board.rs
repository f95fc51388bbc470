//! The demo's second part: the same layer pause, requested mid-layer, on the flashed image on
//! the emulated SKR 2 (`board-emu`, which `scripts/demo.sh` runs between the two calls here)
//! beside the simulator's run of the same job. The job is the demo part at 10 mm (a ninth of
//! the 30 mm part's printing time: the emulated board runs near real time, the simulator
//! thousands of times faster).
//!
//! 1. [`prepare`] (`sim demo`): writes the job and when to request the pause — seconds after
//!    the job's first step, the same moment the simulator requests it (halfway through the
//!    middle infill line of layer 1).
//! 2. `board-emu --job … --pause-request-after S --json …` prints it on the emulated board.
//! 3. [`compare`] (`sim demo --compare-board REPORT`): both timelines side by side (each from
//!    its job's first step), both stop points, and a picture of layer 1 with them.

use crate::exec::PrinterFactory;
use crate::job::JobInfo;
use crate::patterns::demo_part_sized;
use crate::plot::{self, Marker};
use crate::recorder::Scale;
use crate::run::{self, Mode, Outcome, PauseWhen, Policy, Scenario};
use anyhow::Context;
use std::path::Path;

/// The job's file in the output directory.
pub const JOB_FILE: &str = "board-demo.gcode";
/// When to request the pause, s after the job's first step (one number).
pub const REQUEST_FILE: &str = "board-demo.request-s";
/// Side of the square, mm.
const SIDE_MM: f64 = 10.0;

/// The part, with `M302 P1` first: it models motion only (no heating lines), as the main
/// demo's runs allow cold extrusion.
fn job() -> Vec<String> {
    let mut j = vec!["M302 P1".to_string()];
    j.extend(demo_part_sized(3, SIDE_MM));
    j
}

/// The simulator's run: the firmware's layer pause requested halfway through the middle
/// infill line of layer 1, resumed 1 s after the park (as `board-emu` does).
fn sim_run(job: &[String]) -> anyhow::Result<Outcome<crate::exec::PrinterExec>> {
    let info = JobInfo::parse(job);
    let l1 = info
        .layer_starts
        .iter()
        .find(|(l, _)| *l == 1)
        .map(|(_, i)| *i)
        .context("the part has no layer 1")?;
    let extruding: Vec<usize> = (l1..job.len())
        .filter(|&i| info.lines[i].extrudes && info.lines[i].layer == Some(1))
        .collect();
    let line = *extruding
        .get(extruding.len() / 2)
        .context("layer 1 has no extrusion")?;
    let mut sc = Scenario::new(Policy::Firmware, Mode::Layer);
    sc.pause = Some(PauseWhen::DuringLine {
        line,
        fraction: 0.5,
    });
    sc.resume_after_us = Some(1_000_000);
    sc.allow_cold = true;
    run::run(&PrinterFactory, &sc, job)
}

fn first_step_s(o: &Outcome<crate::exec::PrinterExec>) -> f64 {
    o.run
        .rec
        .records
        .first()
        .map_or(0.0, |r| r.t_start_us as f64 * 1e-6)
}

/// Writes the job and the request's moment for the emulated board.
pub fn prepare(out: &Path) -> anyhow::Result<()> {
    let job = job();
    let o = sim_run(&job)?;
    let req = o
        .report
        .request_s
        .context("the simulator requested no pause")?;
    std::fs::write(out.join(JOB_FILE), job.join("\n") + "\n")?;
    std::fs::write(
        out.join(REQUEST_FILE),
        format!("{:.4}\n", req - first_step_s(&o)),
    )?;
    Ok(())
}

fn num(v: &serde_json::Value) -> Option<f64> {
    v.as_f64()
}

fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "—".into(), |x| format!("{x:8.3} s"))
}

/// Both runs side by side, and `board-demo.svg`.
pub fn compare(out: &Path, board_report: &Path) -> anyhow::Result<()> {
    let job = job();
    let o = sim_run(&job)?;
    let text = std::fs::read_to_string(board_report)
        .with_context(|| format!("reading {}", board_report.display()))?;
    let b: serde_json::Value = serde_json::from_str(&text).context("the board's report")?;
    let t0_sim = first_step_s(&o);
    let t0_board = num(&b["first_job_step_s"]).context("the board started no job")?;
    let line_time = |text: &str| -> Option<f64> {
        let lines = b["lines"].as_array()?;
        let times = b["line_times_s"].as_array()?;
        lines
            .iter()
            .position(|l| l.as_str() == Some(text))
            .and_then(|i| num(&times[i]))
    };
    let r = &o.report;
    let sim_rows = [
        ("pause requested (M601)", r.request_s),
        (
            "the head stops, the park begins",
            r.request_s.zip(r.stop_s).map(|(a, b)| a + b),
        ),
        ("parked", r.parked_s),
        ("printing again", r.resumed_s),
    ];
    let board_rows = [
        num(&b["pause_requested_s"]),
        num(&b["park_began_s"]),
        line_time("//action:paused"),
        line_time("//action:resumed"),
    ];
    println!();
    println!(
        "The same pause on the flashed image, on the emulated SKR 2 (a {SIDE_MM} mm part, 3 layers):"
    );
    println!("  seconds after the job's first step     simulator   emulated board");
    for ((what, s), bt) in sim_rows.iter().zip(board_rows) {
        println!(
            "  {what:<36} {}   {}",
            fmt(s.map(|t| t - t0_sim)),
            fmt(bt.map(|t| t - t0_board))
        );
    }
    let scale = Scale::from_config(&firmware::config::MachineConfig::ENDER3);
    let sim_stop = r.pause_point_steps.map(|p| scale.mm(&p));
    let board_stop: Option<[f64; 4]> = b["pause_point_net_steps"].as_array().map(|a| {
        let s: [i32; 4] =
            core::array::from_fn(|i| a.get(i).and_then(|v| v.as_i64()).unwrap_or(0) as i32);
        scale.mm(&s)
    });
    let show = |p: Option<[f64; 4]>| {
        p.map_or("—".into(), |m| {
            format!("X {:.2} Y {:.2} Z {:.2} mm", m[0], m[1], m[2])
        })
    };
    println!("  stopped at   simulator:      {}", show(sim_stop));
    println!("               emulated board: {}", show(board_stop));
    println!(
        "  emulated: {:.1} virtual s in {:.1} s wall; the step interrupt {:.2} % of the time",
        num(&b["virtual_s"]).unwrap_or(0.0),
        num(&b["wall_s"]).unwrap_or(0.0),
        100.0 * num(&b["step_irq_load"]).unwrap_or(0.0)
    );

    // The picture: layer 1 with the request and both stop points.
    let info = JobInfo::parse(&job);
    let mut printing = Vec::new();
    let mut travel = Vec::new();
    for li in info
        .lines
        .iter()
        .filter(|l| l.layer == Some(1) && l.is_move)
    {
        let seg = vec![
            (li.start_mm[0], li.start_mm[1]),
            (li.after.pos_mm[0], li.after.pos_mm[1]),
        ];
        if li.extrudes {
            printing.push(seg);
        } else {
            travel.push(seg);
        }
    }
    let mut markers = Vec::new();
    if let Some(xy) = crate::demo::request_xy(&o, &scale) {
        markers.push(Marker {
            label: "pause requested here (M601)".into(),
            xy,
        });
    }
    if let Some(m) = sim_stop {
        markers.push(Marker {
            label: format!("simulator: stopped {:.3} s after", r.stop_s.unwrap_or(0.0)),
            xy: (m[0], m[1]),
        });
    }
    if let Some(m) = board_stop {
        let after = num(&b["park_began_s"])
            .zip(num(&b["pause_requested_s"]))
            .map_or(0.0, |(a, q)| a - q);
        markers.push(Marker {
            label: format!("emulated board, flashed image: {after:.3} s after"),
            xy: (m[0], m[1]),
        });
    }
    let svg = out.join("board-demo.svg");
    plot::toolpath_plot(
        &svg,
        "Layer 1 of the 10 mm part: the simulator's and the emulated board's stop",
        &printing,
        &travel,
        &markers,
    )?;
    println!("  wrote {}", svg.display());
    Ok(())
}
