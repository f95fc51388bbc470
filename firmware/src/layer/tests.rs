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
        let before = m.position_steps(&CFG);
        if let Some(c) = &line.command {
            m.apply(c, &CFG).unwrap();
        }
        let facts = MoveFacts::between(&before, &m.position_steps(&CFG), &CFG);
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
            layer: 0,
            z_um: Some(200),
            source: LayerSource::Comment
        }
    );
    assert_eq!(m[1].0, 16);
    assert_eq!(m[1].1.z_um, Some(400));
    assert_eq!(m[1].1.layer, 1);
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
    // A helix (Z rising during extrusion): a layer per layer height of rise. The first layer
    // height is 0.2 mm (no flat layer before), so layers start at 0.2, 0.4, ... 1.0.
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
        vec![2, 4, 6, 8, 10],
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
            (1, 0, Some(300)),
            (3, 1, Some(600)),
            (7, 2, Some(300)),
            (9, 3, Some(600))
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
        // Flat 0.3, flat 0.6, the helix's first turn from 0.6, the next turn from 0.9 (not the
        // move after the E-less one, which starts at 0.8 above the last extrusion's 0.7).
        vec![
            (1, Some(300)),
            (3, Some(600)),
            (4, Some(600)),
            (8, Some(900))
        ]
    );
}

#[test]
fn numbering_is_the_slicers_own() {
    // Cura: the header names the family, so the purge line in the start code is no layer and
    // ;LAYER:n numbers the marks (M761 L37 means Cura's layer 37).
    let p = ";FLAVOR:Marlin\n;LAYER_COUNT:40\nG1 Z0.28\nG1 X0 Y200 E15\nG1 Z2\n;LAYER:0\nG0 X10 Y10 Z0.2\nG1 X20 E16\n;LAYER:1\nG0 Z0.4\nG1 X10 E17";
    let m = marks(p);
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![0, 1]
    );
    assert_eq!(m[0].0, 6);
    // Without the header the purge line is a layer of the height rule, but Cura's numbers
    // still number the marker layers.
    let p = "G1 Z0.28\nG1 X0 Y200 E15\nG1 Z2\n;LAYER:0\nG0 X10 Y10 Z0.2\nG1 X20 E16\n;LAYER:1\nG0 Z0.4\nG1 X10 E17";
    let m = marks(p);
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![0, 0, 1]
    );
    // PrusaSlicer: the header too; ;LAYER_CHANGE counted from 0 (PrusaSlicer's [layer_num]).
    let p = "; generated by PrusaSlicer 2.5.0\nG1 Z0.2\nG1 X60 E9 ; intro line\n;LAYER_CHANGE\n;Z:0.2\nG1 Z0.2\nG1 X1 E10";
    let m = marks(p);
    assert_eq!(m.len(), 1, "{m:?}");
    assert_eq!(m[0].1.layer, 0);
    // Klipper and M73 numbers as written.
    let p = "SET_PRINT_STATS_INFO CURRENT_LAYER=1\nG1 X5 E1\nSET_PRINT_STATS_INFO CURRENT_LAYER=2\nG1 Z1\nG1 X6 E2";
    let m = marks(p);
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![1, 2]
    );
    // Cura's raft layers are negative: they count as 0.
    let m = marks(";LAYER:-2\nG1 X1 E1\n;LAYER:-1\nG1 Z1\nG1 X2 E2\n;LAYER:0\nG1 Z2\nG1 X3 E3");
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![0, 0, 0]
    );
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
        vec![(3, 0, LayerSource::ZRise), (6, 1, LayerSource::End)]
    );
    // With markers the end mark follows the last number.
    let m = marks(";LAYER:7\nG1 Z0.3\nG1 X1 E1\nM84");
    assert_eq!(
        m.iter().map(|(_, k)| k.layer).collect::<Vec<_>>(),
        vec![7, 8]
    );
    // Only the printer's detector marks the end (layer counts leave it out).
    assert_eq!(marks_with(p, LayerDetector::new()).len(), 1);
}
