//! The 3D HTML preview, opened in a real browser: Debian's Chromium, headless (WebGL 2 on its
//! software renderer), takes screenshots and dumps the DOM of a page built from G-code whose
//! every move the test wrote itself, so it knows each line's number, layer, feed and bead:
//! three vases (smooth, rippled, wide-beaded) after an MK3S-style purge line.
//!
//! - the default view draws the part in the middle (not pulled off by the purge line); pointing
//!   at a known move (the page's `hover=line:N` parameter picks through the GPU id buffer) shows
//!   its line number, feed, layer (the number `stats` gives it), ΔE and bead; the colour legend
//!   spans exactly the visible layers' feeds; an annotation in the visible layers is placed on
//!   screen and one in a hidden layer is not;
//! - a side view in one colour: the rippled wall shades with one light and dark band per
//!   ripple, the smooth wall does not, and the layers show as bands of their real height;
//! - a top view of the top layer: each wall is as wide on screen as its bead.
//!
//! Chromium comes from `scripts/setup.sh` (Debian package `chromium`). Without it the tests
//! say so and pass — except in CI (`CI` set), where a missing browser is a failure.

use host_tools::design::parts::Helix;
use host_tools::design::profile::Profile;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

fn chromium() -> Option<PathBuf> {
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        if let Ok(out) = Command::new("which").arg(name).output() {
            let p = String::from_utf8_lossy(&out.stdout).trim().to_string();
            if out.status.success() && !p.is_empty() {
                return Some(PathBuf::from(p));
            }
        }
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "chromium is missing in CI: scripts/setup.sh installs Debian's chromium"
    );
    eprintln!("SKIPPED: chromium not installed (scripts/setup.sh installs it)");
    None
}

fn tmp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ht-preview-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

const CHROMIUM_FLAGS: [&str; 6] = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--hide-scrollbars",
    "--virtual-time-budget=5000",
];

/// Opens `page?query` in a `w` × `h` window: its screenshot and its DOM after the script ran.
fn open(browser: &Path, page: &Path, query: &str, w: u32, h: u32) -> (image::RgbImage, String) {
    let png = page.with_extension(format!("{}.png", query.len()));
    let t0 = std::time::Instant::now();
    let out = Command::new(browser)
        .args(CHROMIUM_FLAGS)
        .arg(format!("--window-size={w},{h}"))
        .arg(format!("--screenshot={}", png.display()))
        .arg("--dump-dom")
        .arg(format!("file://{}?{query}", page.display()))
        .output()
        .expect("run chromium");
    eprintln!("chromium ?{query}: {:.1} s", t0.elapsed().as_secs_f64());
    let dom = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        png.exists() && dom.contains("data-ready=\"1\""),
        "the page did not finish (status {}): {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&png).expect("decode screenshot").to_rgb8();
    (img, dom)
}

/// The text of the element with `id` in a dumped DOM.
fn element_text<'a>(dom: &'a str, id: &str) -> &'a str {
    let key = format!("id=\"{id}\"");
    let at = dom.find(&key).unwrap_or_else(|| panic!("no #{id}"));
    let open = at + dom[at..].find('>').expect("tag end") + 1;
    let close = open + dom[open..].find('<').expect("text end");
    &dom[open..close]
}

/// An attribute of the element with `id`.
fn element_attr<'a>(dom: &'a str, id: &str, attr: &str) -> &'a str {
    let key = format!("id=\"{id}\"");
    let at = dom.find(&key).unwrap_or_else(|| panic!("no #{id}"));
    let tag = &dom[dom[..at].rfind('<').expect("tag")..at + dom[at..].find('>').expect("end")];
    let k = format!("{attr}=\"");
    let v = tag
        .find(&k)
        .unwrap_or_else(|| panic!("no {attr} on #{id}: {tag}"))
        + k.len();
    &tag[v..v + tag[v..].find('"').expect("quote")]
}

