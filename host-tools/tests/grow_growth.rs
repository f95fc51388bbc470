//! Differential growth: the stroke stays one closed, simple curve inside its boundary, the
//! density parameter sets the spacing, and the emitted G-code never stops extruding.

use glam::DVec2;
use host_tools::additive::slice::point_in_polygon;
use host_tools::design::motion::{MotionLimits, MoveKind, Trajectory};
use host_tools::design::profile::Profile;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::paste::grow::{
    builtin_boundary, grow, read_boundary, to_model, verify_simple, Boundary, GrowParams,
    StackParams,
};

fn stroke_len(nodes: &[DVec2]) -> f64 {
    (0..nodes.len())
        .map(|i| nodes[i].distance(nodes[(i + 1) % nodes.len()]))
        .sum()
}

fn grow_full(shape: &str, size: f64, spacing: f64) -> (Boundary, Vec<DVec2>) {
    let b = Boundary::new(builtin_boundary(shape, size).unwrap(), 256).unwrap();
    let p = GrowParams {
        max_nodes: 100_000,
        max_iterations: 6_000,
        stall_iterations: 150,
        ..GrowParams::with_spacing(spacing)
    };
    let g = grow(&b, &p, |_| {}).unwrap();
    (b, g.nodes)
}

#[test]
fn growth_fills_a_blob_with_one_simple_stroke_inside() {
    let (b, nodes) = grow_full("blob", 30.0, 1.5);
    assert!(nodes.len() > 250, "grew to {} nodes", nodes.len());
    assert_eq!(verify_simple(&nodes, true), None, "no self-intersection");
    for p in &nodes {
        assert!(point_in_polygon(*p, &b.polygon), "{p} outside the boundary");
    }
    // Evenly filled: mean spacing (area / length) within 40 % of the asked spacing.
    let mean = b.area_mm2() / stroke_len(&nodes);
    assert!(mean > 0.9 && mean < 2.1, "mean spacing {mean}");
}

#[test]
fn density_sets_the_spacing_continuously() {
    let (_, dense) = grow_full("circle", 24.0, 1.0);
    let (_, mid) = grow_full("circle", 24.0, 1.5);
    let (_, coarse) = grow_full("circle", 24.0, 2.0);
    let (ld, lm, lc) = (stroke_len(&dense), stroke_len(&mid), stroke_len(&coarse));
    // Stroke length ∝ 1 / spacing for a filled region.
    assert!(ld > lm && lm > lc, "{ld} {lm} {lc}");
    assert!((ld / lc - 2.0).abs() < 0.6, "{ld} / {lc}");
    for n in [&dense, &mid, &coarse] {
        assert_eq!(verify_simple(n, true), None);
    }
}

#[test]
fn verify_simple_finds_crossings() {
    let eight = [
        DVec2::new(0.0, 0.0),
        DVec2::new(1.0, 1.0),
        DVec2::new(1.0, 0.0),
        DVec2::new(0.0, 1.0),
    ];
    assert!(verify_simple(&eight, true).is_some());
    let square = [
        DVec2::new(0.0, 0.0),
        DVec2::new(1.0, 0.0),
        DVec2::new(1.0, 1.0),
        DVec2::new(0.0, 1.0),
    ];
    assert_eq!(verify_simple(&square, true), None);
    // A long zig-zag with one far-away crossing edge.
    let mut zig: Vec<DVec2> = (0..200)
        .map(|i| DVec2::new(i as f64 * 0.5, (i % 2) as f64))
        .collect();
    assert_eq!(verify_simple(&zig, false), None);
    zig.push(DVec2::new(50.0, -1.0));
    zig.push(DVec2::new(50.2, 2.0));
    assert!(verify_simple(&zig, false).is_some());
}

#[test]
fn emitted_layers_never_stop_extruding() {
    let (_, nodes) = grow_full("square", 16.0, 2.0);
    let model = to_model(
        &nodes,
        DVec2::new(100.0, 100.0),
        &StackParams {
            layers: 3,
            layer_mm: 0.4,
            line_width_mm: 1.0,
            speed_mm_s: 16.7,
        },
    );
    let profile = Profile::ender3();
    let (gcode, summary) = GcodeWriter::new(&profile, WriteOptions::default())
        .to_string(&model)
        .unwrap();
    assert_eq!(summary.travels, 1, "only the travel to the start");
    assert_eq!(summary.retractions, 0);
    assert_eq!(summary.strings, 3 * nodes.len());
    let traj =
        Trajectory::from_gcode(gcode.as_bytes(), MotionLimits::from_profile(&profile)).unwrap();
    // From the first printing move on, every move prints and Z never goes down.
    let first = traj
        .segments
        .iter()
        .position(|s| s.kind == MoveKind::Print)
        .unwrap();
    let mut z = 0.0;
    for s in &traj.segments[first..] {
        if s.end[0] == s.start[0] && s.end[1] == s.start[1] && s.end[2] == s.start[2] {
            continue; // end code
        }
        if s.kind != MoveKind::Print {
            // Only the profile's end code may travel, after the last string.
            assert!(s.end[2] >= 1.2 - 1e-9, "travel inside the print: {s:?}");
            break;
        }
        assert!(s.end[2] >= z - 1e-9);
        z = s.end[2];
    }
    assert!(
        (z - 1.2).abs() < 1e-6,
        "three layers of 0.4 mm, last at {z}"
    );
}

#[test]
fn boundary_files() {
    let txt = "# square\n0 0\n10,0\n10 10\n0 10\n";
    assert_eq!(read_boundary(txt).unwrap().len(), 4);
    assert!(read_boundary("0 0\n1 x\n").is_err());
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg"><path d="M0,0 L20,0 l0,20 H0 z"/></svg>"#;
    let p = read_boundary(svg).unwrap();
    assert_eq!(p.len(), 4);
    assert_eq!(p[2], DVec2::new(20.0, -20.0), "SVG y flipped");
    let poly = r#"<svg><polygon points="0,0 5,0 5,5"/></svg>"#;
    assert_eq!(read_boundary(poly).unwrap().len(), 3);
    let curve = r#"<svg><path d="M0 0 C 1 1 2 2 3 3 Z"/></svg>"#;
    assert!(read_boundary(curve).is_err());
    assert!(Boundary::new(vec![DVec2::ZERO, DVec2::X], 64).is_err());
    let tiny = Boundary::new(builtin_boundary("circle", 2.0).unwrap(), 64).unwrap();
    assert!(grow(&tiny, &GrowParams::with_spacing(5.0), |_| {}).is_err());
}
