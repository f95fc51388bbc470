//! The job model on real slicer output and the operations at a paused layer boundary.

use std::path::PathBuf;

use host_tools::job::gcode::parse;
use host_tools::job::modal::{Modal, E, Z};
use host_tools::job::ops::{self, PROMPT_PREFIX};
use host_tools::job::Job;
use proptest::prelude::*;

fn fixture(rel: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("tests/fixtures")
        .join(rel);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn job(rel: &str) -> Job {
    Job::from_gcode(&fixture(rel)).expect("job")
}

/// Walks a job, checking every line parses; returns the largest single E advance of any move
/// and the modal state at the end.
fn walk(job: &Job) -> (f64, Modal) {
    let mut m = Modal::default();
    let mut max_e: f64 = 0.0;
    for (_, l) in job.lines() {
        if l.trim_start().starts_with(PROMPT_PREFIX) {
            continue;
        }
        let c = parse(l).unwrap_or_else(|e| panic!("{l}: {e}"));
        if let Some(mv) = c.and_then(|c| m.apply(&c)) {
            max_e = max_e.max(mv.e_mm());
        }
    }
    (max_e, m)
}

#[test]
fn slicer_files_split_into_start_layers_end_without_losing_a_line() {
    for (rel, layers) in [
        ("slicer/prusaslicer.gcode", 30),
        ("slicer/cura.gcode", 30),
        ("sender/base-infill20.gcode", 30),
        ("sender/swap-h03-infill60.gcode", 20),
    ] {
        let text = fixture(rel);
        let j = Job::from_gcode(&text).expect(rel);
        assert_eq!(j.layers.len(), layers, "{rel}");
        // Every line kept, in order.
        let orig: Vec<&str> = text.lines().collect();
        let back: Vec<&str> = j.lines().map(|(_, l)| l).collect();
        assert_eq!(orig, back, "{rel}");
        assert!(j.start.iter().any(|l| l.starts_with("G28")), "{rel}");
        assert!(j.end.iter().any(|l| l.starts_with("M104 S0")), "{rel}");
        // Layer heights rise.
        let tops: Vec<f64> = j.layers.iter().filter_map(|l| l.top_mm()).collect();
        assert_eq!(tops.len(), layers, "{rel}: every layer extrudes");
        assert!(tops.windows(2).all(|w| w[1] > w[0]), "{rel}: {tops:?}");
        assert!(
            tops[0] > 0.1 && tops[0] < 0.35,
            "{rel}: first layer {}",
            tops[0]
        );
    }
}

#[test]
fn slic3r_file_without_markers_uses_z_rise() {
    let j = job("slicer/slic3r.gcode");
    assert!(j.layers.len() >= 25, "{}", j.layers.len());
    assert!(j
        .layers
        .iter()
        .all(|l| l.source == firmware::motion::LayerSource::ZRise));
}

#[test]
fn swap_with_same_layer_height_continues_at_the_next_layer() {
    let mut j = job("sender/base-infill20.gcode");
    let orig = j.clone();
    let new = job("sender/swap-infill60.gcode");
    let r = ops::continue_with(&mut j, 12, &new).expect("swap");
    assert!((r.top_mm - 2.4).abs() < 1e-3, "{r:?}");
    assert_eq!(r.first_new_layer, 12);
    assert_eq!(r.skipped_covered, 12);
    assert_eq!(r.flow_factor, 1.0);
    assert_eq!(j.layers[..12], orig.layers[..12]);
    assert_eq!(j.layers.len(), 30);
    // The rest is the new file's (after the modal restore lines).
    for i in 12..30 {
        let tail = &j.layers[i].lines[j.layers[i].lines.len() - new.layers[i].lines.len()..];
        assert_eq!(tail, &new.layers[i].lines[..], "layer {i}");
    }
    assert_eq!(j.end, new.end);
    // Absolute E: the new part starts from its own E count (G92), so no move advances E by more
    // than the original files ever do.
    let (max_e, _) = walk(&j);
    let (max_a, _) = walk(&orig);
    let (max_b, _) = walk(&new);
    assert!(
        max_e <= max_a.max(max_b) + 1e-6,
        "{max_e} > {max_a} / {max_b}"
    );
}

#[test]
fn swap_with_other_layer_height_matches_z() {
    let base = job("sender/base-infill20.gcode");
    let new = job("sender/swap-h03-infill60.gcode");
    let tops: Vec<f64> = new.layers.iter().filter_map(|l| l.top_mm()).collect();
    // Planes line up (top 2.0 = 0.2 + 6 × 0.3): continue with the layer at 2.3, full flow.
    let mut j = base.clone();
    let r = ops::continue_with(&mut j, 10, &new).expect("swap");
    assert!((tops[r.first_new_layer] - 2.3).abs() < 1e-3, "{r:?}");
    assert_eq!(r.flow_factor, 1.0);
    // Top 1.8: next plane 2.0 is only 0.2 above → that layer fills 0.2 of its 0.3: flow 2/3.
    let mut j = base.clone();
    let r = ops::continue_with(&mut j, 9, &new).expect("swap");
    assert!((tops[r.first_new_layer] - 2.0).abs() < 1e-3, "{r:?}");
    assert!((r.flow_factor - 2.0 / 3.0).abs() < 0.01, "{r:?}");
    assert!(j.layers[9].lines[0].starts_with("M221 S67"));
    // Top 2.2: the plane at 2.3 is only 0.1 above (< half a layer): skip it, the layer at 2.6
    // fills the missing 0.4 with 4/3 flow (go back to fill the missing height).
    let mut j = base.clone();
    let r = ops::continue_with(&mut j, 11, &new).expect("swap");
    assert!((tops[r.first_new_layer] - 2.6).abs() < 1e-3, "{r:?}");
    assert!((r.flow_factor - 4.0 / 3.0).abs() < 0.01, "{r:?}");
    // Nothing left above the top: a clear error.
    let mut j = base.clone();
    let n = j.layers.len();
    let mut small = new.clone();
    small.layers.truncate(3);
    assert!(ops::continue_with(&mut j, n, &small).is_err());
}

#[test]
fn template_insert_returns_and_restores_the_modal_state() {
    let mut j = job("sender/base-infill20.gcode");
    let orig = j.clone();
    let at = 8;
    let t = ops::purge_template(200.0, 230.0, 10.0);
    let n = ops::insert_template(&mut j, at, &t, 2.0).expect("insert");
    assert!(n > 3);
    assert_eq!(j.layers[..at], orig.layers[..at]);
    // Modal state where the original layer's own lines begin equals the original's.
    let inserted = j.layers[at].lines.len() - orig.layers[at].lines.len();
    let mut probe = j.clone();
    probe.layers[at].lines.truncate(inserted);
    let after = probe.modal_at(at + 1);
    let before = orig.modal_at(at);
    assert!((after.pos_mm[E] - before.pos_mm[E]).abs() < 1e-4);
    assert_eq!(after.abs_e, before.abs_e);
    assert!((after.pos_mm[Z] - before.pos_mm[Z]).abs() < 1e-6);
    assert_eq!(after.feed_mm_min, before.feed_mm_min);
    // Bad template lines are refused and the job is untouched.
    let mut k = orig.clone();
    assert!(ops::insert_template(&mut k, at, "G1 Xnan", 2.0).is_err());
    assert_eq!(k, orig);
}

#[test]
fn hair_grows_outward_from_the_top_outline() {
    let j = job("sender/base-infill20.gcode");
    let t = ops::hair_template(&j, 15, 12, 4.0, 0.05).expect("hair");
    let strands = t.lines().filter(|l| l.contains("Z{top+")).count();
    assert!(strands >= 8, "{t}");
    let mut k = j.clone();
    ops::insert_template(&mut k, 15, &t, 2.0).expect("insert hair");
    walk(&k);
}

#[test]
fn skip_and_filament_change_keep_e_continuous() {
    let orig = job("sender/base-infill20.gcode");
    let mut j = orig.clone();
    let r = ops::skip_layers(&mut j, 10, 2, true, 3.0).expect("skip");
    assert_eq!(j.layers.len(), 28);
    assert!((r.gap_mm - 0.4).abs() < 1e-3, "{r:?}");
    assert!((r.flow_factor - 3.0).abs() < 1e-6, "{r:?}");
    let (max_e, _) = walk(&j);
    let (max_o, _) = walk(&orig);
    assert!(max_e <= max_o + 1e-6);
    assert!(ops::skip_layers(&mut j, 27, 5, true, 3.0).is_err());

    let mut j = orig.clone();
    ops::filament_change(&mut j, 5, &ops::FilamentChange::default()).expect("change");
    let lines = &j.layers[5].lines;
    let prompt = lines
        .iter()
        .position(|l| l.starts_with(PROMPT_PREFIX))
        .expect("prompt");
    assert!(lines[..prompt].iter().any(|l| l == "G1 E-80 F1500"));
    assert!(lines[prompt..].iter().any(|l| l == "G1 E70 F300"));
    let mut probe = j.clone();
    let inserted = j.layers[5].lines.len() - orig.layers[5].lines.len();
    probe.layers[5].lines.truncate(inserted);
    let after = probe.modal_at(6);
    let before = orig.modal_at(5);
    assert!((after.pos_mm[E] - before.pos_mm[E]).abs() < 1e-4);
    assert_eq!(after.abs_e, before.abs_e);
}

fn synthetic(heights: &[f64]) -> String {
    let mut s = String::from("G28\nG90\nM82\nG92 E0\n");
    let mut z = 0.0;
    let mut e = 0.0;
    for h in heights {
        z += h;
        s.push_str(&format!(";LAYER_CHANGE\n;Z:{z:.3}\nG1 Z{z:.3} F600\n"));
        for (x, y) in [(20.0, 10.0), (20.0, 20.0), (10.0, 20.0), (10.0, 10.0)] {
            e += 0.5;
            s.push_str(&format!("G1 X{x} Y{y} E{e:.4} F1800\n"));
        }
    }
    s.push_str("M104 S0\nM84\n");
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Whatever the two files' layer heights and the boundary: the printed prefix is untouched,
    /// every appended layer lies above the printed top and heights keep rising, the flow
    /// correction stays within half a layer either way, and E never jumps.
    #[test]
    fn swap_invariants(
        a in proptest::collection::vec(prop_oneof![Just(0.1), Just(0.15), Just(0.2), Just(0.3)], 3..20),
        b in proptest::collection::vec(prop_oneof![Just(0.1), Just(0.2), Just(0.25), Just(0.3)], 3..30),
        at_frac in 0.0f64..1.0,
    ) {
        let mut j = Job::from_gcode(&synthetic(&a)).expect("a");
        let new = Job::from_gcode(&synthetic(&b)).expect("b");
        prop_assert_eq!(j.layers.len(), a.len());
        let at = ((a.len() as f64) * at_frac) as usize;
        let orig = j.clone();
        let top = ops::top_at(&j, at);
        match ops::continue_with(&mut j, at, &new) {
            Ok(r) => {
                prop_assert_eq!(&j.layers[..at], &orig.layers[..at]);
                let tops: Vec<f64> = j.layers[at..].iter().filter_map(|l| l.top_mm()).collect();
                prop_assert!(tops.iter().all(|z| *z > top + ops::Z_TOL_MM));
                prop_assert!(tops.windows(2).all(|w| w[1] > w[0]));
                prop_assert_eq!(r.skipped_covered + r.layers_added, new.layers.len());
                prop_assert!(r.flow_factor >= ops::MIN_FLOW - 1e-9, "{:?}", r);
                prop_assert!(r.flow_factor <= ops::MAX_FLOW + 1e-9, "{:?}", r);
                let (max_e, _) = walk(&j);
                prop_assert!(max_e <= 0.5 + 1e-6, "E jump {}", max_e);
            }
            Err(_) => {
                // Only when the new file does not reach above the printed top.
                let new_top = new.layers.iter().filter_map(|l| l.top_mm()).fold(0.0, f64::max);
                prop_assert!(new_top <= top + ops::Z_TOL_MM);
                prop_assert_eq!(&j, &orig);
            }
        }
    }
}
