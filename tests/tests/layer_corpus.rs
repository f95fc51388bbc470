//! The layer corpus (tests/fixtures/corpus, made by scripts/make-corpus.sh from Debian's
//! PrusaSlicer 2.5, Slic3r 1.3 and CuraEngine 4.13 in vase, sequential, variable-layer, Z-hop and
//! support modes) against an independent checker: the layer boundaries are derived here from the
//! heights at which the extruding moves print — written from scratch, not calling
//! `firmware::layer` — and the firmware's `layer` pause (the real executive, through
//! `sim::run`) must stop at the first reachable one, in both comment modes (as sliced, and
//! stripped from `;` on as OctoPrint and printcore send), at random (fixed-seed) request times
//! and for `M761 L<n>` schedules.
//!
//! # The checker's boundaries
//! Every extruding move (X or Y moves while E advances) prints at a height: its Z. Between two
//! consecutive extruding moves a (new) layer starts when
//! - the second starts higher than the first ended (a layer change; a Z-hop comes back down);
//! - the second starts lower (sequential printing: the next object's first layer);
//! - in a helix (extruding moves that rise while they print: vase/spiral mode) the second
//!   starts at or above the current turn's base + one layer height `h` (the base is where the
//!   helix or its current turn started; `h` is the last step between flat layers, else the first
//!   layer's height): a turn is a layer;
//! - entering a helix: the first rising extruding move starts a layer (its printed height
//!   differs from the flat layer before it).
//!
//! With comments kept the slicer's own markers (`;LAYER_CHANGE`, `;LAYER:<n>`) are boundaries
//! too (Cura's layer 0 follows its purge line at the same height), and they number the layers:
//! Cura's `n`, PrusaSlicer's markers counted from 0. Without comments the layers are numbered
//! from 0 at the first extruding move.
//!
//! # First reachable boundary
//! A boundary is passed at the request when the first extruding move after it has begun. The
//! stop must be at a boundary not passed, and not beyond the first boundary whose distance along
//! the path (from the request to the end of the layer's last extrusion) exceeds the braking
//! distance `v²/2a` from the speed at the request plus a margin (the executing segment and the
//! step quantisation): boundaries nearer than the braking distance may be taken or left.

use sim::exec::PrinterFactory;
use sim::hostlink::Origin;
use sim::port::Lane;
use sim::run::{self, Mode, PauseWhen, Policy, Scenario};

const FILES: &[&str] = &[
    "prusa-vase.gcode",
    "prusa-sequential.gcode",
    "prusa-zhop.gcode",
    "prusa-support.gcode",
    "slic3r-vase.gcode",
    "slic3r-sequential.gcode",
    "slic3r-zhop-support.gcode",
    "cura-vase.gcode",
    "cura-variable.gcode",
    "cura-support.gcode",
];

/// Height tolerance, mm (slicers write Z with 3 decimals: heights compare exactly).
const TOL_MM: f64 = 0.0005;

fn load(name: &str, comments: bool) -> Vec<String> {
    let path = if name.contains('/') {
        format!("{}/{name}", env!("CARGO_MANIFEST_DIR"))
    } else {
        format!("{}/fixtures/corpus/{name}", env!("CARGO_MANIFEST_DIR"))
    };
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    if comments {
        // Comment text beyond the link's 128-byte line buffer is cut here (PrusaSlicer's
        // settings block): what the link will do itself once it drops comment text as it
        // arrives (issue 14 item 6, another branch). Markers are short and stay whole.
        return text
            .lines()
            .map(|l| l.get(..96).unwrap_or(l).to_string())
            .collect();
    }
    // OctoPrint / printcore: everything from `;` goes, blank lines are not sent.
    text.lines()
        .map(|l| l.split(';').next().unwrap_or("").trim().to_string())
        .filter(|l| !l.is_empty())
        .collect()
}

