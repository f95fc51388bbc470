use super::*;
use crate::gcode::parse_line;
use crate::machine::MachineState;
use std::vec::Vec;

const CFG: MachineConfig = MachineConfig::ENDER3;

/// Run a program; return (index of the line each mark precedes, mark).
fn marks(program: &str) -> Vec<(usize, LayerMark)> {
    marks_with(program, LayerDetector::new().with_end_mark())
}

fn marks_with(program: &str, mut d: LayerDetector) -> Vec<(usize, LayerMark)> {
    let mut m = MachineState::new(&CFG);
    let mut out = Vec::new();
    for (i, text) in program.lines().enumerate() {
        let line = parse_line(text.as_bytes()).unwrap();
        let before = m;
        if let Some(c) = &line.command {
            m.apply(c, &CFG).unwrap();
        }
        let facts = MoveFacts::of(&before, &m, &CFG);
        if let Some(mark) = d.feed(&line, facts) {
            out.push((i, mark));
        }
    }
    if let Some(mark) = d.finish() {
        out.push((usize::MAX, mark));
    }
    out
}

#[test]
fn prusaslicer_marker_precedes_the_z_move() {
    let p = "G28\nG1 Z5 F5000\n;LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\nG1 E-2 F2400\nG1 Z.2 F7800\nG1 X10 Y10\nG1 E2\n\
             G1 X20 Y10 E1\n;HEIGHT:0.15\nG1 X20 Y20 E2\nG1 E-1\n;LAYER_CHANGE\n;Z:0.4\n;HEIGHT:0.2\nG1 Z.4\nG1 X10 Y10 E3";
    let m = marks(p);
    assert_eq!(m.len(), 2, "{m:?}");
    // Placed before `G1 E-2` (line 5), i.e. before the Z move, height from ;Z:.
    assert_eq!(m[0].0, 5);
    assert_eq!(
        m[0].1,
        LayerMark {
            layer: 1,
            z_um: Some(200),
            source: LayerSource::Comment
        }
    );
    assert_eq!(m[1].0, 16);
    assert_eq!(m[1].1.z_um, Some(400));
    assert_eq!(m[1].1.layer, 2);
}

#[test]
fn cura_marker_follows_the_z_move() {
    let p = ";LAYER_COUNT:2\n;LAYER:0\nM107\nG0 F3000 X10 Y10 Z0.3\n;TYPE:WALL-OUTER\nG1 X20 E1\n\
             G0 X20 Y20 Z0.5\n;TIME_ELAPSED:10\n;LAYER:1\nG1 X10 Y20 E2\n";
    let m = marks(p);
    assert_eq!(m.len(), 2, "{m:?}");
    // Layer 0: Cura moves Z after the marker: the mark goes before that move.
    assert_eq!(m[0].0, 3);
    assert_eq!(m[0].1.z_um, Some(300));
    assert_eq!(m[1].0, 9);
    // Height: Cura has moved Z already.
    assert_eq!(m[1].1.z_um, Some(500));
}

#[test]
fn simplify3d_and_turn_markers() {
    let m =
        marks("; layer 1, Z = 0.300\nG1 Z0.3\nG1 X5 E1\n; layer 2, Z = 0.600\nG1 Z0.6\nG1 X6 E2");
    assert_eq!(m.len(), 2);
    assert_eq!(m[1].1.z_um, Some(600));
    let m = marks(";TURN:0\nG1 X1 Z0.1 E1\n;TURN:1\nG1 X2 Z0.2 E2\n;TURN\nG1 X3 Z0.3 E3");
    assert_eq!(m.len(), 3);
    assert!(m.iter().all(|(_, k)| k.source == LayerSource::Turn));
    // Not markers.
    assert!(marks(";layer height 0.2\n;LAYER:abc\n;HEIGHT:0.2\n;Z:0.3\nG1 X1").is_empty());
}

