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

#[test]
fn every_family_with_or_without_a_space_and_headers_choose_nothing() {
    for (a, b, family) in [
        (";LAYER_CHANGE", "; LAYER_CHANGE", read::Family::Prusa),
        (";CHANGE_LAYER", "; CHANGE_LAYER", read::Family::Bambu),
        (";LAYER:0", "; LAYER:1", read::Family::Cura),
        (
            "; layer 1, Z = 0.2",
            ";layer 2, Z = 0.4",
            read::Family::Simplify3d,
        ),
        (";layer:0.20", "; layer:0.20", read::Family::FlashPrint),
        (
            "; BEGIN_LAYER_OBJECT z=0.2",
            ";BEGIN_LAYER_OBJECT z=0.4",
            read::Family::KisSlicer,
        ),
        (
            ";; --- layer 0 (0.2 @ 0.2) ---",
            "; --- layer 1 (0.2 @ 0.4) ---",
            read::Family::KiriMoto,
        ),
        ("; <layer>", ";<layer>", read::Family::IceSl),
    ] {
        // Behind a header of another slicer (Orca's for a Bambu printer): the markers count.
        let g = format!(
            "; generated by OrcaSlicer 2.3.0\n{a}\nG1 Z0.2\nG1 X5 E1\n{b}\nG1 Z0.4\nG1 X6 E2"
        );
        let m = model(&g, Comments::Keep);
        assert_eq!(starts(&m), vec![(1, 3), (2, 6)], "{a} / {b}");
        assert!(
            m.layers()
                .iter()
                .all(|l| l.source == Source::Marker(family)),
            "{a}"
        );
    }
    // Not markers.
    for c in [
        ";LAYER_COUNT:3",
        "; END_LAYER_OBJECT z=0.2",
        "; </layer>",
        ";layer:3",
    ] {
        let g = format!("{c}\nG1 Z0.2\nG1 X5 E1\nG1 Z0.4\nG1 X6 E2");
        assert!(model(&g, Comments::Keep)
            .layers()
            .iter()
            .all(|l| l.source == Source::Height));
    }
}

/// A square loop of side `s` mm at `z` from (x, y).
fn square(x: f64, y: f64, s: f64, z: f64) -> String {
    format!(
        "G1 X{x} Y{y} Z{z}\nG1 X{} E1\nG1 Y{} E1\nG1 X{x} E1\nG1 Y{y} E1\n",
        x + s,
        y + s
    )
}

#[test]
fn purge_lines_below_at_and_above_the_first_layer_are_preludes() {
    for z in [0.2, 0.3, 0.45] {
        let g = format!(
            "M83\nG1 X0 Y2 Z{z}\nG1 X60 E9\nG1 X100 E3.5\n{}{}",
            square(80.0, 80.0, 20.0, 0.3),
            square(80.0, 80.0, 20.0, 0.6)
        );
        let m = model(&g, Comments::Strip);
        assert_eq!(starts(&m), vec![(0, 2), (1, 5), (2, 10)], "purge at {z}");
    }
    // A first layer that is a loop stays layer 1.
    let g = format!(
        "M83\n{}{}{}",
        square(10.0, 10.0, 30.0, 0.3),
        square(80.0, 80.0, 20.0, 0.3),
        square(80.0, 80.0, 20.0, 0.6)
    );
    assert_eq!(starts(&model(&g, Comments::Strip)), vec![(1, 2), (2, 12)]);
}

#[test]
fn levelling_baked_into_the_file_keeps_the_layers() {
    // 1 mm pieces, Z = layer height + a plane (0.1 mm per 100 mm in X, 0.05 in Y).
    let plane = |x: f64, y: f64| 0.001 * x + 0.0005 * y;
    let mut g = String::from("M83\n");
    for layer in 1..=4 {
        let z = 0.1 + 0.2 * f64::from(layer);
        let c = [
            (40.0, 40.0),
            (60.0, 40.0),
            (60.0, 60.0),
            (40.0, 60.0),
            (40.0, 40.0),
        ];
        g.push_str(&format!("G1 X40 Y40 Z{:.4}\n", z + plane(40.0, 40.0)));
        for w in c.windows(2) {
            for k in 1..=20 {
                let t = f64::from(k) / 20.0;
                let (x, y) = (
                    w[0].0 + (w[1].0 - w[0].0) * t,
                    w[0].1 + (w[1].1 - w[0].1) * t,
                );
                g.push_str(&format!(
                    "G1 X{x:.3} Y{y:.3} Z{:.4} E0.05\n",
                    z + plane(x, y)
                ));
            }
        }
    }
    let m = model(&g, Comments::Strip);
    let numbers: Vec<u32> = m.layers().iter().map(|l| l.number).collect();
    assert_eq!(numbers, vec![1, 2, 3, 4]);
}
