//! Every named printer profile writes G-code whose layers are numbered the same way by
//! - the firmware library's own layer detector (`firmware::layer::LayerDetector`, driven here
//!   line by line with the printer's parser and machine state, as the printer does),
//! - `host-tools stats` (its layer table), and
//! - an independent checker written here from scratch (no `firmware::layer`): layers from the
//!   heights at which the extruding moves print, with the markers as boundaries.
//!
//! Both marker styles are covered: Cura's `;LAYER:n` (Creality and EAZAO profiles) and
//! PrusaSlicer's `;LAYER_CHANGE` (Prusa, Anycubic, Voron, SKR 2, paste), with and without a
//! purge line in the start code, with `M73` progress lines (Prusa, Anycubic, SKR 2). Every start
//! and end code line also parses with the printer's parser.
//!
//! # The checker's numbering
//! Extruding moves (X or Y moves while E advances) are grouped into layers. A new layer starts
//! at a marker line (the first extruding move after it), and — while no marker has been seen —
//! when an extruding move starts higher than the previous one ended (a purge line at another
//! height). Numbers count from 1 in file order (the slicers' preview numbers: Cura's `;LAYER:n`
//! is layer n + 1); what prints before the first marker (a purge line) is a prelude, and the
//! first marker's layer is layer 1. A `;FLAVOR:` / `;LAYER_COUNT:` header means markers
//! follow: no height rule before them, as Cura files mean.

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::layer::{LayerDetector, MoveFacts};
use firmware::machine::MachineState;
use glam::DVec3;
use host_tools::design::model::{MarkerKind, Model, Step, Str};
use host_tools::design::profile::{Profile, BUILTIN};
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::job::stats::stats;

const LAYERS: usize = 6;

/// Six 20 mm squares stacked 0.2 mm apart, each after a layer marker, at X/Y 40–60.
fn model() -> Model {
    let mut m = Model::new([50.0, 50.0]);
    for k in 0..LAYERS {
        let z = 0.2 * (k + 1) as f64;
        m.push(Step::Marker {
            kind: MarkerKind::Layer,
            z_mm: z,
            height_mm: 0.2,
        });
        let c = [
            (40.0, 40.0),
            (60.0, 40.0),
            (60.0, 60.0),
            (40.0, 60.0),
            (40.0, 40.0),
        ];
        for w in c.windows(2) {
            m.push(Step::String(Str::line(
                DVec3::new(w[0].0, w[0].1, z),
                DVec3::new(w[1].0, w[1].1, z),
                0.1,
                30.0,
            )));
        }
    }
    m
}

/// Layer numbers from the firmware library's detector, with the printer's parser and machine
/// state (MachineConfig::ENDER3's travel covers the squares; moves it refuses, such as a purge
/// line at Y −3 beyond its travel, leave the state as the printer would). Every line must parse.
fn firmware_numbers(g: &str) -> Vec<u32> {
    firmware_numbers_with(g, false)
}

/// [`firmware_numbers`]; with `skip_bad`, lines the parser rejects are skipped (the printer
/// answers `Error:` and does nothing), as `stats` does.
fn firmware_numbers_with(g: &str, skip_bad: bool) -> Vec<u32> {
    let cfg = MachineConfig::ENDER3;
    let mut m = MachineState::new(&cfg);
    let mut d = LayerDetector::new();
    let mut out = Vec::new();
    for text in g.lines() {
        let line = match parse_line(text.as_bytes()) {
            Ok(l) => l,
            Err(_) if skip_bad => continue,
            Err(e) => panic!("`{text}`: {e:?}"),
        };
        // As the executive feeds its detector: the commanded positions before and after
        // (a vase move that rises 1 µm rises, though it makes no Z step).
        let before = m;
        if let Some(cmd) = &line.command {
            let _ = m.apply(cmd, &cfg);
        }
        let facts = MoveFacts::of(&before, &m, &cfg);
        if let Some(mark) = d.feed(&line, facts) {
            out.push(mark.layer);
        }
    }
    if let Some(mark) = d.finish() {
        out.push(mark.layer);
    }
    out
}

/// The layers that count: leading prelude marks (purge lines the height rule marked before
/// the slicer's first marker, the layer after each numbered 1 again) dropped.
fn without_prelude(mut marks: &[u32]) -> &[u32] {
    while let [1, rest @ ..] = marks {
        if rest.first() != Some(&1) {
            break;
        }
        marks = rest;
    }
    marks
}