#[test]
fn families_do_not_double_count() {
    // Orca: ;LAYER_CHANGE and M73 L both per layer.
    let p = ";LAYER_CHANGE\n;Z:0.2\nM73 L1\nG1 Z0.2\nG1 X5 E1\n;LAYER_CHANGE\n;Z:0.4\nM73 L2\nG1 Z0.4\nG1 X6 E2\nG1 Z1\nG1 X7 E3";
    let m = marks(p);
    assert_eq!(m.len(), 2, "{m:?}");
    assert_eq!(m[0].0, 3);
    // Klipper macro alone, repeated with the same number: one layer each.
    let p =
        "SET_PRINT_STATS_INFO CURRENT_LAYER=1\nG1 X5 E1\nSET_PRINT_STATS_INFO CURRENT_LAYER=1\n\
             SET_PRINT_STATS_INFO CURRENT_LAYER=2\nG1 Z1\nG1 X6 E2";
    let m = marks(p);
    assert_eq!(m.len(), 2, "{m:?}");
    assert_eq!(m[0].1.source, LayerSource::Command);
    assert_eq!(m[1].0, 3);
}

#[test]
fn z_rise_fallback() {
    // Slic3r 1.3 style: no comments. Z-hop does not count; layers do.
    let p = "G28\nG1 Z5\nG1 Z0.3\nG1 X10 Y10\nG1 X20 E1\nG1 Z0.7\nG1 X30\nG1 Z0.3\nG1 X40 E2\n\
             G1 Z0.6\nG1 X41\nG1 E2.5\nG1 X50 E3\nG1 X60 E4\nG1 Z0.9\nG1 X55 E5";
    let m = marks(p);
    assert_eq!(
        m.iter().map(|(i, k)| (*i, k.z_um)).collect::<Vec<_>>(),
        vec![(4, Some(300)), (12, Some(600)), (15, Some(900))]
    );
    assert!(m.iter().all(|(_, k)| k.source == LayerSource::ZRise));
    // A rising path that never comes round (a zigzag in a 1 mm square, no seam to find): cut
    // every 1.5 expected rises of a turn (the first layer's 0.2 mm: 0.2, 0.5, 0.8, 1.1).
    let mut p = String::from("G1 X10 Y10 Z0.2\n");
    for i in 0..200 {
        p.push_str(&format!(
            "G1 X{} Y{} Z{:.4} E{}\n",
            10 + i % 2,
            10 + (i / 2) % 2,
            0.2 + i as f32 * 0.005,
            i
        ));
    }
    let m = marks(&p);
    assert_eq!(
        m.iter()
            .map(|(_, k)| k.z_um.unwrap_or(0) / 100)
            .collect::<Vec<_>>(),
        vec![2, 5, 8, 11],
        "{m:?}"
    );
    // Explicit markers switch the fallback off.
    let p = "G1 Z0.3\nG1 X1 E1\n;LAYER_CHANGE\n;Z:0.5\nG1 Z0.5\nG1 X2 E2\nG1 Z0.7\nG1 X3 E3";
    let m = marks(p);
    assert_eq!(m.len(), 2, "{m:?}");
    assert_eq!(m[0].1.source, LayerSource::ZRise);
    assert_eq!(m[1].1.source, LayerSource::Comment);
}

#[test]
fn marker_at_end_of_file_counts() {
    let m = marks("G1 X1 E1\n;LAYER_CHANGE");
    assert_eq!(m.len(), 2);
    assert_eq!(m[1].0, usize::MAX);
}

#[test]
fn sequential_drop_starts_a_layer() {
    // Object 1: layers 0.3 and 0.6; object 2 back at 0.3 (travel lifted above, then down).
    let p = "G1 Z0.3\nG1 X1 E1\nG1 Z0.6\nG1 X2 E2\nG1 Z5\nG1 X50\nG1 Z0.3\nG1 X51 E3\nG1 Z0.6\nG1 X52 E4";
    let m = marks(p);
    assert_eq!(
        m.iter()
            .map(|(i, k)| (*i, k.layer, k.z_um))
            .collect::<Vec<_>>(),
        vec![
            (1, 1, Some(300)),
            (3, 2, Some(600)),
            (7, 3, Some(300)),
            (9, 4, Some(600))
        ]
    );
}

