use super::*;

fn model(text: &str, comments: Comments) -> Model {
    Model::of_lines(text.lines(), comments)
}

/// (number, first line) of each layer of a job.
fn starts(m: &Model) -> Vec<(u32, usize)> {
    m.layers()
        .iter()
        .map(|l| (l.number, l.first_line))
        .collect()
}

#[test]
fn flat_layers_hops_prelude_and_sequential() {
    // A purge line at 0.28 above a first layer at 0.2 (Cura's Ender-3 start code), a Z-hop,
    // two layers, then a second object back at 0.2.
    let g = "G1 Z0.28\nG1 X0 Y100 E5\nG1 Z2\nG1 X10 Y10 Z0.2\nG1 X20 E6\nG1 Z0.8\nG1 X30\n\
             G1 Z0.2\nG1 X40 E7\nG1 Z0.4\nG1 X10 E8\nG1 Z5\nG1 X60\nG1 Z0.2\nG1 X70 E9";
    let m = model(g, Comments::Strip);
    assert_eq!(starts(&m), vec![(0, 1), (1, 4), (2, 10), (3, 14)]);
    assert!(m.extrudes(8) && m.layer_of(8).map(|l| l.number) == Some(1));
    assert!(!m.extrudes(6));
}

#[test]
fn markers_number_from_one_and_preludes_are_no_layer() {
    let g = ";FLAVOR:Marlin\nG1 Z0.28\nG1 X0 Y100 E5\n;LAYER:0\nG1 Z0.2\nG1 X20 E6\n;LAYER:1\n\
             G1 Z0.4\nG1 X10 E7\n;LAYER:2\n;LAYER:3\nG1 Z0.8\nG1 X20 E8";
    let m = model(g, Comments::Keep);
    // The empty layer 3 keeps its number: the next one is 4.
    assert_eq!(starts(&m), vec![(0, 2), (1, 5), (2, 8), (4, 12)]);
    // Command markers: a repeated number is no new layer, 0 is before the first.
    let g = "M73 L0\nG1 X1 E1\nM73 L1\nG1 X2 E2\nM73 L1\nG1 X3 E3\nM73 L2\nG1 X4 E4";
    let m = model(g, Comments::Strip);
    assert_eq!(starts(&m), vec![(0, 1), (1, 3), (2, 7)]);
    // The first family wins (Orca writes ;LAYER_CHANGE and M73 L).
    let g = ";LAYER_CHANGE\nM73 L1\nG1 X1 E1\n;LAYER_CHANGE\nM73 L2\nG1 X2 E2";
    assert_eq!(starts(&model(g, Comments::Keep)), vec![(1, 2), (2, 5)]);
    assert_eq!(starts(&model(g, Comments::Strip)), vec![(1, 2), (2, 5)]);
}

#[test]
fn jobs_restart_the_count() {
    let job = "G92 E0\nG1 Z0.2\nG1 X5 E1\nG1 Z0.4\nG1 X6 E2\nM104 S0\nM84\n";
    let m = model(&format!("{job}{job}N-1 M110*15\n{job}"), Comments::Strip);
    let got: Vec<(u32, u32)> = m.layers().iter().map(|l| (l.job, l.number)).collect();
    assert_eq!(got, vec![(0, 1), (0, 2), (1, 1), (1, 2), (2, 1), (2, 2)]);
    // The bed alone switched off is no end of the job.
    let m = model(
        "G1 Z0.2\nG1 X5 E1\nM140 S0\nG1 Z0.4\nG1 X6 E2",
        Comments::Strip,
    );
    assert_eq!(m.layers().last().map(|l| (l.job, l.number)), Some((0, 2)));
}

/// A vase: two flat layers (a loop and a line of bottom infill, as PrusaSlicer's solid bottom:
/// not one closed loop, so the spiral does not continue the last of them as Cura's first
/// spiralized layer does), then a spiral of `turns` turns of an `n`-gon of radius 20 mm rising
/// 0.2 mm per turn, with PrusaSlicer's marker at each seam.
fn vase(n: usize, turns: usize) -> String {
    let pt = |k: usize| {
        let a = std::f64::consts::TAU * (k % n) as f64 / n as f64;
        (100.0 + 20.0 * a.cos(), 100.0 + 20.0 * a.sin())
    };
    let mut g = String::from("G1 X120 Y100 Z0.2\n");
    let mut e = 0.0;
    for z in [0.2, 0.4] {
        g.push_str(&format!(";LAYER_CHANGE\nG1 Z{z}\n"));
        for k in 1..=n {
            e += 0.05;
            let (x, y) = pt(k);
            g.push_str(&format!("G1 X{x:.3} Y{y:.3} E{e:.5}\n"));
        }
        e += 0.5;
        g.push_str(&format!(
            "G1 X90 Y100\nG1 X110 Y100 E{e:.5}\nG1 X120 Y100\n"
        ));
    }
    for t in 0..turns {
        g.push_str(";LAYER_CHANGE\n");
        for k in 1..=n {
            e += 0.05;
            let (x, y) = pt(k);
            let z = 0.4 + 0.2 * (t as f64 + k as f64 / n as f64);
            g.push_str(&format!("G1 X{x:.3} Y{y:.3} Z{z:.3} E{e:.5}\n"));
        }
    }
    g
}

#[test]
fn spiral_turns_end_where_the_markers_are() {
    for n in [24, 360] {
        let g = vase(n, 6);
        let kept = model(&g, Comments::Keep);
        let bare = model(&g, Comments::Strip);
        assert_eq!(kept.layers().len(), 8, "n={n}");
        assert_eq!(starts(&kept), starts(&bare), "n={n}");
        // Every turn found winds once round.
        for l in &bare.layers()[3..bare.layers().len() - 1] {
            let w = l.winding_rad.expect("winding");
            assert!((w.abs() - std::f64::consts::TAU).abs() < 0.2, "{l:?}");
        }
    }
}