fn write_page(dir: &Path, g: &str, profile: &Profile) -> PathBuf {
    let page = dir.join("job.html");
    let (html, _) =
        host_tools::job::preview_html::html(g.as_bytes(), profile, "job").expect("page");
    std::fs::write(&page, html).expect("write page");
    page
}

/// A 20 mm cup-like helix on the MK3S profile (purge line, M73, markers), as G-code.
fn helix_job() -> (Profile, String) {
    let p = Profile::builtin("mk3s").expect("mk3s");
    let m = Helix {
        center_xy: [125.0, 105.0],
        z0_mm: 0.2,
        radius_mm: 10.0,
        pitch_mm: 0.3,
        turns: 60.0,
        per_turn: 90,
        cross_mm2: 0.12,
        ..Helix::default()
    }
    .build()
    .expect("helix");
    let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&m)
        .expect("write");
    (p, g)
}

/// One printing move the vase job wrote.
#[derive(Clone, Copy, Debug)]
struct Written {
    line: usize,
    layer: usize,
    vase: usize,
    feed_mm_s: f64,
    de_mm: f64,
    mid: [f64; 2],
}

const LAYERS: usize = 40;
const LAYER_MM: f64 = 0.3;
const VASE_X: [f64; 3] = [105.0, 125.0, 145.0];
const VASE_Y: f64 = 105.0;
/// Bead cross-sections, mm²: thin, thin (rippled), wide.
const CROSS_MM2: [f64; 3] = [0.12, 0.12, 0.30];
const RIPPLES: f64 = 24.0;

/// The start of an MK3S job (PrusaSlicer's): home, then a purge line along the bed's front
/// edge, outside the print area. The beads are declared stadiums (as PrusaSlicer models
/// them; the page's default is FullControl's rectangle).
const START: &str = ";AREA_MODEL:stadium\nG90\nM82\nG28\nG1 Z0.2 F720\nG1 Y-3 F1000\nG92 E0\n\
                     G1 X60 E9 F1000\nG1 X100 E12.5 F1000\nG92 E0\n";

/// Three vases printed layer by layer, written here line by line (not by the compiler), after
/// the MK3S purge line: a smooth one, one whose radius ripples ±0.25 mm 24 times round, and a
/// smooth one with a bead 2.5 times the cross-section. The k-th layer (from 0, at Z 0.3·(k+1),
/// after `;LAYER_CHANGE`) is printed at F = 60·(10 + k); two annotations, in the 6th and 21st.
fn vase_job() -> (String, Vec<Written>) {
    let area = PI * 0.25 * 1.75 * 1.75;
    let mut g = String::from(START);
    let mut moves = Vec::new();
    let mut e = 0.0;
    // Lines written so far (each `writeln!`/marker adds its own).
    let mut line = START.lines().count();
    for k in 0..LAYERS {
        let z = LAYER_MM * (k + 1) as f64;
        let _ = write!(g, ";LAYER_CHANGE\n;Z:{z:.2}\n");
        line += 2;
        let feed = 10.0 + k as f64;
        for (v, cx) in VASE_X.iter().enumerate() {
            // 0.52 mm strings on the smooth vases, 0.26 mm (8 per ripple) on the rippled one.
            let per_ring = if v == 1 { 192 } else { 96 };
            let at = |s: usize| {
                let th = 2.0 * PI * s as f64 / per_ring as f64;
                let r = 8.0
                    + if v == 1 {
                        0.25 * (RIPPLES * th).sin()
                    } else {
                        0.0
                    };
                [cx + r * th.cos(), VASE_Y + r * th.sin()]
            };
            let p0 = at(0);
            let _ = writeln!(g, "G0 X{:.3} Y{:.3} Z{z:.2} F6000", p0[0], p0[1]);
            line += 1;
            for (layer, note) in [(5, "seam of layer 5"), (20, "hidden above")] {
                if v == 1 && k == layer {
                    let _ = writeln!(g, "; ANNOTATION: {note}");
                    line += 1;
                }
            }
            let mut prev = p0;
            for s in 1..=per_ring {
                let p = at(s % per_ring);
                let len = (p[0] - prev[0]).hypot(p[1] - prev[1]);
                let de = (CROSS_MM2[v] * len / area * 1e5).round() / 1e5;
                e += de;
                let _ = writeln!(
                    g,
                    "G1 X{:.3} Y{:.3} E{e:.5} F{:.0}",
                    p[0],
                    p[1],
                    feed * 60.0
                );
                line += 1;
                moves.push(Written {
                    line,
                    layer: k,
                    vase: v,
                    feed_mm_s: feed,
                    de_mm: de,
                    mid: [(p[0] + prev[0]) / 2.0, (p[1] + prev[1]) / 2.0],
                });
                prev = p;
            }
        }
    }
    assert_eq!(g.lines().count(), line, "line numbers kept");
    (g, moves)
}