/// The independent checker: (number, height) of each layer, from the text alone.
fn checker_layers(g: &str) -> Vec<(u32, f64)> {
    let (mut abs_xyz, mut abs_e) = (true, true);
    let mut pos = [0.0f64; 4];
    let mut layers: Vec<(u32, f64)> = Vec::new();
    let mut pending: Option<Option<u32>> = None; // a marker seen, its number if it has one
    let mut header = false;
    let mut markers_seen = false;
    let mut last_end_z: Option<f64> = None;
    let mut next_count = 1u32;
    let mut first_marker_done = false;
    for raw in g.lines() {
        let (code, comment) = match raw.find(';') {
            Some(i) => (&raw[..i], raw[i + 1..].trim()),
            None => (raw, ""),
        };
        if comment == "LAYER_CHANGE" {
            pending = Some(Some(0));
            markers_seen = true;
        } else if let Some(n) = comment.strip_prefix("LAYER:") {
            pending = Some(n.trim().parse().ok());
            markers_seen = true;
        } else if comment.starts_with("FLAVOR:") || comment.starts_with("LAYER_COUNT:") {
            header = true;
        }
        let words: Vec<&str> = code.split_whitespace().collect();
        let Some(cmd) = words.first() else { continue };
        let val = |c: char| {
            words[1..]
                .iter()
                .find(|w| w.starts_with(c))
                .and_then(|w| w[1..].parse::<f64>().ok())
        };
        match *cmd {
            "G90" => abs_xyz = true,
            "G91" => abs_xyz = false,
            "M82" => abs_e = true,
            "M83" => abs_e = false,
            "G92" => {
                if let Some(e) = val('E') {
                    pos[3] = e;
                }
            }
            "G0" | "G1" => {
                let mut to = pos;
                for (k, c) in ['X', 'Y', 'Z'].iter().enumerate() {
                    if let Some(v) = val(*c) {
                        to[k] = if abs_xyz { v } else { pos[k] + v };
                    }
                }
                if let Some(e) = val('E') {
                    to[3] = if abs_e && abs_xyz { e } else { pos[3] + e };
                }
                let extrudes = to[3] > pos[3] && (to[0] != pos[0] || to[1] != pos[1]);
                if extrudes {
                    let start_z = pos[2];
                    let new_layer = match pending.take() {
                        Some(number) => Some(number),
                        None if !markers_seen && !header => match last_end_z {
                            None => Some(None),
                            // higher: the next layer; lower: a new first layer (sequential)
                            Some(z) if (start_z - z).abs() > 1e-6 => Some(None),
                            _ => None,
                        },
                        None => None,
                    };
                    if let Some(number) = new_layer {
                        if number.is_some() && !first_marker_done {
                            // The slicer's first marker: what came before was a prelude.
                            first_marker_done = true;
                            layers.clear();
                            next_count = 1;
                        }
                        layers.push((next_count, start_z));
                        next_count += 1;
                    }
                    last_end_z = Some(to[2]);
                }
                pos = to;
            }
            _ => {}
        }
    }
    layers
}

#[test]
fn every_profile_numbers_layers_alike() {
    for name in BUILTIN {
        let p = Profile::builtin(name).expect("profile");
        let (g, sum) = GcodeWriter::new(&p, WriteOptions::default())
            .to_string(&model())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(sum.markers, LAYERS, "{name}");
        let fw = firmware_numbers(&g);
        let st = stats(g.as_bytes(), &p).expect("stats");
        assert_eq!(st.bad_lines, 0, "{name}: {:?}", st.bad_line_errors);
        let st_numbers: Vec<u32> = st.layer_times.iter().map(|l| l.layer).collect();
        let checker = checker_layers(&g);
        let ck_numbers: Vec<u32> = checker.iter().map(|l| l.0).collect();
        let fw = without_prelude(&fw);
        assert_eq!(st_numbers, fw, "{name}: stats vs firmware");
        assert_eq!(ck_numbers, fw, "{name}: checker vs firmware\n{checker:?}");
        assert_eq!(st.layers as usize, fw.len(), "{name}");
        // Every profile, purge line or not, Cura or PrusaSlicer markers: the design's six
        // layers are layers 1 to 6, at their heights.
        assert_eq!(fw, (1..=LAYERS as u32).collect::<Vec<_>>(), "{name}");
        for (k, (_, z)) in checker.iter().enumerate() {
            assert!(
                (z - 0.2 * (k + 1) as f64).abs() < 1e-6,
                "{name}: layer {} at {z}",
                k + 1
            );
        }
    }
}

