//! `sim demo`: the built-in demo part printed with a pause requested mid-layer, under every
//! policy; prints the timeline of our firmware's pause and the comparison, and draws the layer
//! with the point where each policy stopped.

use crate::exec::PrinterFactory;
use crate::metrics::PauseReport;
use crate::patterns::demo_part;
use crate::plot::{self, Marker};
use crate::recorder::Scale;
use crate::run::{self, Mode, PauseWhen, Policy, Scenario};
use std::fmt::Write as _;
use std::path::Path;

fn opt(v: Option<f64>, unit: &str) -> String {
    v.map_or_else(|| "—".into(), |x| format!("{x:.3} {unit}"))
}

/// A human summary of one report.
pub fn summary(r: &PauseReport) -> String {
    let mut s = String::new();
    if r.request_s.is_some() || r.stop_layer.is_some() {
        let _ = writeln!(s, "  reaction:            {}", opt(r.reaction_s, "s"));
        let _ = writeln!(s, "  stop:                {}", opt(r.stop_s, "s"));
        let _ = writeln!(
            s,
            "  travel after request: {}",
            opt(r.travel_after_request_mm, "mm")
        );
        let _ = writeln!(
            s,
            "  extrusion after req.: {}",
            opt(r.extrusion_after_request_mm, "mm")
        );
        let _ = writeln!(
            s,
            "  stopped:             {} layer {}",
            if r.stopped_at_layer_boundary {
                "at the end of"
            } else {
                "inside"
            },
            r.stop_layer.map_or("—".into(), |l| l.to_string())
        );
        let _ = writeln!(
            s,
            "  first boundary after the request: {}",
            if r.first_boundary_after_request {
                "yes"
            } else {
                "no"
            }
        );
        let _ = writeln!(
            s,
            "  resume position error: {} steps",
            r.resume_position_error_steps
                .map_or("—".into(), |e| e.to_string())
        );
        let _ = writeln!(
            s,
            "  lost / duplicated moves: {} / {}",
            r.lost_moves, r.duplicated_moves
        );
    }
    let _ = writeln!(
        s,
        "  print time:          {:.1} s ({:.1} s without the pause){}",
        r.print_time_s,
        r.print_time_unpaused_s,
        r.segmentation_cost_s
            .map_or(String::new(), |c| format!(", segmentation cost {c:+.2} s"))
    );
    let _ = write!(
        s,
        "  simulated in {:.2} s wall ({:.0}× real time)",
        r.sim_wall_s, r.realtime_factor
    );
    s
}

/// Where the head was at the pause request, mm, from the reference run's records.
pub(crate) fn request_xy<E: crate::port::Executive>(
    o: &run::Outcome<E>,
    scale: &Scale,
) -> Option<(f64, f64)> {
    let t_us = (o.report.request_s? * 1e6) as u64;
    let r = o
        .reference
        .rec
        .records
        .iter()
        .rev()
        .find(|r| r.t_start_us <= t_us)?;
    let mm = scale.mm(&r.end);
    let st = scale.mm(&r.start);
    let f = if r.t_end_us > r.t_start_us {
        (t_us - r.t_start_us) as f64 / (r.t_end_us - r.t_start_us) as f64
    } else {
        1.0
    }
    .clamp(0.0, 1.0);
    Some((st[0] + (mm[0] - st[0]) * f, st[1] + (mm[1] - st[1]) * f))
}