#[test]
fn helix_move_without_an_e_step_is_no_layer() {
    // A vase turn whose last piece advances E by less than one step (Slic3r writes these):
    // it lifts Z without extruding; the next move is still the same turn.
    let p = "G1 Z0.3\nG1 X1 E1\nG1 Z0.6\nG1 X2 E2\nG1 X3 Z0.7 E3\nG1 X4 Z0.8 E3.001\nG1 X5 Z0.85 E4\nG1 X6 Z0.9 E5\nG1 X7 Z1.0 E6";
    let m = marks(p);
    assert_eq!(
        m.iter().map(|(i, k)| (*i, k.z_um)).collect::<Vec<_>>(),
        // Flat 0.3, flat 0.6, the helix's first turn from 0.6; the move after the E-less one
        // starts at 0.8, above the last extrusion's 0.7, and is no new layer (the path has
        // not come round).
        vec![(1, Some(300)), (3, Some(600)), (4, Some(600))]
    );
}

#[test]
fn numbering_is_the_physical_layer_from_1() {
    let nums = |p: &str| marks(p).iter().map(|(_, k)| k.layer).collect::<Vec<_>>();
    // Cura: the purge line in the start code gets a mark of the height rule (no marker yet:
    // headers choose nothing), then ;LAYER:0 numbers the first layer 1 again (Cura's preview
    // shows it as 1) — as the height rule does when the comments are stripped.
    let p = ";FLAVOR:Marlin\n;LAYER_COUNT:40\nG1 Z0.28\nG1 X0 Y200 E15\nG1 Z2\n;LAYER:0\nG0 X10 Y10 Z0.2\nG1 X20 E16\n;LAYER:1\nG0 Z0.4\nG1 X10 E17";
    assert_eq!(nums(p), vec![1, 1, 2]);
    assert_eq!(marks(p)[1].0, 6);
    // Without the header the same.
    let p = "G1 Z0.28\nG1 X0 Y200 E15\nG1 Z2\n;LAYER:0\nG0 X10 Y10 Z0.2\nG1 X20 E16\n;LAYER:1\nG0 Z0.4\nG1 X10 E17";
    assert_eq!(nums(p), vec![1, 1, 2]);
    // Stripped of its comments, the same: the purge at 0.28 is left downwards before
    // anything rose, so the count restarts at the first layer.
    let p = "G1 Z0.28\nG1 X0 Y200 E15\nG1 Z2\nG0 X10 Y10 Z0.2\nG1 X20 E16\nG0 Z0.4\nG1 X10 E17";
    assert_eq!(nums(p), vec![1, 1, 2]);
    // PrusaSlicer: ;LAYER_CHANGE counted from 1 ([layer_num] + 1), the intro line before it.
    let p = "; generated by PrusaSlicer 2.5.0\nG1 Z0.2\nG1 X60 E9 ; intro line\n;LAYER_CHANGE\n;Z:0.2\nG1 Z0.2\nG1 X1 E10\n;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4\nG1 X2 E11";
    assert_eq!(nums(p), vec![1, 1, 2]);
    // Klipper and M73: 1-based as written; 0 is before the first layer.
    let p = "SET_PRINT_STATS_INFO CURRENT_LAYER=0\nG1 X1 E0.5\nSET_PRINT_STATS_INFO CURRENT_LAYER=1\nG1 X5 E1\nSET_PRINT_STATS_INFO CURRENT_LAYER=2\nG1 Z1\nG1 X6 E2";
    assert_eq!(nums(p), vec![1, 2]);
    assert_eq!(
        nums("M73 L1\nG1 X5 E1\nM73 L1\nM73 L2\nG1 Z1\nG1 X6 E2"),
        vec![1, 2]
    );
    // Cura's raft layers (negative numbers) are physical layers: counted in order.
    assert_eq!(
        nums(";LAYER:-2\nG1 X1 E1\n;LAYER:-1\nG1 Z1\nG1 X2 E2\n;LAYER:0\nG1 Z2\nG1 X3 E3"),
        vec![1, 2, 3]
    );
    // Simplify3D, Bambu and ideaMaker.
    assert_eq!(
        nums("; layer 1, Z = 0.200\nG1 Z0.2\nG1 X5 E1\n; layer 2, Z = 0.400\nG1 Z0.4\nG1 X6 E2"),
        vec![1, 2]
    );
    let p = "; CHANGE_LAYER\n; Z_HEIGHT: 0.2\nM73 L1\nG1 Z.2\nG1 X5 E1\n; CHANGE_LAYER\n; Z_HEIGHT: 0.4\nM73 L2\nG1 Z.4\nG1 X6 E2";
    let m = marks(p);
    assert_eq!(nums(p), vec![1, 2]);
    assert_eq!(m[1].1.z_um, Some(400));
    assert_eq!(
        nums(";Sliced by ideaMaker 4.2.3\nG1 Z0.3\nG1 X0 Y9 E2\n;LAYER:0\n;Z:0.3\nG1 X5 E3\n;LAYER:1\n;Z:0.6\nG1 Z0.6\nG1 X6 E4"),
        vec![1, 1, 2]
    );
}

