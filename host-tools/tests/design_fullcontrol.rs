//! FullControl's reach (issue 15): building from points, state changes at any point of a
//! script, travels that never collide, Kanada's names and errors that point at the script
//! line. Every G-code check reads the output back with the project's reader
//! (`host_tools::gcode::read`), independent of the writer's internals; the collision check is
//! this file's own: it samples every travel against the printed strings' volumes (and a base
//! part's box) computed here.

use glam::DVec3;
use host_tools::additive::job::{
    check, plan, start_position, to_model, FaceChoice, JobParams, Speeds,
};
use host_tools::additive::stl::box_mesh;
use host_tools::design::model::Model;
use host_tools::design::profile::Profile;
use host_tools::design::script::{ScriptError, ScriptOutput, ScriptRunner};
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::gcode::read::{default_reader, Event, GcodeReader};
use std::path::Path;

fn run(src: &str) -> Result<ScriptOutput, ScriptError> {
    ScriptRunner::new(Profile::ender3()).run("t.rhai", src, Path::new("."))
}

fn gcode(m: &Model) -> String {
    let p = Profile::ender3();
    GcodeWriter::new(&p, WriteOptions::default())
        .to_string(m)
        .map(|(g, _)| g)
        .unwrap_or_else(|e| panic!("write: {e}"))
}

/// One move as the reader sees it.
#[derive(Clone, Copy, Debug)]
struct Mv {
    from: DVec3,
    to: DVec3,
    de: f64,
    feed_mm_s: f64,
    line: u32,
}

impl Mv {
    fn prints(&self) -> bool {
        self.de > 1e-9 && self.from.distance(self.to) > 1e-9
    }
    fn travels(&self) -> bool {
        self.de <= 1e-9 && self.from.distance(self.to) > 1e-9
    }
}

fn moves(g: &str) -> Vec<Mv> {
    let mut out = Vec::new();
    default_reader()
        .read(g.as_bytes(), &mut |e| {
            if let Event::Move {
                from,
                to,
                feed_mm_s,
                line,
            } = e
            {
                out.push(Mv {
                    from: DVec3::new(from[0], from[1], from[2]),
                    to: DVec3::new(to[0], to[1], to[2]),
                    de: to[3] - from[3],
                    feed_mm_s,
                    line,
                });
            }
        })
        .unwrap_or_else(|e| panic!("the reader rejects the output: {e}"));
    out
}

/// 1-based numbers of the lines equal to `text` (comments stripped).
fn lines_of(g: &str, text: &str) -> Vec<u32> {
    g.lines()
        .enumerate()
        .filter(|(_, l)| l.split(';').next().unwrap_or("").trim() == text)
        .map(|(i, _)| i as u32 + 1)
        .collect()
}

fn one(g: &str, text: &str) -> u32 {
    let v = lines_of(g, text);
    assert_eq!(v.len(), 1, "`{text}` lines: {v:?}");
    v[0]
}

/// The printing move ending at `p`.
fn printed_to(ms: &[Mv], p: DVec3) -> Mv {
    *ms.iter()
        .find(|m| m.prints() && m.to.distance(p) < 1e-6)
        .unwrap_or_else(|| panic!("no printing move to {p}"))
}

// ------------------------------------------------------------------ collision check

/// Half the width of a printed string: the nozzle tip closer than this (in XY) to a string's
/// centre line is over the string, mm.
const HALF_WIDTH_MM: f64 = 0.2;
/// A string's height below its centre line, mm.
const STRING_HEIGHT_MM: f64 = 0.4;
/// How far above a string's top the tip must pass, mm.
const ABOVE_MM: f64 = 0.1;
/// Samples this close to a travel's own start or end are where the nozzle meets the print
/// legitimately (leaving a string, landing on the next one), mm.
const END_SKIP_MM: f64 = 1.0;