/// Progress lines: Prusa-style profiles with `progress` write `M73 P.. R..` rising to
/// `M73 P100 R0` before the end code; they are no layer markers (numbers above are unchanged
/// by them); Cura-style profiles write none.
#[test]
fn m73_progress_by_profile() {
    for name in BUILTIN {
        let p = Profile::builtin(name).expect("profile");
        let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
            .to_string(&model())
            .expect("write");
        let m73: Vec<(u32, u32)> = g
            .lines()
            .filter_map(|l| l.strip_prefix("M73 P"))
            .map(|r| {
                let (pc, rm) = r.split_once(" R").expect("P and R");
                (pc.parse().expect("P"), rm.parse().expect("R"))
            })
            .collect();
        if !p.progress {
            assert!(m73.is_empty(), "{name}");
            continue;
        }
        assert!(m73.len() >= 2, "{name}: {m73:?}");
        assert_eq!(m73.first().map(|m| m.0), Some(0), "{name}");
        assert_eq!(m73.last(), Some(&(100, 0)), "{name}");
        assert!(
            m73.windows(2).all(|w| w[0].0 <= w[1].0 && w[0].1 >= w[1].1),
            "{m73:?}"
        );
        let end = g.find("M73 P100 R0").expect("end");
        let last_marker = g.rfind(";LAYER_CHANGE").expect("markers");
        assert!(end > last_marker, "{name}: M73 P100 before the last layer");
    }
}

/// Fan: profiles with `fan_off_layers = 1` turn the part fan on after the second layer
/// marker, never before; the start code switches it off (M107).
#[test]
fn fan_comes_on_after_the_first_layer() {
    for name in BUILTIN {
        let p = Profile::builtin(name).expect("profile");
        let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
            .to_string(&model())
            .expect("write");
        let fan_on = g.find("M106 S255");
        if p.fan == 0.0 {
            assert!(fan_on.is_none(), "{name}");
            continue;
        }
        if p.fan_off_layers == 1 {
            let second = [";LAYER:1\n", ";LAYER_CHANGE\n;Z:0.4\n"]
                .iter()
                .filter_map(|m| g.find(m))
                .min()
                .expect("second marker");
            let on = fan_on.expect("fan on");
            assert!(on > second, "{name}: fan on before layer 2");
            assert!(
                g[..second].contains("M107"),
                "{name}: fan not off in start code"
            );
        }
    }
}

/// The slicer corpus (tests/fixtures/corpus: PrusaSlicer, Slic3r and Cura in vase, sequential,
/// Z-hop, support and variable-layer modes): `stats` numbers every layer as the firmware's
/// detector does, and a bad line in the middle is skipped with its error, the numbers unchanged.
#[test]
fn stats_numbers_corpus_layers_as_the_firmware() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/corpus");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("corpus")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "gcode"))
        .collect();
    files.sort();
    assert!(files.len() >= 10, "{files:?}");
    let p = Profile::builtin("mk3s").expect("mk3s");
    for f in &files {
        let text = std::fs::read_to_string(f).expect("read");
        let fw = firmware_numbers_with(&text, true);
        let st = stats(text.as_bytes(), &p).expect("stats");
        let nums: Vec<u32> = st.layer_times.iter().map(|l| l.layer).collect();
        assert!(fw.len() > 3, "{}: {} layers", f.display(), fw.len());
        // The prelude (a purge line the firmware's height rule numbered before the slicer's
        // first marker, its count then starting again) is left out as the firmware leaves it.
        assert_eq!(nums, without_prelude(&fw), "{}", f.display());
        // A bad line in the middle of the file: skipped, reported, nothing else changes.
        let lines: Vec<&str> = text.lines().collect();
        let mid = lines.len() / 2;
        let mut bad = lines[..mid].join("\n");
        bad.push_str("\nG1 X1e99 Y?\n");
        bad.push_str(&lines[mid..].join("\n"));
        let sb = stats(bad.as_bytes(), &p).expect("stats reads past a bad line");
        assert_eq!(sb.bad_lines, st.bad_lines + 1, "{}", f.display());
        assert!(sb
            .bad_line_errors
            .iter()
            .any(|e| e.line as usize == mid + 1));
        let nb: Vec<u32> = sb.layer_times.iter().map(|l| l.layer).collect();
        assert_eq!(nb, nums, "{}", f.display());
    }
}

/// A design in FullControl's manner with a prelude: a floor ring printed before its first
/// `mark_layer`, then rings reached by `travel_to` (a lift over what is printed).
const FLOOR_FIRST: &str = r#"
let t = init(#{ fan_percent: 0, print_speed: 30, extrusion_width: 0.45,
               extrusion_height: 0.2, start: point(BED_X + 12, BED_Y, 0.2) });