#[test]
fn a_job_restarts_the_count() {
    let job = "G92 E0\nG1 Z0.2\nG1 X5 E1\nG1 Z0.4\nG1 X6 E2\nM104 S0\nM84\n";
    // Two jobs streamed one after the other: the second extrudes after the first's end code.
    let m = marks_with(&format!("{job}{job}"), LayerDetector::new());
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![1, 2, 1, 2]
    );
    // The bed switched off part-way is no end.
    let m = marks_with(
        "G1 Z0.2\nG1 X5 E1\nM140 S0\nG1 Z0.4\nG1 X6 E2",
        LayerDetector::new(),
    );
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![1, 2]
    );
    // restart(): the executive's job start (M110, an SD file), or a continued job.
    let mut d = LayerDetector::new();
    d.restart(7);
    assert_eq!(d.next_layer(), 7);
    let m = marks_with("G1 Z0.2\nG1 X5 E1\nG1 Z0.4\nG1 X6 E2", d);
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![7, 8]
    );
}

#[test]
fn spiral_turns_are_found_from_the_path() {
    // Two flat layers, then a 36-point circle rising 0.2 mm per turn, with the marker
    // comments a slicer would write at each seam; stripped, the turns come from the path.
    let mut p = String::from("G1 Z0.2\n");
    let pt = |k: usize| {
        let a = core::f64::consts::TAU * (k % 36) as f64 / 36.0;
        (100.0 + 20.0 * a.cos(), 100.0 + 20.0 * a.sin())
    };
    let mut e = 0.0;
    for z in [0.2, 0.4] {
        p.push_str(&format!(";LAYER_CHANGE\nG1 Z{z}\n"));
        for k in 1..=36 {
            e += 0.1;
            let (x, y) = pt(k);
            p.push_str(&format!("G1 X{x:.3} Y{y:.3} E{e:.5}\n"));
        }
        // Infill after a travel, back to the seam: a bottom layer, not one loop.
        e += 1.0;
        p.push_str(&format!(
            "G0 X90 Y100\nG1 X110 Y100 E{e:.5}\nG0 X120 Y100\n"
        ));
    }
    for turn in 0..5 {
        p.push_str(";LAYER_CHANGE\n");
        for k in 1..=36 {
            e += 0.1;
            let (x, y) = pt(k);
            let z = 0.4 + 0.2 * (turn as f64 + k as f64 / 36.0);
            p.push_str(&format!("G1 X{x:.3} Y{y:.3} Z{z:.3} E{e:.5}\n"));
        }
    }
    let kept = marks_with(&p, LayerDetector::new());
    let stripped: String = p
        .lines()
        .filter(|l| !l.starts_with(';'))
        .map(|l| format!("{l}\n"))
        .collect();
    let bare = marks_with(&stripped, LayerDetector::new());
    assert_eq!(kept.len(), 7, "{kept:?}");
    assert_eq!(bare.len(), 7, "{bare:?}");
    // The same layers, numbered alike, starting at the same extrusions.
    let texts = |m: &[(usize, LayerMark)], src: &str| {
        m.iter()
            .map(|(i, k)| {
                let line = src.lines().nth(*i).unwrap_or("");
                let l = if line.contains('E') {
                    line
                } else {
                    src.lines().nth(i + 1).unwrap_or("")
                };
                (k.layer, l.to_string())
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(texts(&kept, &p)[2..], texts(&bare, &stripped)[2..]);
    assert!(bare.iter().all(|(_, k)| k.source == LayerSource::ZRise));
}

#[test]
fn end_of_printing_is_a_boundary() {
    // The first end-code command after the last extrusion ends the last layer; later end
    // commands do not, nor does a heater or motor command before anything printed.
    let p = "M104 S0\nM84\nG1 Z0.3\nG1 X1 E1\nG1 E0 F2400\nG1 Z5\nM104 S0\nM140 S0\nM84\nM104 S200\nM84 S600";
    let m = marks(p);
    assert_eq!(
        m.iter()
            .map(|(i, k)| (*i, k.layer, k.source))
            .collect::<Vec<_>>(),
        vec![(3, 1, LayerSource::ZRise), (6, 2, LayerSource::End)]
    );
    // With markers the end mark follows the last number.
    let m = marks(";LAYER:7\nG1 Z0.3\nG1 X1 E1\nM84");
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![1, 2]
    );
    // Only the printer's detector marks the end (layer counts leave it out).
    assert_eq!(marks_with(p, LayerDetector::new()).len(), 1);
}

/// Numbers of the marks a program gets, and the line each precedes.
fn numbered(p: &str) -> Vec<(usize, u32)> {
    marks(p).iter().map(|(i, k)| (*i, k.layer)).collect()
}

#[test]
fn every_family_is_read_with_or_without_a_space() {
    let two = |first: &str, second: &str| {
        format!("{first}\nG1 Z0.2\nG1 X5 E1\n{second}\nG1 Z0.4\nG1 X6 E2")
    };
    for (a, b) in [
        (";LAYER_CHANGE", "; LAYER_CHANGE"),
        (";CHANGE_LAYER", "; CHANGE_LAYER"),
        (";LAYER:0", "; LAYER:1"),
        ("; layer 1, Z = 0.200", ";layer 2, Z = 0.400"),
        (";layer:0.20", "; layer:0.20"),
        (
            "; BEGIN_LAYER_OBJECT z=0.2 z_thickness=0.2",
            ";BEGIN_LAYER_OBJECT z=0.4",
        ),
        (
            ";; --- layer 0 (0.200 @ 0.2) ---",
            "; --- layer 1 (0.200 @ 0.4) ---",
        ),
        ("; <layer>", ";<layer>"),
    ] {
        let p = two(a, b);
        let m = marks(&p);
        assert_eq!(
            m.iter()
                .map(|(i, k)| (*i, k.layer, k.source))
                .collect::<Vec<_>>(),
            vec![(1, 1, LayerSource::Comment), (4, 2, LayerSource::Comment)],
            "{a} / {b}"
        );
    }
    // Heights given by the marker itself.
    let z = |p: &str| marks(p).first().and_then(|(_, k)| k.z_um);
    assert_eq!(
        z("; BEGIN_LAYER_OBJECT z=0.263 z_thickness=0.263\nG1 X1 E1"),
        Some(263)
    );
    assert_eq!(z(";; --- layer 0 (0.250 @ 0.255) ---\nG1 X1 E1"), Some(255));
    assert_eq!(z("; layer 3, Z = 0.6\nG1 X1 E1"), Some(600));
    // Not markers: Cura's count, KISSlicer's end of layer, IceSL's, a FlashPrint-like integer.
    for c in [
        ";LAYER_COUNT:12",
        "; END_LAYER_OBJECT z=0.2",
        "; </layer>",
        ";layer:3",
    ] {
        assert!(marks(&format!("{c}\nG1 X1 E1"))
            .iter()
            .all(|(_, k)| k.source == LayerSource::ZRise));
    }
}

#[test]
fn a_header_does_not_choose_the_family() {
    // OrcaSlicer for a Bambu printer: its header is PrusaSlicer-like, its markers Bambu's.
    let p = "; generated by OrcaSlicer 2.3.0 on 2025-01-01\n; CHANGE_LAYER\n; Z_HEIGHT: 0.2\nM73 L1\nG1 Z.2\nG1 X5 E1\n; CHANGE_LAYER\n; Z_HEIGHT: 0.4\nM73 L2\nG1 Z.4\nG1 X6 E2";
    assert_eq!(numbered(p), vec![(4, 1), (9, 2)]);
}

/// A square loop of side `s` mm at `z`, from (x, y), as four extrusions.
fn square(x: f32, y: f32, s: f32, z: f32) -> String {
    format!(
        "G1 X{x} Y{y} Z{z}\nG1 X{} E1\nG1 Y{} E1\nG1 X{x} E1\nG1 Y{y} E1\n",
        x + s,
        y + s
    )
}

#[test]
fn a_purge_line_below_at_or_above_the_first_layer_is_start_code() {
    let d = LayerDetector::new();
    let purge = |z: f32| format!("M83\nG1 X0 Y2 Z{z}\nG1 X60 E9\nG1 X100 E3.5\n");
    for (z, what) in [(0.2f32, "below"), (0.3, "at"), (0.45, "above")] {
        let p = format!(
            "{}{}{}{}",
            purge(z),
            square(80.0, 80.0, 20.0, 0.3),
            square(80.0, 80.0, 20.0, 0.6),
            square(80.0, 80.0, 20.0, 0.9)
        );
        // The purge's mark, then the first layer numbered 1 again, and 2, 3.
        assert_eq!(
            marks_with(&p, d)
                .iter()
                .map(|(i, k)| (*i, k.layer))
                .collect::<Vec<_>>(),
            vec![(2, 1), (5, 1), (10, 2), (15, 3)],
            "a purge {what} the first layer"
        );
    }
    // A first layer that is a loop is no purge, whatever follows at its height.
    let p = format!(
        "M83\n{}{}{}",
        square(10.0, 10.0, 30.0, 0.3),
        square(80.0, 80.0, 20.0, 0.3),
        square(80.0, 80.0, 20.0, 0.6)
    );
    assert_eq!(
        marks_with(&p, d)
            .iter()
            .map(|(i, k)| (*i, k.layer))
            .collect::<Vec<_>>(),
        vec![(2, 1), (12, 2)]
    );
}

#[test]
fn levelling_baked_into_the_file_is_no_layer_change() {
    // MatterControl's software levelling: every move cut into 1 mm pieces, each at the
    // layer's height plus the bed's plane (here 0.1 mm over 100 mm in X, 0.05 in Y).
    let plane = |x: f32, y: f32| 0.001 * x + 0.0005 * y;
    let mut p = String::from("M83\n");
    for layer in 1..=4 {
        let z = 0.1 + 0.2 * layer as f32;
        // A 20 mm square from (40, 40), then a line of infill after a travel, and a hop.
        let corners = [
            (40.0, 40.0),
            (60.0, 40.0),
            (60.0, 60.0),
            (40.0, 60.0),
            (40.0, 40.0),
        ];
        p.push_str(&format!("G1 X40 Y40 Z{:.4}\n", z + plane(40.0, 40.0)));
        for w in corners.windows(2) {
            let ((x0, y0), (x1, y1)) = (w[0], w[1]);
            for k in 1..=20 {
                let t = k as f32 / 20.0;
                let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
                p.push_str(&format!(
                    "G1 X{x:.3} Y{y:.3} Z{:.4} E0.05\n",
                    z + plane(x, y)
                ));
            }
        }
        p.push_str(&format!(
            "G1 Z{:.4}\nG1 X58 Y42\n",
            z + 0.4 + plane(40.0, 40.0)
        ));
        p.push_str(&format!("G1 Z{:.4}\n", z + plane(58.0, 42.0)));
        for k in 1..=16 {
            let y = 42.0 + k as f32;
            p.push_str(&format!(
                "G1 X58 Y{y:.3} Z{:.4} E0.05\n",
                z + plane(58.0, y)
            ));
        }
    }
    let m = marks_with(&p, LayerDetector::new());
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![1, 2, 3, 4],
        "{m:?}"
    );
}

#[test]
fn the_detector_stays_small() {
    // It lives in the `Printer` (a static on the board): bounded state, no allocation.
    let n = core::mem::size_of::<LayerDetector>();
    std::eprintln!("LayerDetector: {n} bytes");
    assert!(n <= 192, "{n} bytes");
}