/// Where a travel's tip passes through a printed string (printed before the travel) or the
/// `base` box: (line, tip).
fn collisions(ms: &[Mv], base: Option<(DVec3, DVec3)>) -> Vec<(u32, DVec3)> {
    let mut printed: Vec<(DVec3, DVec3)> = Vec::new();
    let mut hits = Vec::new();
    for m in ms {
        if m.prints() {
            printed.push((m.from, m.to));
            continue;
        }
        if !m.travels() {
            continue;
        }
        let len = m.from.distance(m.to);
        let n = (len / 0.1).ceil().max(1.0) as usize;
        for k in 0..=n {
            let p = m.from.lerp(m.to, k as f64 / n as f64);
            if let Some((lo, hi)) = base {
                if p.cmpgt(lo + 0.05).all() && p.cmplt(hi - 0.05).all() {
                    hits.push((m.line, p));
                    break;
                }
            }
            if p.distance(m.from) < END_SKIP_MM || p.distance(m.to) < END_SKIP_MM {
                continue;
            }
            let inside = printed.iter().any(|(a, b)| {
                let ab = (*b - *a).truncate();
                let t = if ab.length_squared() > 0.0 {
                    ((p - *a).truncate().dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let c = a.lerp(*b, t);
                (p - c).truncate().length() < HALF_WIDTH_MM
                    && p.z < c.z + ABOVE_MM
                    && p.z > c.z - STRING_HEIGHT_MM
            });
            if inside {
                hits.push((m.line, p));
                break;
            }
        }
    }
    hits
}

// ------------------------------------------------------------------ state changes

#[test]
fn state_changes_come_out_where_the_script_put_them() {
    let out = run(r#"
        let t = turtle(50, 50, 0.2);
        t.extrude_to(60, 50, 0.2);
        t.fan(50);
        t.extrude_to(point(60, 60, 0.2));
        t.hotend(210);
        t.hotend(215, true);
        t.bed(70, false);
        t.bed(65, true);
        t.set_width_height(0.5, 0.25);
        t.set_speed(30);
        t.extrude_to(50, 60, 0.2);
        t.set_retraction(#{ length: 2.5, speed: 30, min_travel: 0.5 });
        t.gcode("M42 P4 S255\nM117 hello");
        t.pause();
        t.travel_to(70, 70, 0.2);
        t.pause_now();
        t.extrude_to(80, 70, 0.2);
        t
    "#)
    .unwrap_or_else(|e| panic!("{e}"));
    let g = gcode(&out.model);
    let ms = moves(&g);
    let a = printed_to(&ms, DVec3::new(60.0, 50.0, 0.2));
    let b = printed_to(&ms, DVec3::new(60.0, 60.0, 0.2));
    let c = printed_to(&ms, DVec3::new(50.0, 60.0, 0.2));
    let d = printed_to(&ms, DVec3::new(80.0, 70.0, 0.2));
    let order = [
        a.line,
        one(&g, "M106 S128"),
        b.line,
        one(&g, "M104 S210"),
        one(&g, "M109 S215"),
        one(&g, "M140 S70"),
        one(&g, "M190 S65"),
        c.line,
        one(&g, "M42 P4 S255"),
        one(&g, "M117 hello"),
        one(&g, "M601"),
        one(&g, "M601 S1"),
        d.line,
    ];
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{order:?}\n{g}");
    // Width × height and speed apply from C on.
    let area = std::f64::consts::PI * 0.875 * 0.875;
    assert!((c.de - 0.5 * 0.25 * 10.0 / area).abs() < 2e-3, "{c:?}");
    assert!((a.de - 0.2 * 10.0 / area).abs() < 2e-3, "{a:?}");
    assert!((c.feed_mm_s - 30.0).abs() < 1e-9 && (b.feed_mm_s - 20.0).abs() < 1e-9);
    // The new retraction (2.5 mm at 30 mm/s) on the travel after the pause mark, primed
    // before D; the travel lifts.
    let pause = one(&g, "M601");
    let between: Vec<&Mv> = ms
        .iter()
        .filter(|m| m.line > pause && m.line < d.line)
        .collect();
    let retract = between.iter().find(|m| m.de < 0.0).expect("a retraction");
    assert!(
        (retract.de + 2.5).abs() < 1e-5 && (retract.feed_mm_s - 30.0).abs() < 1e-9,
        "{retract:?}"
    );
    assert!(between
        .iter()
        .any(|m| m.de > 0.0 && (m.de - 2.5).abs() < 1e-5));
    let top = between.iter().map(|m| m.to.z).fold(0.0, f64::max);
    assert!(top >= 1.2 - 1e-9, "travel lifts: top {top}");
    assert!(
        one(&g, "M601 S1")
            > between
                .iter()
                .filter(|m| m.travels())
                .map(|m| m.line)
                .max()
                .unwrap_or(0)
    );
}

#[test]
fn bad_state_changes_are_script_errors_at_their_line() {
    for (src, want) in [
        ("let t = turtle(0, 0, 0);\nt.fan(150);\nt", "fan"),
        ("let t = turtle(0, 0, 0);\nlet p = circle_xy(point(0, 0, 0), 1, 0, 2000000);\nt", "segments"),
        ("let t = turtle(0, 0, 0);\nlet p = subdivide([[0, 0, 0], [1000, 0, 0]], 0.0001);\nt", "subdivide"),
        ("let t = turtle(0, 0, 0);\nt.hotend(900, true);\nt", "hotend"),
        ("let t = turtle(0, 0, 0);\nt.gcode(\"M42\\u0007\");\nt", "ASCII"),
        ("let t = turtle(0, 0, 0);\nt.set_retraction(#{ length: -1 });\nt", "retraction"),
        ("let t = turtle(0, 0, 0);\nt.set_extrusion(#{ width: 0.2, height: 0.4, area_model: \"stadium\" });\nt", "stadium"),
        ("let t = turtle(0, 0, 0);\nt.set_extrusion(#{ widht: 0.2 });\nt", "widht"),
    ] {
        let e = run(src).expect_err(src);
        assert_eq!(e.line, 2, "{src}: {e}");
        assert!(e.msg.contains(want), "{src}: {e}");
    }
}

// ------------------------------------------------------------------ building from points

#[test]
fn points_helpers_build_the_expected_path() {
    // A hexagon (polygon_xy), a FullControl-style circle subdivided, a reflected copy.
    let out = run(r#"
        let c = point(100, 100, 0.2);
        let t = turtle(c);
        t.polyline(polygon_xy(c, 10, 0, 6));
        let circle = subdivide(circle_xy(point(130, 100, 0.2), 5, 0, 8), 0.5);
        t.polyline(circle);
        t.polyline(reflect_xy(circle, point(100, 0, 0), point(100, 1, 0)));
        t.polyline(move_points(square_wave_xy(point(80, 130, 0.2), 0, 4, 1, 3), [0, 0, 0]));
        t
    "#)
    .unwrap_or_else(|e| panic!("{e}"));
    let g = gcode(&out.model);
    let ms = moves(&g);
    let printed: Vec<&Mv> = ms.iter().filter(|m| m.prints()).collect();
    // 6 hexagon sides, 8 chords of 3.83 mm in 8 pieces each (2 circles), 11 wave segments.
    assert_eq!(printed.len(), 6 + 64 + 64 + 11, "{}", printed.len());
    let hex: f64 = printed[..6].iter().map(|m| m.from.distance(m.to)).sum();
    assert!((hex - 60.0).abs() < 0.01, "{hex}");
    // The mirrored circle is around x = 70.
    let mirrored = &printed[70..134];
    assert!(mirrored
        .iter()
        .all(|m| (m.to.truncate() - glam::DVec2::new(70.0, 100.0)).length() < 5.01));
    assert!(collisions(&ms, None).is_empty());
}

#[test]
fn true_arcs_from_the_pen_are_g2_g3_and_end_where_asked() {
    // A quarter circle counter-clockwise about (100, 100) from (110, 100), then a full
    // clockwise circle rising 0.4 mm.
    let out = run("let t = turtle(110, 100, 0.2);\n\
                   t.extrude_arc(point(100, 100, 0), PI / 2);\n\
                   t.extrude_arc(point(100, 100, 0), -2 * PI, 0.4);\nt")
    .unwrap_or_else(|e| panic!("{e}"));
    let g = gcode(&out.model);
    assert_eq!(g.lines().filter(|l| l.starts_with("G3 ")).count(), 1, "{g}");
    assert_eq!(g.lines().filter(|l| l.starts_with("G2 ")).count(), 1, "{g}");
    let ms = moves(&g);
    let printed: Vec<&Mv> = ms.iter().filter(|m| m.prints()).collect();
    // The reader splits arcs into chords: all on the circle, the quarter ending at (100, 110).
    assert!(printed.len() > 10);
    assert!(printed.iter().all(
        |m| ((m.to.truncate() - glam::DVec2::new(100.0, 100.0)).length() - 10.0).abs() < 0.01
    ));
    assert!(printed
        .iter()
        .any(|m| m.to.distance(DVec3::new(100.0, 110.0, 0.2)) < 1e-3));
    let last = printed.last().map(|m| m.to).unwrap_or_default();
    assert!(
        last.distance(DVec3::new(100.0, 110.0, 0.6)) < 1e-3,
        "{last}"
    );
    let len: f64 = printed.iter().map(|m| m.from.distance(m.to)).sum();
    let want =
        10.0 * std::f64::consts::FRAC_PI_2 + (400.0 * std::f64::consts::PI.powi(2) + 0.16).sqrt();
    assert!((len - want).abs() < 0.05, "{len} vs {want}");
    let e = run("let t = turtle(100, 100, 0.2);\nt.extrude_arc(point(100, 100, 0), 1);\nt")
        .expect_err("on the centre");
    assert_eq!(e.line, 2, "{e}");
}

#[test]
fn model_copies_reflect_and_subdivide() {
    let out = run(r#"
        let h = helix(#{ cx: 60, cy: 60, radius: 5, turns: 2, per_turn: 20, z0: 0.2 });
        let both = h.copies([30, 0, 0], 3);
        let m = both + h.reflect_xy(point(0, 100, 0), point(1, 100, 0));
        m.subdivide(0.5)
    "#)
    .unwrap_or_else(|e| panic!("{e}"));
    let m = &out.model;
    let b = m.bbox();
    assert!(
        (b.max.x - 125.0).abs() < 1e-6 && (b.max.y - 145.0).abs() < 1e-6,
        "{b:?}"
    );
    assert!(m.strings().all(|s| s.len_mm() <= 0.5 + 1e-9));
    // The copies are reached by lifted travels: nothing collides.
    assert!(collisions(&moves(&gcode(m)), None).is_empty());
}

// ------------------------------------------------------------------ travel never collides

/// Two helical towers, the second on the far side of the first's last point.
const TOWERS: &str = r#"
    let a = helix(#{ cx: 100, cy: 100, radius: 5, turns: 25, per_turn: 36, z0: 0.2 });
    let b = helix(#{ cx: 70, cy: 100, radius: 5, turns: 2, per_turn: 36, z0: 0.2 });
"#;

#[test]
fn assemble_lifts_where_a_straight_travel_would_cut_the_first_part() {
    let safe = run(&format!("{TOWERS} assemble([a, b])")).unwrap_or_else(|e| panic!("{e}"));
    let naive = run(&format!("{TOWERS} a + b")).unwrap_or_else(|e| panic!("{e}"));
    let hits = collisions(&moves(&gcode(&naive.model)), None);
    assert!(
        !hits.is_empty(),
        "the check must see the straight diagonal cut tower A"
    );
    let hits = collisions(&moves(&gcode(&safe.model)), None);
    assert!(hits.is_empty(), "{hits:?}");
}

#[test]
fn turtle_pops_and_travel_to_lift_over_what_was_printed() {
    // A rising 3D tree: each pop returns to a branch point below the tip.
    let tree = r#"
        fn tree(len, depth) {
            this.forward(len, len * 0.5);
            if depth > 0 {
                this.push(); this.left(35); this.tree(len * 0.75, depth - 1); this.pop();
                this.push(); this.right(35); this.tree(len * 0.75, depth - 1); this.pop();
            }
        }
        let t = turtle(100, 100, 0.2);
        t.tree(12, 4);
    "#;
    let safe = run(&format!("{tree} t")).unwrap_or_else(|e| panic!("{e}"));
    let hits = collisions(&moves(&gcode(&safe.model)), None);
    assert!(hits.is_empty(), "{hits:?}");
    // The same return made with a straight travel drags the nozzle through the branch.
    let naive = run("let t = turtle(100, 100, 0.2);\n\
                     t.forward(12, 6);\n\
                     t.travel_straight_to(100, 100, 0.2);\n\
                     t.left(90); t.forward(5);\nt")
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(!collisions(&moves(&gcode(&naive.model)), None).is_empty());
    let fixed = run("let t = turtle(100, 100, 0.2);\n\
                     t.forward(12, 6);\n\
                     t.travel_to(100, 100, 0.2);\n\
                     t.left(90); t.forward(5);\nt")
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(collisions(&moves(&gcode(&fixed.model)), None).is_empty());
}

#[test]
fn the_fractal_tree_example_never_travels_through_its_branches() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/fractal_tree.rhai");
    let out = ScriptRunner::new(Profile::ender3())
        .run_file(&path)
        .unwrap_or_else(|e| panic!("{e}"));
    let hits = collisions(&moves(&gcode(&out.model)), None);
    assert!(hits.is_empty(), "{hits:?}");
}

#[test]
fn additive_approach_and_travels_clear_the_base_and_the_new_walls() {
    let p = Profile::ender3();
    // A 20 mm cube base at 40..60 and a 10 mm cube added on its top face.
    let lo = DVec3::new(40.0, 40.0, 0.0);
    let hi = DVec3::new(60.0, 60.0, 20.0);
    let base = box_mesh(lo, hi);
    let shape = box_mesh(DVec3::ZERO, DVec3::splat(10.0));
    let start = start_position(&p).unwrap_or_else(|e| panic!("{e}"));
    let params = JobParams {
        face: FaceChoice::At(DVec3::new(50.0, 50.0, 20.0)),
        start_mm: start,
        ..JobParams::default()
    };
    let job = plan(&base, &shape, &params).unwrap_or_else(|e| panic!("{e}"));
    assert!(check(&base, &job, &params).ok().flatten().is_none());
    let model = to_model(&job, &params, &Speeds::default());
    let g = gcode(&model);
    let ms = moves(&g);
    assert!(ms.iter().all(|m| m.to.z >= 0.0));
    let hits = collisions(&ms, Some((lo, hi)));
    assert!(hits.is_empty(), "{hits:?}");
    // The check sees the old way: straight from where the start code leaves the head to the
    // first point, through the cube's top edge.
    let first = job.paths[0].points[0];
    let mut old = Model::new([0.0, 0.0]);
    old.push(host_tools::design::model::Step::Travel {
        to: first,
        speed_mm_s: None,
    });
    old.push(host_tools::design::model::Step::String(
        host_tools::design::model::Str::line(first, first + DVec3::X, 0.08, 20.0),
    ));
    assert!(!collisions(&moves(&gcode(&old)), Some((lo, hi))).is_empty());
}

// ------------------------------------------------------------------ names and errors

#[test]
fn kanada_names_are_aliases() {
    let kanada = run("let t = init(1.75, 200, 0, 0.2, 100, 100, 0.2);\n\
                      t.setVelocity(30); t.setCrossSection(0.3);\n\
                      t.fd(10); t.lt(90); t.penup(); t.fd(5); t.pendown(); t.rt(45); t.fd(3, 0.1);\nt")
    .unwrap_or_else(|e| panic!("{e}"));
    let snake = run("let t = init(1.75, 200, 0, 0.2, 100, 100, 0.2);\n\
                     t.set_velocity(30); t.set_cross_section(0.3);\n\
                     t.forward(10); t.left(90); t.pen_up(); t.forward(5); t.pen_down(); t.right(45); t.forward(3, 0.1);\nt")
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(kanada.model, snake.model);
    assert_eq!(snake.model.string_count(), 2);
}

#[test]
fn misspelt_functions_get_a_hint_and_the_line() {
    for (src, line, want) in [
        (
            "let t = turtle(0, 0, 0);\n\nt.extrudeTo(1, 2, 3);\nt",
            3,
            "extrude_to",
        ),
        ("let p = arcXY(point(0, 0, 0), 5, 0, 1, 10);", 1, "arc_xy"),
        ("let t = turtle(0,0,0);\nt.speed(20);\nt", 2, "set_velocity"),
        ("let t = turtle(0,0,0);\nt.Hotend(200);\nt", 2, "hotend"),
        (
            "let t = turtle(0,0,0);\nt.set_velocity(1, 2, 3);\nt",
            2,
            "exists",
        ),
    ] {
        let e = run(src).expect_err(src);
        assert_eq!(e.line, line, "{src}: {e}");
        assert!(e.msg.contains(want), "{src}: {e}");
    }
}

#[test]
fn errors_never_point_at_nothing_or_name_closures_anon() {
    let cases = [
        // A closure that fails inside a deformation.
        "let h = helix(#{ turns: 1, per_turn: 8 });\nh.deform_xyz(|x, y, z| [x, y], |c, x, y, z| c, |v, x, y, z| v)",
        // A closure with the wrong result in map_strings.
        "let h = helix(#{ turns: 1, per_turn: 8 });\nh.map_strings(|i, c, v| 3)",
        // The last expression is not a design.
        "let t = turtle(0, 0, 0);\nt.forward(3);\n42\n",
        // An error inside a script function called as a method.
        "fn go(n) { this.forward(n); this.set_velocity(-1); }\nlet t = turtle(0, 0, 0);\nt.go(3);\nt",
    ];
    for src in cases {
        let e = run(src).expect_err(src);
        assert!(e.line > 0 && e.col > 0, "{src}: {e}");
        assert!(!e.msg.contains("anon$"), "{src}: {e}");
    }
    let e = run("let t = turtle(0, 0, 0);\nt.forward(3);\n42\n").expect_err("not a model");
    assert_eq!(e.line, 3, "{e}");
}

// ------------------------------------------------------------------ ported FullControl models

fn example(name: &str) -> (Model, String) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name);
    let out = ScriptRunner::new(Profile::ender3())
        .run_file(&path)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let g = gcode(&out.model);
    (out.model, g)
}

#[test]
fn ported_fullcontrol_models_keep_their_shape_and_never_collide() {
    // Ripple vase: one spiral, 125 layers of 101 zig-zag segments, radius 15..~23 mm.
    let (m, g) = example("fc_ripple_vase.rhai");
    let ms = moves(&g);
    assert_eq!(m.string_count(), 125 * 101 - 1);
    let printed: Vec<&Mv> = ms.iter().filter(|m| m.prints()).collect();
    let c = glam::DVec2::new(117.5, 117.5);
    let r: Vec<f64> = printed
        .iter()
        .map(|m| (m.to.truncate() - c).length())
        .collect();
    let (lo, hi) = r
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
    assert!(lo > 14.9 && hi < 23.1 && hi - lo > 6.0, "{lo}..{hi}");
    assert!(
        printed.windows(2).all(|w| w[1].to.z >= w[0].to.z - 1e-6),
        "z never falls"
    );
    assert!(collisions(&ms, None).is_empty());
    // Non-planar spacer: Z rises and falls inside each ring; two copies, lifted between.
    let (m, g) = example("fc_nonplanar_spacer.rhai");
    let ms = moves(&g);
    let falls = ms
        .windows(2)
        .filter(|w| w[0].prints() && w[1].prints() && w[1].to.z < w[0].to.z - 1e-3)
        .count();
    assert!(falls > 100, "{falls}");
    let b = m.bbox();
    assert!(
        b.max.x - b.min.x > 29.0 + 2.0 * 10.0,
        "two copies 29 mm apart: {b:?}"
    );
    let hits = collisions(&ms, None);
    assert!(hits.is_empty(), "{hits:?}");
    // Star lattice: three identical layers, 0.2 mm apart.
    let (m, g) = example("fc_star_lattice.rhai");
    assert_eq!(m.string_count() % 3, 0);
    let ms = moves(&g);
    let zs: std::collections::BTreeSet<i64> = ms
        .iter()
        .filter(|m| m.prints())
        .map(|m| (m.to.z * 1000.0).round() as i64)
        .collect();
    assert_eq!(zs.into_iter().collect::<Vec<_>>(), [200, 400, 600]);
    let hits = collisions(&ms, None);
    assert!(hits.is_empty(), "{hits:?}");
}

#[test]
fn a_retraction_change_while_retracted_primes_what_was_pulled() {
    // Retract 5 mm (the profile's) on the first travel, change to 1 mm while retracted (a
    // travel follows at once), then another travel: every millimetre pulled is pushed back.
    let out = run("let t = turtle(50, 50, 0.2);\n\
                   t.extrude_to(60, 50, 0.2);\n\
                   t.travel_straight_to(60, 70, 0.2);\n\
                   t.set_retraction(#{ length: 1, speed: 20, min_travel: 0.5 });\n\
                   t.travel_straight_to(70, 70, 0.2);\n\
                   t.extrude_to(80, 70, 0.2);\n\
                   t.travel_straight_to(80, 90, 0.2);\n\
                   t.extrude_to(90, 90, 0.2);\nt")
    .unwrap_or_else(|e| panic!("{e}"));
    let g = gcode(&out.model);
    let ms = moves(&g);
    let e_only: Vec<f64> = ms
        .iter()
        .filter(|m| m.from.distance(m.to) < 1e-9 && m.de.abs() > 1e-9)
        .map(|m| m.de)
        .collect();
    assert_eq!(e_only.len(), 6, "{e_only:?}\n{g}");
    assert!(
        (e_only[0] + 5.0).abs() < 1e-5 && (e_only[1] - 5.0).abs() < 1e-5,
        "{e_only:?}"
    );
    assert!(
        (e_only[2] + 1.0).abs() < 1e-5 && (e_only[3] - 1.0).abs() < 1e-5,
        "{e_only:?}"
    );
    assert!(e_only.iter().sum::<f64>().abs() < 1e-5, "{e_only:?}");
}

// ------------------------------------------------------------------ the route's invariant

fn seg_dist_xy(p: glam::DVec2, a: glam::DVec2, b: glam::DVec2) -> f64 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).length()
}

fn xy_segments_within(a0: DVec3, a1: DVec3, b0: DVec3, b1: DVec3, d: f64) -> bool {
    // Sampled finely: the segments are short (≤ ~70 mm), 0.05 mm steps.
    let n = ((a0.truncate().distance(a1.truncate()) / 0.05).ceil() as usize).max(1);
    (0..=n).any(|k| {
        let p = a0.lerp(a1, k as f64 / n as f64).truncate();
        seg_dist_xy(p, b0.truncate(), b1.truncate()) < d
    })
}

mod route_props {
    use super::*;
    use host_tools::design::model::{Step, Str};
    use host_tools::design::travel::{HeightMap, TRAVEL_CLEARANCE_MM};
    use proptest::prelude::*;

    fn p3() -> impl Strategy<Value = DVec3> {
        (0.0..50.0f64, 0.0..50.0f64, 0.0..10.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// A route is straight only when every printed string within 1 mm (in XY) of its
        /// way (1 mm at each end left out, as the printability check does) lies more than
        /// 0.1 mm below its lower end; otherwise its crossing is at least the clearance
        /// above every such string, and above both ends.
        #[test]
        fn routes_clear_everything_printed_near_their_way(
            strings in proptest::collection::vec((p3(), p3()), 0..30),
            from in p3(),
            to in p3(),
        ) {
            let mut m = Model::new([0.0, 0.0]);
            for (a, b) in &strings {
                m.push(Step::String(Str::line(*a, *b, 0.1, 20.0)));
            }
            let mut map = HeightMap::new();
            map.catch_up(&m);
            let r = map.route(from, to);
            if from == to {
                prop_assert!(r.is_empty());
                return Ok(());
            }
            prop_assert_eq!(r.last().copied(), Some(to));
            if r.len() == 1 {
                let len = from.distance(to);
                if len > 2.0 {
                    let (a0, a1) = (from.lerp(to, 1.0 / len), from.lerp(to, 1.0 - 1.0 / len));
                    let low = from.z.min(to.z) - 0.1;
                    for (a, b) in &strings {
                        if xy_segments_within(a0, a1, *a, *b, 1.0) {
                            prop_assert!(a.z.max(b.z) < low + 1e-9,
                                "string {a}→{b} in the straight way {from}→{to}");
                        }
                    }
                }
                return Ok(());
            }
            let safe = r[0].z;
            prop_assert!(safe >= from.z.max(to.z) + TRAVEL_CLEARANCE_MM - 1e-9);
            for (a, b) in &strings {
                if xy_segments_within(from, to, *a, *b, 1.0) {
                    prop_assert!(safe >= a.z.max(b.z) + TRAVEL_CLEARANCE_MM - 1e-9,
                        "string {a}→{b} under the way, crossing at {safe}");
                }
            }
        }
    }
}

#[test]
fn the_additive_start_is_where_the_start_code_leaves_the_head() {
    // A start code ending with a purge line (and a line this firmware rejects, skipped as the
    // printer skips it): the approach starts at the purge line's end.
    let mut p = Profile::ender3();
    p.gcode.start =
        "G28\nM420 S1 Z10 Q\nG1 Z0.3 F600\nG1 X5 Y20 F3000\nG1 X5 Y120 E10 F1500\n".into();
    let s = start_position(&p).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.distance(DVec3::new(5.0, 120.0, 0.3)) < 1e-5, "{s}");
    assert!(start_position(&Profile::ender3()).is_ok_and(|s| s.z.abs() < 1e-9));
}
