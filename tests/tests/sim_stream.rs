//! `sim run` compares the run with the pause against its reference as they run, letting the
//! records go (memory flat with job length, docs/sim.md); the figures must be exactly those of
//! the comparison over the whole kept records. Checked on PrusaSlicer's fixture for `layer` and
//! `now` pauses at several request times and a scheduled pause, and with the fixture twice (a
//! second G28 streamed after the resume).

use sim::exec::PrinterFactory;
use sim::job::JobLines;
use sim::run::{self, Mode, PauseWhen, Policy, Scenario};

fn fixture(copies: usize) -> JobLines {
    let path = format!(
        "{}/fixtures/slicer/prusaslicer.gcode",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).expect("fixture");
    JobLines::from_text(text.repeat(copies)).expect("job")
}

fn report(job: &JobLines, pause: PauseWhen, mode: Mode, keep: bool) -> String {
    let mut sc = Scenario::new(Policy::Firmware, mode);
    sc.pause = Some(pause);
    sc.resume_after_us = Some(2_000_000);
    sc.keep_records = keep;
    let o = run::run_job(&PrinterFactory, &sc, job.clone()).expect("run");
    if keep {
        assert!(o.run.rec.records.len() > 10_000);
    } else {
        // Streamed: nothing left in the recorders or the sequence map once compared.
        for e in [&o.run, &o.reference] {
            assert!(e.rec.records.is_empty(), "{} records", e.rec.records.len());
            assert!(e.seqs.held() < 64, "{} ranges", e.seqs.held());
        }
    }
    let mut r = o.report.clone();
    r.sim_wall_s = 0.0;
    r.realtime_factor = 0.0;
    assert!(r.finished);
    serde_json::to_string_pretty(&r).expect("json")
}

#[test]
fn streamed_comparison_equals_the_kept_one() {
    let one = fixture(1);
    let two = fixture(2);
    let cases = [
        (&one, PauseWhen::AtUs(40_000_000), Mode::Layer),
        (&one, PauseWhen::AtUs(333_300_000), Mode::Now),
        (&one, PauseWhen::AtLayer(7), Mode::Layer),
        (&two, PauseWhen::AtUs(900_000_000), Mode::Layer),
        // Streamed through the second copy's G28 after the resume (homing blocks carry no job
        // number).
        (&two, PauseWhen::AtUs(100_000_000), Mode::Layer),
    ];
    for (job, pause, mode) in cases {
        let kept = report(job, pause, mode, true);
        let streamed = report(job, pause, mode, false);
        assert_eq!(streamed, kept, "{pause:?} {mode:?}");
        assert!(kept.contains("\"executed_in_order\": true"), "{kept}");
    }
}