/// Luminance 0–255.
fn lum(p: &image::Rgb<u8>) -> f64 {
    let [r, g, b] = p.0;
    0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b)
}

fn is_bg(p: &image::Rgb<u8>) -> bool {
    p.0.iter().all(|&c| c > 235)
}

/// Local maxima of `v` that rise at least `prominence` above the lowest point on each side
/// before the next higher value (a simple hysteresis count).
fn peaks(v: &[f64], prominence: f64) -> usize {
    let mut n = 0;
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut rising = true;
    for &x in v {
        if rising {
            hi = hi.max(x);
            if x < hi - prominence && hi - lo >= prominence {
                n += 1;
                rising = false;
                lo = x;
            }
            lo = lo.min(x);
        } else {
            lo = lo.min(x);
            if x > lo + prominence {
                rising = true;
                hi = x;
            }
        }
    }
    n
}

/// Columns `[first, last]` of each run of part pixels in a row band.
fn runs(img: &image::RgbImage, rows: std::ops::Range<u32>, min_len: u32) -> Vec<(u32, u32)> {
    let (w, _) = img.dimensions();
    let mut out = Vec::new();
    let mut start = None;
    for x in 0..=w {
        let part = x < w && rows.clone().any(|y| !is_bg(img.get_pixel(x, y)));
        match (part, start) {
            (true, None) => start = Some(x),
            (false, Some(s)) => {
                if x - s >= min_len {
                    out.push((s, x - 1));
                }
                start = None;
            }
            _ => {}
        }
    }
    out
}