t.extrude_path(circle_xy(point(BED_X, BED_Y, 0.2), 12, 0, 48));
for l in 1..8 {
    let z = 0.2 * (l + 1);
    t.mark_layer(0.2);
    t.travel_to(point(BED_X - 12, BED_Y, z));
    t.extrude_path(circle_xy(point(BED_X, BED_Y, z), 12, PI, 48));
    t.travel_to(point(BED_X + 3, BED_Y, z));
    t.extrude_path(circle_xy(point(BED_X, BED_Y, z), 3, 0, 24));
}
t
"#;

/// Issue 33, one notion of a layer's height and number: on every profile, for a design with
/// a prelude (a floor ring before its first mark) and lifted travels, and for
/// `fc_speed_lattice` (its own prime line; `mark_layer` while the pen is still on the layer
/// below), `stats` gives the layers the independent `layerref` model finds — the same numbers
/// (from 1, the prelude no layer: before, mk3s restarted 1, 2, 1, 2, 3) and heights (where
/// the layer prints, never a lift: before, ender3 showed layer 1 at Z 1.2) — and so do the
/// written `;Z:` markers and the 3D page's layer table (the hover readout's Z).
#[test]
fn numbers_and_heights_agree_with_layerref() {
    use host_tools::design::script::ScriptRunner;
    let lattice = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/fc_speed_lattice.rhai"),
    )
    .expect("example");
    for name in BUILTIN {
        let p = Profile::builtin(name).expect("profile");
        for (what, src) in [
            ("floor first", FLOOR_FIRST),
            ("speed lattice", lattice.as_str()),
        ] {
            if what == "speed lattice" && p.limits.max_feed_xy_mm_s < 120.0 {
                continue; // the paste printer: its 120 mm/s travels are refused, rightly
            }
            let out = ScriptRunner::new(p.clone())
                .run(what, src, std::path::Path::new("."))
                .unwrap_or_else(|e| panic!("{name} {what}: {e}"));
            let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
                .to_string(&out.model)
                .unwrap_or_else(|e| panic!("{name} {what}: {e}"));
            let ctx = format!("{name}, {what}");
            let st = stats(g.as_bytes(), &p).expect("stats");
            let got: Vec<(u32, f64)> = st
                .layer_times
                .iter()
                .map(|l| (l.layer, l.z_mm.expect("height")))
                .collect();
            let reference = layerref::Model::of_lines(g.lines(), layerref::Comments::Keep);
            let want: Vec<(u32, f64)> = reference
                .layers()
                .iter()
                .filter(|l| l.number > 0)
                .map(|l| (l.number, l.z_mm))
                .collect();
            assert_eq!(got.len(), want.len(), "{ctx}: {got:?} vs layerref {want:?}");
            for (a, b) in got.iter().zip(&want) {
                assert!(
                    a.0 == b.0 && (a.1 - b.1).abs() < 1e-4,
                    "{ctx}: {got:?} vs {want:?}"
                );
            }
            // The numbers count from 1, every one once (no prelude restart).
            let nums: Vec<u32> = got.iter().map(|l| l.0).collect();
            assert_eq!(nums, (1..=nums.len() as u32).collect::<Vec<_>>(), "{ctx}");
            // `;Z:` (PrusaSlicer-style profiles) says the same heights.
            let zs: Vec<f64> = g
                .lines()
                .filter_map(|l| l.strip_prefix(";Z:"))
                .map(|v| v.parse().expect(";Z:"))
                .collect();
            if !zs.is_empty() {
                assert_eq!(zs.len(), got.len(), "{ctx}");
                for (z, l) in zs.iter().zip(&got) {
                    assert!((z - l.1).abs() < 1e-3, "{ctx}: ;Z:{z} for {l:?}");
                }
            }
            // The 3D page's table: [number, Z] per layer.
            let (page, _) =
                host_tools::job::preview_html::html(g.as_bytes(), &p, "t").expect("page");
            let table = page
                .split("const LAYERS = ")
                .nth(1)
                .and_then(|r| r.split(";\n").next())
                .expect("LAYERS");
            let rows: Vec<(u32, f64)> = serde_json::from_str::<Vec<(u32, f64)>>(table)
                .unwrap_or_else(|e| panic!("{ctx}: {e}: {table}"));
            assert_eq!(rows.len(), got.len(), "{ctx}: page {rows:?}");
            for (r, l) in rows.iter().zip(&got) {
                assert!(
                    r.0 == l.0 && (r.1 - l.1).abs() < 1e-3,
                    "{ctx}: page {r:?} vs {l:?}"
                );
            }
        }
    }
}
