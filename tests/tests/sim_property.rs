//! Property: on real slicer G-code, a `layer` pause requested at any moment stops at the first
//! layer boundary after the request, loses and repeats nothing, and resumes to the step.

use proptest::prelude::*;
use sim::exec::PrinterFactory;
use sim::run::{self, Mode, PauseWhen, Policy, Scenario};

/// The PrusaSlicer fixture cut after its 8th layer (start code, heating and 8 real layers), so
/// each case stays short. Requests fall in the first 85 % of the printing time, so a boundary
/// (and a resume) always follows.
fn job() -> Vec<String> {
    let path = format!(
        "{}/fixtures/slicer/prusaslicer.gcode",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut out = Vec::new();
    let mut layers = 0;
    for l in text.lines() {
        if l.starts_with(";LAYER_CHANGE") {
            layers += 1;
            if layers > 8 {
                break;
            }
        }
        out.push(l.to_string());
    }
    out
}

/// When printing starts and ends in the cut job (after heating), from a run without a pause.
fn printing_window(job: &[String]) -> (f64, f64) {
    static W: std::sync::OnceLock<(f64, f64)> = std::sync::OnceLock::new();
    *W.get_or_init(|| window(job))
}

fn window(job: &[String]) -> (f64, f64) {
    let sc = Scenario::new(Policy::Firmware, Mode::Layer);
    let o = run::run(&PrinterFactory, &sc, job).expect("reference run");
    let recs = &o.reference.rec.records;
    let first_xy = recs
        .iter()
        .find(|r| r.start[0] != r.end[0] || r.start[1] != r.end[1])
        .map_or(0, |r| r.t_start_us);
    (first_xy as f64 * 1e-6, o.report.print_time_unpaused_s)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    #[test]
    fn layer_pause_stops_at_the_first_boundary_after_any_request(frac in 0.0f64..0.85) {
        let job = job();
        let (t0, t1) = printing_window(&job);
        prop_assume!(t1 > t0 + 10.0);
        let at = t0 + (t1 - t0) * frac;
        let mut sc = Scenario::new(Policy::Firmware, Mode::Layer);
        sc.pause = Some(PauseWhen::AtUs((at * 1e6) as u64));
        sc.resume_after_us = Some(500_000);
        let r = run::run(&PrinterFactory, &sc, &job).expect("run").report;
        prop_assert!(r.stopped_at_layer_boundary, "{:#?}", r);
        prop_assert!(r.first_boundary_after_request, "{:#?}", r);
        prop_assert_eq!(r.lost_moves + r.duplicated_moves, 0, "{:#?}", r);
        prop_assert_eq!(r.resume_position_error_steps, Some(0), "{:#?}", r);
        prop_assert!(r.finished, "{:#?}", r);
    }
}