/// Run the demo, print the timeline and comparison, write `demo.svg` and `demo.json` to `out`.
pub fn run_demo(out: &Path) -> anyhow::Result<()> {
    let job = demo_part(3);
    let info = crate::job::JobInfo::parse(&job);
    // The request: halfway through the 12th infill line of layer 1.
    let l1 = info
        .layer_starts
        .iter()
        .find(|(l, _)| *l == 1)
        .map(|(_, i)| *i)
        .ok_or_else(|| anyhow::anyhow!("demo part has no layer 1"))?;
    let line = (l1..job.len())
        .filter(|&i| info.lines[i].extrudes)
        .nth(8 + 12)
        .ok_or_else(|| anyhow::anyhow!("demo part layer 1 too short"))?;
    let when = PauseWhen::DuringLine {
        line,
        fraction: 0.5,
    };
    let cases = [
        (Policy::Firmware, Mode::Layer),
        (Policy::Firmware, Mode::Now),
        (Policy::Fifo, Mode::Layer),
        (Policy::HostSplit, Mode::Layer),
    ];
    std::fs::create_dir_all(out)?;
    let pb = indicatif::ProgressBar::new(cases.len() as u64);
    let mut reports = Vec::new();
    let mut markers = Vec::new();
    let mut first_timeline = Vec::new();
    let mut req_xy = None;
    let scale = Scale::from_config(&firmware::config::MachineConfig::ENDER3);
    for (i, (p, m)) in cases.iter().enumerate() {
        let mut sc = Scenario::new(*p, *m);
        sc.pause = Some(when);
        sc.resume_after_us = Some(5_000_000);
        sc.measure_segmentation_cost = *p == Policy::Firmware && *m == Mode::Layer;
        // The built-in part models motion only (no heating lines): as M302 P1 allows.
        sc.allow_cold = true;
        let o = run::run(&PrinterFactory, &sc, &job)?;
        if i == 0 {
            first_timeline = o.timeline.clone();
            req_xy = request_xy(&o, &scale);
        }
        if let Some(pp) = o.report.pause_point_steps {
            let mm = scale.mm(&pp);
            markers.push(Marker {
                label: format!(
                    "{} / {}: stopped after {}",
                    p.name(),
                    m.name(),
                    opt(o.report.stop_s, "s")
                ),
                xy: (mm[0], mm[1]),
            });
        }
        reports.push(o.report);
        pb.inc(1);
    }
    pb.finish_and_clear();

    println!("sim demo: a 30 × 30 mm square, 3 layers; pause requested mid-layer 1");
    println!();
    println!("Our firmware, layer mode — timeline:");
    for ev in &first_timeline {
        println!("  {:>9.3} s  {}", ev.t_s, ev.what);
    }
    println!();
    println!(
        "{:<22} {:>10} {:>10} {:>10} {:>14} {:>8} {:>6}",
        "policy / mode", "reaction", "stop", "travel", "stopped", "resume", "lost"
    );
    for r in &reports {
        println!(
            "{:<22} {:>10} {:>10} {:>10} {:>14} {:>8} {:>6}",
            format!("{} / {}", r.policy, r.mode),
            opt(r.reaction_s, "s"),
            opt(r.stop_s, "s"),
            opt(r.travel_after_request_mm, "mm"),
            match (r.stopped_at_layer_boundary, r.stop_layer) {
                (true, Some(l)) => format!("end of L{l}"),
                (false, Some(l)) => format!("inside L{l}"),
                _ => "—".into(),
            },
            r.resume_position_error_steps
                .map_or("—".into(), |e| format!("{e} st")),
            r.lost_moves + r.duplicated_moves,
        );
    }

    // The picture: layer 1's toolpath from the job, the request point and the stop points.
    let mut printing = Vec::new();
    let mut travel = Vec::new();
    for (i, li) in info.lines.iter().enumerate() {
        if li.layer != Some(1) || !li.is_move {
            continue;
        }
        let seg = vec![
            (li.start_mm[0], li.start_mm[1]),
            (li.after.pos_mm[0], li.after.pos_mm[1]),
        ];
        if info.lines[i].extrudes {
            printing.push(seg);
        } else {
            travel.push(seg);
        }
    }
    if let Some(xy) = req_xy {
        markers.insert(
            0,
            Marker {
                label: "pause requested here".into(),
                xy,
            },
        );
    }
    let svg = out.join("demo.svg");
    plot::toolpath_plot(
        &svg,
        "Layer 1 of the demo part: where each policy stopped",
        &printing,
        &travel,
        &markers,
    )?;
    std::fs::write(
        out.join("demo.json"),
        serde_json::to_string_pretty(&reports)?,
    )?;
    println!();
    println!(
        "wrote {} and {}",
        svg.display(),
        out.join("demo.json").display()
    );
    Ok(())
}