/// Side view in one colour: only the lighting of the tubes can make bands.
#[test]
fn lit_tubes_show_a_walls_ripples_and_its_layers() {
    let Some(browser) = chromium() else { return };
    let (g, _) = vase_job();
    let dir = tmp_dir("ripple");
    let page = write_page(&dir, &g, &Profile::builtin("mk3s").expect("mk3s"));
    let (img, _) = open(
        &browser,
        &page,
        "color=plain&yaw=0&pitch=0.05&zoom=1.6",
        1000,
        600,
    );
    let (_, h) = img.dimensions();
    // The three vases side by side: find them on the middle row band.
    let vases = runs(&img, h / 2 - 2..h / 2 + 2, 40);
    assert_eq!(vases.len(), 3, "three vases side by side: {vases:?}");
    // Each vase's rows (its wall's height on screen): the run of part pixels through the
    // middle row in a column.
    let rows_of = |x: u32| {
        let part = |y: u32| !is_bg(img.get_pixel(x, y));
        let (mut y0, mut y1) = (h / 2, h / 2);
        while y0 > 0 && part(y0 - 1) {
            y0 -= 1;
        }
        while y1 + 1 < h && part(y1 + 1) {
            y1 += 1;
        }
        (y0, y1)
    };
    let mut ripple_peaks = Vec::new();
    let mut profiles = Vec::new();
    for &(x0, x1) in &vases[..2] {
        let (y0, y1) = rows_of((x0 + x1) / 2);
        let (ym, band) = ((y0 + y1) / 2, (y1 - y0) / 3);
        // Brightness across the middle 70 % of the wall, averaged over the middle two thirds
        // of its height (some 26 layers, so the layer lines average out) and 3 columns.
        let span = x1 - x0;
        let profile: Vec<f64> = (x0 + span * 15 / 100..x1 - span * 15 / 100)
            .map(|x| {
                let mut sum = 0.0;
                for xx in x - 1..=x + 1 {
                    for y in ym - band..ym + band {
                        sum += lum(img.get_pixel(xx, y));
                    }
                }
                sum / f64::from(6 * band)
            })
            .collect();
        ripple_peaks.push(peaks(&profile, 6.0));
        profiles.push(
            profile
                .iter()
                .step_by(4)
                .map(|v| format!("{v:.0}"))
                .collect::<Vec<_>>()
                .join(" "),
        );
    }
    eprintln!(
        "light bands {ripple_peaks:?}\nsmooth: {}\nrippled: {}",
        profiles[0], profiles[1]
    );
    // Smooth: one bright region at most (two with the highlight); rippled: 24 ripples round,
    // of which the middle 70 % of the visible half shows about seven.
    assert!(
        ripple_peaks[0] <= 2 && ripple_peaks[1] >= 5,
        "light bands across the smooth and the rippled wall: {ripple_peaks:?}\n\
         smooth: {}\nrippled: {}",
        profiles[0],
        profiles[1]
    );
    // Layers: brightness down the smooth wall's middle column rises and falls once per layer.
    let (x0, x1) = vases[0];
    let xm = (x0 + x1) / 2;
    let (y0, y1) = rows_of(xm);
    let column: Vec<f64> = (y0 + 3..y1 - 3)
        .map(|y| {
            (xm - 2..=xm + 2)
                .map(|x| lum(img.get_pixel(x, y)))
                .sum::<f64>()
                / 5.0
        })
        .collect();
    let bands = peaks(&column, 4.0);
    eprintln!("{bands} bands down {} px", y1 - y0);
    assert!(
        (LAYERS * 3 / 4..=LAYERS * 5 / 4).contains(&bands),
        "{bands} bright bands down a wall of {LAYERS} layers ({} px high)",
        y1 - y0
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Top view of the top layer only: each wall is as wide on screen as its bead.
#[test]
fn tubes_are_as_wide_as_their_beads() {
    let Some(browser) = chromium() else { return };
    let (g, _) = vase_job();
    let dir = tmp_dir("width");
    let page = write_page(&dir, &g, &Profile::builtin("mk3s").expect("mk3s"));
    let top = layer_number(&g, LAYER_MM * LAYERS as f64);
    let (img, _) = open(
        &browser,
        &page,
        &format!("color=plain&yaw=0&pitch=1.5707&zoom=1.6&layers={top},{top}"),
        1000,
        600,
    );
    let (_, h) = img.dimensions();
    // The row through the vases' centres crosses each ring twice.
    let walls = runs(&img, h / 2..h / 2 + 1, 1);
    assert_eq!(walls.len(), 6, "two walls per vase: {walls:?}");
    let width = |k: usize| f64::from(walls[k].1 - walls[k].0 + 1);
    let centre = |k: usize| f64::from(walls[k].0 + walls[k + 1].1) / 2.0;
    // The scale from the picture itself: the outer vases' centres are 40 mm apart.
    let px_per_mm = (centre(4) - centre(0)) / (VASE_X[2] - VASE_X[0]);
    // Beads: w = A/h + h(1 − π/4) at h = 0.3 mm.
    let bead = |a: f64| a / LAYER_MM + LAYER_MM * (1.0 - PI / 4.0);
    let thin = (width(0) + width(1)) / 2.0;
    let wide = (width(4) + width(5)) / 2.0;
    eprintln!(
        "walls {walls:?}, {px_per_mm:.1} px/mm: thin {thin} px, wide {wide} px, beads {:.1} and \
         {:.1} px",
        bead(CROSS_MM2[0]) * px_per_mm,
        bead(CROSS_MM2[2]) * px_per_mm
    );
    // Each wall as wide as its bead, within the edge pixels antialiasing adds and 10 %.
    for (measured, a) in [(thin, CROSS_MM2[0]), (wide, CROSS_MM2[2])] {
        let expected = bead(a) * px_per_mm;
        assert!(
            (measured - expected).abs() <= 1.5 + 0.1 * expected,
            "a wall of a {:.3} mm bead is {measured} px wide on screen, expected {expected:.1}",
            bead(a)
        );
    }
    assert!(thin >= 3.0, "thin wall {thin} px");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The firmware's number of the layer at `z_mm`, as `host-tools stats` reports it.
fn layer_number(g: &str, z_mm: f64) -> u32 {
    let st = host_tools::job::stats::stats(g.as_bytes(), &Profile::builtin("mk3s").expect("mk3s"))
        .expect("stats");
    st.layer_times
        .iter()
        .find(|l| l.z_mm.is_some_and(|z| (z - z_mm).abs() < 1e-3))
        .unwrap_or_else(|| panic!("no layer at Z {z_mm}: {:?}", st.layer_times))
        .layer
}

/// The default view with layers 4–10 (from 0: 3–9) shown, coloured by feed, pointing at a
/// known move: the part is drawn in the middle, the readout names the move, the legend spans
/// the visible layers' feeds, and only the visible annotation is placed.
#[test]
fn default_view_hover_legend_and_annotations() {
    let Some(browser) = chromium() else { return };
    let (g, moves) = vase_job();
    let dir = tmp_dir("hover");
    let page = write_page(&dir, &g, &Profile::builtin("mk3s").expect("mk3s"));
    let z_of = |k: usize| LAYER_MM * (k + 1) as f64;
    let (n3, n9) = (layer_number(&g, z_of(3)), layer_number(&g, z_of(9)));
    // A move of the left vase in the top layer shown, on its far side from the camera.
    let target = moves
        .iter()
        .filter(|m| m.layer == 9 && m.vase == 0 && m.mid[1] > VASE_Y + 7.0)
        .nth(3)
        .copied()
        .expect("move");
    let (img, text) = open(
        &browser,
        &page,
        &format!("color=feed&layers={n3},{n9}&hover=line:{}", target.line),
        800,
        600,
    );

    // The part: saturated (coloured, not grey/black/white) pixels in the middle third, none
    // in the bottom-right corner (the purge line does not pull the view off the part).
    let (w, h) = img.dimensions();
    let coloured = |p: &image::Rgb<u8>| {
        let [r, g, b] = p.0;
        let (mx, mn) = (r.max(g).max(b), r.min(g).min(b));
        mx > 80 && mx - mn > 80
    };
    let mid = (h / 3..2 * h / 3)
        .flat_map(|y| (w / 3..2 * w / 3).map(move |x| (x, y)))
        .filter(|&(x, y)| coloured(img.get_pixel(x, y)))
        .count();
    let area = ((w / 3) * (h / 3)) as usize;
    assert!(
        mid > area / 50,
        "only {mid} coloured pixels of {area} in the middle: the part is not drawn there"
    );
    let corner = (h - h / 8..h)
        .flat_map(|y| (w - w / 8..w).map(move |x| (x, y)))
        .filter(|&(x, y)| coloured(img.get_pixel(x, y)))
        .count();
    assert_eq!(corner, 0, "coloured pixels in the bottom-right corner");

    // The readout names the move: its line, its layer (the number `stats` gives it), its
    // commanded feed, ΔE and bead, as written.
    assert_eq!(element_text(&text, "ro-line"), target.line.to_string());
    assert_eq!(element_text(&text, "ro-kind"), "printing");
    let layer = element_text(&text, "ro-layer");
    assert!(layer.starts_with(&format!("{n9} (Z 3.00 mm)")), "{layer}");
    let feed = element_text(&text, "ro-feed");
    assert!(
        feed.starts_with(&format!("{:.1} mm/s", target.feed_mm_s)),
        "{feed}"
    );
    let de: f64 = element_text(&text, "ro-e")
        .trim_end_matches(" mm")
        .parse()
        .expect("ΔE");
    // The printer reads E as f32: a few 10⁻⁵ mm off the written difference.
    assert!(
        (de - target.de_mm).abs() < 5e-5,
        "ΔE {de}, written {}",
        target.de_mm
    );
    let bead = element_text(&text, "ro-bead");
    let shown: f64 = bead
        .split(' ')
        .next()
        .and_then(|s| s.parse().ok())
        .expect("width");
    let w_mm = CROSS_MM2[0] / LAYER_MM + LAYER_MM * (1.0 - PI / 4.0);
    assert!(
        (shown - w_mm).abs() < 0.01,
        "bead {bead}, expected {w_mm:.3} wide"
    );

    // The legend spans the feeds of the visible layers (13–19 mm/s), not the job's 10–49.
    let lo: f64 = element_attr(&text, "legend-min", "data-value")
        .parse()
        .expect("min");
    let hi: f64 = element_attr(&text, "legend-max", "data-value")
        .parse()
        .expect("max");
    assert!(
        (lo - 13.0).abs() < 1e-3 && (hi - 19.0).abs() < 1e-3,
        "legend {lo}–{hi}"
    );

    // The note of the 6th layer is placed in the window; the one of the 21st (hidden) is not.
    let note = |label: &str| {
        let at = text.find(&format!(">{label}</div>")).expect("note element");
        text[text[..at].rfind("<div").expect("div")..at].to_string()
    };
    let seam = note("seam of layer 5");
    assert!(seam.contains("display: block"), "{seam}");
    let px = |k: &str| -> f64 {
        let i = seam.find(&format!("{k}: ")).expect("position") + k.len() + 2;
        seam[i..i + seam[i..].find("px").expect("px")]
            .parse()
            .expect("number")
    };
    assert!(
        (0.0..f64::from(w)).contains(&px("left")) && (0.0..f64::from(h)).contains(&px("top")),
        "{seam}"
    );
    assert!(note("hidden above").contains("display: none"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A design's annotations reach the page: `t.comment("ANNOTATION: …")` at the nozzle's
/// position there, `t.annotate(label)` at the pen's, `t.annotate(point, label)` at that point
/// (FullControl's `PlotAnnotation` with and without a point), each with its layer.
#[test]
fn a_designs_annotations_reach_the_page() {
    let p = Profile::builtin("mk3s").expect("mk3s");
    let src = r#"
        let t = turtle(100.0, 100.0, 0.2);
        t.set_width_height(0.45, 0.2);
        t.forward(10.0);
        t.comment("ANNOTATION: corner");
        t.left(90.0);
        t.forward(10.0);
        t.annotate("pen");
        t.annotate([95.5, 104.25, 3.0], "above");
        t.mark_layer(0.2);
        t.forward(5.0);
        t
    "#;
    let out = host_tools::design::script::ScriptRunner::new(p.clone())
        .run("notes.rhai", src, Path::new("."))
        .expect("script");
    let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&out.model)
        .expect("write");
    let (html, s) = host_tools::job::preview_html::html(g.as_bytes(), &p, "t").expect("page");
    assert_eq!(s.annotations, 3, "{g}");
    let line_of = |needle: &str| {
        g.lines()
            .position(|l| l.contains(needle))
            .unwrap_or_else(|| panic!("{needle} not written:\n{g}"))
            + 1
    };
    let notes_at = html.find("const NOTES = ").expect("notes") + 14;
    let notes = &html[notes_at..notes_at + html[notes_at..].find('\n').expect("end")];
    // [text, line, x, y, z, layer index]: all three on the design's first layer, before the
    // mark of the second. The page lists the start code (index 0), the profile's purge line
    // (index 1: before the first marker the firmware's height rule numbers it as a layer of
    // its own, docs/profiles.md), then the design's first layer (index 2).
    for (text, x, y, z) in [
        ("corner", "110", "100", "0.2"),
        ("pen", "110", "110", "0.2"),
        ("above", "95.5", "104.25", "3"),
    ] {
        let want = format!(
            "[\"{text}\",{},{x},{y},{z},2]",
            line_of(&format!(": {text}"))
        );
        assert!(notes.contains(&want), "{want} in {notes}");
    }
}

/// The CLI writes the page however users type it (issue 33: `preview --html OUT.gcode -o
/// page.html` failed, `--html` took the G-code for the page's name): `--html FILE -o PAGE`,
/// `FILE --html -o PAGE`, `FILE -o PAGE.html` and the older `--html PAGE FILE`; the page is
/// self-contained; a page name not ending in `.html`, or no page name, is refused.
#[test]
fn cli_writes_the_page() {
    let (_, g) = helix_job();
    let dir = tmp_dir("cli");
    let gcode = dir.join("job.gcode");
    std::fs::write(&gcode, g).expect("write gcode");
    let exe = env!("CARGO_BIN_EXE_host-tools");
    let page = dir.join("out.html");
    let (gs, ps) = (
        gcode.to_str().expect("utf-8"),
        page.to_str().expect("utf-8"),
    );
    for args in [
        vec!["--html", gs, "-o", ps],
        vec![gs, "--html", "-o", ps],
        vec!["--html", "-o", ps, gs],
        vec![gs, "-o", ps],
        vec!["--html", ps, gs],
        vec![gs, "--html", ps],
    ] {
        let _ = std::fs::remove_file(&page);
        let out = Command::new(exe)
            .args(["preview", "--profile", "mk3s"])
            .args(&args)
            .output()
            .expect("run");
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(&page).expect("page");
        assert!(
            text.starts_with("<!DOCTYPE html>") && text.contains("const MOVES = ["),
            "{args:?}"
        );
    }
    let txt = dir.join("out.txt");
    let ts = txt.to_str().expect("utf-8");
    for args in [
        vec!["--html", ts, gs],
        vec!["--html", gs],
        vec!["--html", gs, "-o", ts],
    ] {
        let bad = Command::new(exe)
            .arg("preview")
            .args(&args)
            .output()
            .expect("run");
        assert!(!bad.status.success(), "{args:?}");
        assert!(!txt.exists(), "{args:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A job without layer marks (a flat ring after a Cura-style header, which switches the
/// height rule off: no layers at all) is shown as one piece — "whole job (no layer marks)",
/// not "start–start of start" and "0 layers" (issue 33).
#[test]
fn a_page_without_layer_marks_says_so() {
    let Some(browser) = chromium() else { return };
    let mut g = String::from(";FLAVOR:Marlin\nG90\nM82\nG92 E0\nG0 X110 Y100 Z0.2 F6000\n");
    let mut e = 0.0;
    for k in 1..=48 {
        let th = 2.0 * PI * k as f64 / 48.0;
        e += 0.05;
        let _ = writeln!(
            g,
            "G1 X{:.3} Y{:.3} E{e:.4} F1200",
            100.0 + 10.0 * th.cos(),
            100.0 + 10.0 * th.sin()
        );
    }
    let dir = tmp_dir("nomarks");
    let page = write_page(&dir, &g, &Profile::builtin("ender3").expect("ender3"));
    let (_, dom) = open(&browser, &page, "", 800, 600);
    // No marker: the firmware finds the one layer from the heights (a header chooses no
    // marker family), and the page names it — never "0 layers" or "start–start".
    let range = element_text(&dom, "range");
    assert_eq!(range, "start–1 of 1");
    let info = element_text(&dom, "info");
    assert!(
        !info.contains("0 layers") && !info.contains("start–start"),
        "{info}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