/// One extruding move as the checker sees it.
#[derive(Clone, Copy, Debug)]
struct Extrusion {
    line: usize,
    /// Layer index (0, 1, ... in boundary order).
    layer: usize,
}

/// The checker's view of a job.
#[derive(Debug, Default)]
struct Layers {
    extrusions: Vec<Extrusion>,
    /// Per layer index: the slicer's number (comment mode; `None` for what prints before the
    /// first marker, e.g. a purge line) or the index (stripped).
    number: Vec<Option<u32>>,
    /// Path length (XYZ, mm) from the start of the job to the end of each line.
    path_end_mm: Vec<f64>,
    /// Layer index of the first extrusion at or after each line (`None` after the last).
    next_layer: Vec<Option<usize>>,
    /// Layer index of the last extrusion at or before each line.
    prev_layer: Vec<Option<usize>>,
}

fn word(text: &str, letter: char) -> Option<f64> {
    text.split_whitespace().find_map(|w| {
        let mut c = w.chars();
        (c.next()?.to_ascii_uppercase() == letter)
            .then(|| c.as_str().parse().ok())
            .flatten()
    })
}

fn analyse(lines: &[String]) -> Layers {
    let mut pos = [0.0f64; 4];
    let (mut abs_xyz, mut abs_e) = (true, true);
    let mut out = Layers::default();
    let mut path = 0.0;
    // Boundary state.
    let mut layer: Option<usize> = None;
    let mut last_end_z: Option<f64> = None;
    let mut flat_z: Option<f64> = None;
    let mut step_h: Option<f64> = None;
    let mut helix_base: Option<f64> = None;
    let mut marker_pending: Option<Option<u32>> = None;
    let mut prusa_markers = 0u32;
    let mut numbers: Vec<Option<u32>> = Vec::new();
    let has_markers = lines.iter().any(|l| {
        l.split_once(';')
            .is_some_and(|(_, c)| c.trim() == "LAYER_CHANGE" || c.trim().starts_with("LAYER:"))
    });
    let mut seen_marker = false;
    for (i, raw) in lines.iter().enumerate() {
        let (code, comment) = match raw.find(';') {
            Some(k) => (&raw[..k], Some(raw[k + 1..].trim())),
            None => (raw.as_str(), None),
        };
        if let Some(c) = comment {
            if c == "LAYER_CHANGE" {
                marker_pending = Some(Some(prusa_markers));
                prusa_markers += 1;
            } else if let Some(n) = c.strip_prefix("LAYER:").and_then(|n| n.parse().ok()) {
                marker_pending = Some(Some(n));
            }
        }
        let code = code.trim();
        let g = word(code, 'G').filter(|_| code.starts_with(['G', 'g']));
        let m = word(code, 'M').filter(|_| code.starts_with(['M', 'm']));
        let before = pos;
        match (g.map(|v| v as i32), m.map(|v| v as i32)) {
            (Some(0 | 1), _) => {
                for (k, l) in ['X', 'Y', 'Z', 'E'].into_iter().enumerate() {
                    if let Some(v) = word(code, l) {
                        let abs = if k == 3 { abs_e } else { abs_xyz };
                        pos[k] = if abs { v } else { pos[k] + v };
                    }
                }
            }
            (Some(90), _) => (abs_xyz, abs_e) = (true, true),
            (Some(91), _) => (abs_xyz, abs_e) = (false, false),
            (Some(92), _) => {
                for (k, l) in ['X', 'Y', 'Z', 'E'].into_iter().enumerate() {
                    if let Some(v) = word(code, l) {
                        pos[k] = v;
                    }
                }
            }
            (Some(28), _) => {
                // G28 homes the named axes (all without names) to 0.
                let axes = ['X', 'Y', 'Z'];
                let none_named = !axes.iter().any(|&a| code[3..].contains(a));
                for (p, a) in pos.iter_mut().zip(axes) {
                    if none_named || code[3..].contains(a) {
                        *p = 0.0;
                    }
                }
            }
            (_, Some(82)) => abs_e = true,
            (_, Some(83)) => abs_e = false,
            _ => {}
        }
        let d: f64 = (0..3)
            .map(|k| (pos[k] - before[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        path += d;
        out.path_end_mm.push(path);
        let xy = (pos[0] - before[0]).abs() > 1e-9 || (pos[1] - before[1]).abs() > 1e-9;
        let extrudes = xy && pos[3] - before[3] > 1e-9;
        if !extrudes {
            continue;
        }
        let (zs, ze) = (before[2], pos[2]);
        let rising = ze > zs + 1e-9;
        let new_layer = match last_end_z {
            None => true,
            Some(pz) => {
                if zs < pz - TOL_MM {
                    // Sequential: the next object.
                    helix_base = None;
                    true
                } else if let Some(base) = helix_base {
                    let h = step_h.unwrap_or(0.1);
                    if !rising && (zs - pz).abs() <= TOL_MM {
                        // A flat move where the helix ended (Cura's closing turn).
                        helix_base = None;
                        false
                    } else if zs >= base + h - TOL_MM {
                        helix_base = Some(zs);
                        true
                    } else {
                        false
                    }
                } else if rising {
                    // Entering a helix.
                    helix_base = Some(zs);
                    true
                } else {
                    zs > pz + TOL_MM
                }
            }
        };
        if new_layer {
            helix_base = rising.then_some(zs);
        }
        let marked = marker_pending.take();
        if new_layer || marked.is_some() {
            if step_h.is_none() {
                step_h = Some(zs.max(0.1));
            }
            if !rising && helix_base.is_none() {
                if let Some(f) = flat_z {
                    if zs > f + TOL_MM {
                        step_h = Some(zs - f);
                    }
                }
                flat_z = Some(zs);
            }
            let idx = layer.map_or(0, |l| l + 1);
            layer = Some(idx);
            let n = match marked {
                Some(n) => {
                    seen_marker = true;
                    n
                }
                None if has_markers && !seen_marker => None,
                None => Some(
                    numbers
                        .last()
                        .copied()
                        .flatten()
                        .map_or(idx as u32, |p| p + 1),
                ),
            };
            numbers.push(n);
        }
        last_end_z = Some(ze);
        out.extrusions.push(Extrusion {
            line: i,
            layer: layer.unwrap_or(0),
        });
    }
    out.number = numbers;
    let n = lines.len();
    out.next_layer = vec![None; n];
    out.prev_layer = vec![None; n];
    let mut k = out.extrusions.len();
    for i in (0..n).rev() {
        while k > 0 && out.extrusions[k - 1].line >= i {
            k -= 1;
        }
        out.next_layer[i] = out.extrusions.get(k).map(|e| e.layer);
    }
    let mut k = 0;
    for i in 0..n {
        while k < out.extrusions.len() && out.extrusions[k].line <= i {
            k += 1;
        }
        out.prev_layer[i] = k.checked_sub(1).map(|j| out.extrusions[j].layer);
    }
    out
}

impl Layers {
    /// Last extruding line of layer `k`.
    fn last_line_of(&self, k: usize) -> Option<usize> {
        self.extrusions
            .iter()
            .rev()
            .find(|e| e.layer == k)
            .map(|e| e.line)
    }
    fn first_line_of(&self, k: usize) -> Option<usize> {
        self.extrusions
            .iter()
            .find(|e| e.layer == k)
            .map(|e| e.line)
    }
    fn layer_count(&self) -> usize {
        self.extrusions.last().map_or(0, |e| e.layer + 1)
    }
}

/// Where a run's pause stopped, in job lines.
#[derive(Debug)]
struct Stop {
    /// Last job line executed (wholly or partly) before the service moves.
    last_line: usize,
    /// First job line executed after the resume.
    next_line: Option<usize>,
    /// The last line was cut by the stop (resumed in the middle).
    mid_line: bool,
    /// Job line in progress at the request and the path position then (mm from the start).
    req_line: Option<usize>,
    req_path_mm: f64,
    /// Speed at the request, mm/s.
    v_req_mm_s: f64,
}

fn job_line(o: &run::Outcome<<PrinterFactory as run::Factory>::Exec>, seq: u32) -> Option<usize> {
    if seq == u32::MAX {
        // The executive's own moves (G28's homing moves) carry no job sequence number.
        return None;
    }
    match o.run.origin_of_seq(seq) {
        Some(Origin::Job(l)) => Some(l),
        _ => None,
    }
}

fn find_stop(
    o: &run::Outcome<<PrinterFactory as run::Factory>::Exec>,
    t_req_us: u64,
    ly: &Layers,
) -> Option<Stop> {
    let recs = &o.run.rec.records;
    let scale = sim::recorder::Scale::from_config(&firmware::config::MachineConfig::ENDER3);
    let first_service = recs
        .iter()
        .position(|r| r.tag.lane == Lane::Service && r.t_start_us >= t_req_us)?;
    let before = recs[..first_service]
        .iter()
        .rposition(|r| r.tag.lane == Lane::Job && job_line(o, r.tag.seq).is_some())?;
    let last = &recs[before];
    let last_line = job_line(o, last.tag.seq)?;
    let after = recs[first_service..]
        .iter()
        .find(|r| r.tag.lane == Lane::Job && job_line(o, r.tag.seq).is_some());
    let next_line = after.and_then(|r| job_line(o, r.tag.seq));
    let mid_line = after.is_some_and(|r| r.tag == last.tag || next_line == Some(last_line));
    // The request: the record in progress (or the next one).
    let req = recs
        .iter()
        .position(|r| r.t_end_us >= t_req_us && r.tag.lane == Lane::Job);
    let (req_line, req_path_mm, v) = match req {
        Some(k) => {
            let r = &recs[k];
            let line = job_line(o, r.tag.seq);
            // Path position: end of the previous line plus the part of this line done.
            let line_start = line
                .and_then(|l| l.checked_sub(1))
                .map_or(0.0, |p| ly.path_end_mm[p]);
            let done: f64 = recs[..k]
                .iter()
                .rev()
                .take_while(|x| job_line(o, x.tag.seq) == line)
                .map(|x| scale.xyz_dist_mm(&x.start, &x.end))
                .sum();
            // Speed from this and the neighbouring records.
            let mut v = 0.0f64;
            for x in &recs[k.saturating_sub(2)..(k + 3).min(recs.len())] {
                let dt = (x.t_end_us.saturating_sub(x.t_start_us)) as f64 * 1e-6;
                if dt > 0.0 {
                    v = v.max(scale.xyz_dist_mm(&x.start, &x.end) / dt);
                }
            }
            (line, line_start + done, v)
        }
        None => (None, 0.0, 0.0),
    };
    Some(Stop {
        last_line,
        next_line,
        mid_line,
        req_line,
        req_path_mm,
        v_req_mm_s: v,
    })
}

/// The layer index whose end the stop is at, or a description of why it is not a boundary.
fn boundary_of(stop: &Stop, ly: &Layers) -> Result<Option<usize>, String> {
    if stop.mid_line {
        return Err(format!("stopped inside line {}", stop.last_line));
    }
    let before = ly.prev_layer[stop.last_line];
    let after = stop.next_line.and_then(|n| ly.next_layer[n]);
    // Between the last extrusion before the stop and the first after it.
    match (before, after) {
        (Some(b), Some(a)) if a == b + 1 => Ok(Some(b)),
        (None, Some(0)) => Ok(None),
        (Some(b), None) if b + 1 == ly.layer_count() => Ok(Some(b)),
        _ => Err(format!(
            "not between layers: last layer before {before:?}, first after {after:?} (lines {} / {:?})",
            stop.last_line, stop.next_line
        )),
    }
}

/// A small fixed-seed generator (xorshift64*): request times and schedules.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The firmware policy with the host sending comments (`--keep-comments`) or not.
fn scenario(comments: bool) -> Scenario {
    let mut sc = Scenario::new(Policy::Firmware, Mode::Layer);
    sc.link.strip_comments = !comments;
    sc
}

/// Printing window (first XY step, end) of a run without a pause.
fn window(job: &[String], comments: bool) -> (f64, f64) {
    let sc = scenario(comments);
    let o = run::run(&PrinterFactory, &sc, job).expect("reference run");
    let first_xy = o
        .reference
        .rec
        .records
        .iter()
        .find(|r| r.start[0] != r.end[0] || r.start[1] != r.end[1])
        .map_or(0, |r| r.t_start_us);
    (first_xy as f64 * 1e-6, o.report.print_time_unpaused_s)
}

fn check_requests(name: &str, comments: bool, requests: usize, rng: &mut Rng) -> Vec<String> {
    let job = load(name, comments);
    let ly = analyse(&job);
    let mut failures = Vec::new();
    assert!(ly.layer_count() >= 5, "{name}: {} layers", ly.layer_count());
    let (t0, t1) = window(&job, comments);
    let accel = f64::from(firmware::config::MachineConfig::ENDER3.axes[0].max_accel_mm_s2);
    for _ in 0..requests {
        let at = t0 + (t1 - t0) * rng.unit() * 0.97;
        let t_req = (at * 1e6) as u64;
        let mut sc = scenario(comments);
        sc.pause = Some(PauseWhen::AtUs(t_req));
        sc.resume_after_us = Some(200_000);
        let tag = format!("{name} comments={comments} request at {at:.3} s");
        let o = match run::run(&PrinterFactory, &sc, &job) {
            Ok(o) => o,
            Err(e) => {
                failures.push(format!("{tag}: run failed: {e:#}"));
                continue;
            }
        };
        if !o.report.finished {
            failures.push(format!("{tag}: the job did not finish"));
        }
        let Some(stop) = find_stop(&o, t_req, &ly) else {
            failures.push(format!("{tag}: no pause point"));
            continue;
        };
        let k = match boundary_of(&stop, &ly) {
            Ok(k) => k,
            Err(e) => {
                failures.push(format!("{tag}: {e}"));
                continue;
            }
        };
        // Lowest allowed: the first boundary not passed at the request.
        let req_line = stop.req_line.unwrap_or(0);
        let lo = ly.prev_layer[req_line.saturating_sub(1)];
        // Highest allowed: the first boundary whose end of extrusion is farther than braking.
        let brake_mm = stop.v_req_mm_s.powi(2) / (2.0 * accel) + 2.0;
        let hi = (lo.unwrap_or(0)..ly.layer_count()).find(|&b| {
            ly.last_line_of(b)
                .is_some_and(|l| ly.path_end_mm[l] - stop.req_path_mm > brake_mm)
        });
        let ok_lo = match (k, lo) {
            (Some(k), Some(lo)) => k >= lo,
            (None, Some(_)) => false,
            _ => true,
        };
        let ok_hi = match (k, hi) {
            (Some(k), Some(hi)) => k <= hi,
            _ => true,
        };
        // The sim's own judgement (sim::metrics, from the executed path and the job's layers)
        // agrees that this is the first reachable boundary.
        if o.report.first_reachable_boundary != Some(true) {
            failures.push(format!(
                "{tag}: the sim reports first_reachable_boundary {:?} (stop layer {:?}, request layer {:?})",
                o.report.first_reachable_boundary, o.report.stop_layer, o.report.request_layer
            ));
        }
        if !(ok_lo && ok_hi) {
            failures.push(format!(
                "{tag}: stopped at the end of layer {k:?}, allowed {lo:?}..={hi:?} (request in line {req_line}, {:.1} mm/s, brake {brake_mm:.1} mm)",
                stop.v_req_mm_s
            ));
        }
    }
    failures
}

fn check_schedules(name: &str, comments: bool, schedules: usize, rng: &mut Rng) -> Vec<String> {
    let job = load(name, comments);
    let ly = analyse(&job);
    let mut failures = Vec::new();
    for _ in 0..schedules {
        // A layer with a number and an earlier layer.
        let idx = 1 + (rng.unit() * (ly.layer_count() - 1) as f64) as usize;
        let Some(n) = ly.number[idx.min(ly.number.len() - 1)] else {
            continue;
        };
        let want = ly
            .number
            .iter()
            .position(|x| x.is_some_and(|x| x >= n))
            .unwrap_or(idx);
        let mut sc = scenario(comments);
        sc.pause = Some(PauseWhen::AtLayer(n));
        sc.resume_after_us = Some(200_000);
        let tag = format!("{name} comments={comments} M761 L{n}");
        let o = match run::run(&PrinterFactory, &sc, &job) {
            Ok(o) => o,
            Err(e) => {
                failures.push(format!("{tag}: run failed: {e:#}"));
                continue;
            }
        };
        let Some(stop) = find_stop(&o, 0, &ly) else {
            failures.push(format!("{tag}: never paused"));
            continue;
        };
        match boundary_of(&stop, &ly) {
            Ok(k) if k.map_or(0, |k| k + 1) == want => {}
            Ok(k) => failures.push(format!(
                "{tag}: stopped before layer index {} (number {:?}), want index {want} (lines {:?} / {:?})",
                k.map_or(0, |k| k + 1),
                ly.number.get(k.map_or(0, |k| k + 1)),
                ly.last_line_of(want.saturating_sub(1)),
                ly.first_line_of(want),
            )),
            Err(e) => failures.push(format!("{tag}: {e}")),
        }
        if !o.report.finished {
            failures.push(format!("{tag}: the job did not finish"));
        }
    }
    failures
}

fn run_corpus(comments: bool) {
    let mut rng = Rng(if comments { 0x5EED_0001 } else { 0x5EED_0002 });
    let mut failures = Vec::new();
    for name in FILES {
        failures.extend(check_requests(name, comments, 3, &mut rng));
        failures.extend(check_schedules(name, comments, 1, &mut rng));
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn corpus_with_comments() {
    run_corpus(true);
}

#[test]
fn corpus_comments_stripped() {
    run_corpus(false);
}

/// The checker itself, on the corpus: layer counts a reader can verify by eye.
#[test]
fn checker_counts_layers() {
    for (name, comments, want) in [
        // 10 layers of 0.3 mm per 3 mm block, three blocks one after another.
        ("prusa-sequential.gcode", false, 30),
        ("prusa-sequential.gcode", true, 30),
        ("slic3r-sequential.gcode", false, 20),
    ] {
        let ly = analyse(&load(name, comments));
        assert_eq!(ly.layer_count(), want, "{name} comments={comments}");
    }
    // Cura numbers from its own ;LAYER:n (the purge line before ;LAYER:0 is not a layer of
    // its own in either mode: it prints at the first layer's height).
    let ly = analyse(&load("cura-support.gcode", true));
    assert_eq!(ly.number.iter().flatten().next(), Some(&0));
    assert_eq!(ly.number.first(), Some(&None));
    assert_eq!(ly.number.len(), ly.layer_count());
}

#[test]
#[ignore]
fn dump_layers() {
    let name = std::env::var("CORPUS").unwrap_or("prusa-vase.gcode".into());
    let comments = std::env::var("COMMENTS").is_ok_and(|v| !v.is_empty());
    let job = load(&name, comments);
    let ly = analyse(&job);
    for k in 0..ly.layer_count() {
        let f = ly.first_line_of(k).unwrap();
        println!(
            "layer {k} number {:?} first line {f}: {}  last {}",
            ly.number[k],
            job[f],
            ly.last_line_of(k).unwrap()
        );
    }
}

#[test]
#[ignore]
fn dump_schedule() {
    let name = std::env::var("CORPUS").unwrap_or("cura-vase.gcode".into());
    let comments = std::env::var("COMMENTS").is_ok_and(|v| !v.is_empty());
    let n: u32 = std::env::var("L").map_or(8, |v| v.parse().unwrap());
    let job = load(&name, comments);
    let mut sc = scenario(comments);
    sc.pause = Some(PauseWhen::AtLayer(n));
    if let Ok(t) = std::env::var("T") {
        sc.pause = Some(PauseWhen::AtUs((t.parse::<f64>().unwrap() * 1e6) as u64));
    }
    sc.resume_after_us = Some(200_000);
    let o = run::run(&PrinterFactory, &sc, &job).unwrap();
    println!("{:#?}", o.timeline);
    println!("{:#?}", o.report);
    for r in o
        .run
        .rec
        .records
        .iter()
        .filter(|r| r.t_start_us > 271_000_000 && r.t_start_us < 290_000_000)
    {
        println!(
            "{:?} {:?} {} {:?} {:?}",
            r.tag,
            o.run.origin_of_seq(r.tag.seq),
            r.t_start_us,
            r.start,
            r.end
        );
    }
    for n in o
        .run
        .fw
        .notes
        .iter()
        .filter(|n| !format!("{n:?}").starts_with("State"))
    {
        println!("{n:?}");
    }
    for r in o
        .run
        .host
        .received
        .iter()
        .filter(|r| format!("{r:?}").contains("pause"))
    {
        println!("{r:?}");
    }
}

#[test]
#[ignore]
fn dump_firmware_marks() {
    let name = std::env::var("CORPUS").unwrap_or("cura-vase.gcode".into());
    let comments = std::env::var("COMMENTS").is_ok_and(|v| !v.is_empty());
    let job = load(&name, comments);
    for (i, m) in sim::layers::detect(&job).iter().enumerate() {
        if let Some(m) = m {
            println!("mark {m} before line {i}: {}", job[i]);
        }
    }
}

/// A `layer` pause requested in the last layer stops at its end — after the last extrusion and
/// before the end code (PrusaSlicer's: `M104 S0`, `G28 X0`, `M84`), not after it with the
/// heater off and X homed.
#[test]
fn a_request_in_the_last_layer_stops_before_the_end_code() {
    for comments in [true, false] {
        let job = load("prusa-zhop.gcode", comments);
        let ly = analyse(&job);
        let heater_off = job
            .iter()
            .position(|l| l.starts_with("M104 S0"))
            .expect("end code");
        // The last extrusion's time in a run without a pause; request 1 s before it.
        let sc = scenario(comments);
        let o = run::run(&PrinterFactory, &sc, &job).expect("reference run");
        let last_ext = ly.extrusions.last().expect("extrusions").line;
        let t_last = o
            .run
            .rec
            .records
            .iter()
            .rev()
            .find(|r| job_line(&o, r.tag.seq) == Some(last_ext))
            .expect("last extrusion ran")
            .t_end_us;
        let t_req = t_last - 1_000_000;
        let mut sc = scenario(comments);
        sc.pause = Some(PauseWhen::AtUs(t_req));
        sc.resume_after_us = Some(200_000);
        let o = run::run(&PrinterFactory, &sc, &job).expect("run");
        let stop = find_stop(&o, t_req, &ly).expect("paused");
        assert!(!stop.mid_line, "comments={comments}: {stop:?}");
        assert!(
            stop.last_line >= last_ext && stop.last_line < heater_off,
            "comments={comments}: stopped after line {} (last extrusion {last_ext}, heater off {heater_off})",
            stop.last_line
        );
        let p = o.report.pause_point_steps.expect("pause point");
        assert!(
            p[0] > 0,
            "comments={comments}: X homed before the stop: {p:?}"
        );
        assert!(o.report.finished, "comments={comments}");
    }
}
