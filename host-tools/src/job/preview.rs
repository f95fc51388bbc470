//! Preview of a G-code job: top, side and isometric views side by side, printing moves
//! coloured by commanded speed or by cross-section (ΔE × filament area ÷ length), travels in
//! light grey, the bed outline, a colour scale with its range — SVG or PNG by the output's
//! extension. Drawn with `plotters` (SVG and bitmap back ends); the few labels use a built-in
//! 3 × 5 pixel font, so no system font is needed. An `.html` output is the turnable 3D page of
//! [`crate::job::preview_html`] instead.

use crate::design::profile::Profile;
use crate::gcode::read::{default_reader, Event, GcodeReader, ReadError};
use plotters::prelude::*;
use std::path::Path;

/// What colours the printing moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ColorBy {
    /// Commanded head speed, mm/s.
    Speed,
    /// Cross-section of the extruded string, mm².
    Cross,
}

/// Preview options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviewOptions {
    /// Colour source.
    pub color_by: ColorBy,
    /// Draw travels.
    pub travels: bool,
    /// Size of one view, pixels.
    pub view_px: u32,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            color_by: ColorBy::Speed,
            travels: true,
            view_px: 600,
        }
    }
}

#[derive(Clone, Copy)]
struct Seg {
    a: [f64; 3],
    b: [f64; 3],
    value: f64,
    print: bool,
}

/// Summary of what was drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviewSummary {
    /// Printing moves drawn.
    pub print_moves: usize,
    /// Travels drawn.
    pub travels: usize,
    /// Colour range (low, high).
    pub range: (f64, f64),
}

fn read_segments(input: &[u8], profile: &Profile, by: ColorBy) -> Result<Vec<Seg>, ReadError> {
    let area = profile.filament_area_mm2();
    let mut segs = Vec::new();
    default_reader().read(input, &mut |ev| {
        if let Event::Move {
            from,
            to,
            feed_mm_s,
            ..
        } = ev
        {
            let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if len < 1e-9 {
                return;
            }
            let de = to[3] - from[3];
            let print = de > 1e-9;
            let value = match by {
                ColorBy::Speed => feed_mm_s,
                ColorBy::Cross => de * area / len,
            };
            segs.push(Seg {
                a: [from[0], from[1], from[2]],
                b: [to[0], to[1], to[2]],
                value,
                print,
            });
        }
    })?;
    Ok(segs)
}

/// Colour map (viridis-like stops), t in 0..=1.
fn colormap(t: f64) -> RGBColor {
    const STOPS: [(f64, [f64; 3]); 5] = [
        (0.0, [68.0, 1.0, 84.0]),
        (0.25, [59.0, 82.0, 139.0]),
        (0.5, [33.0, 145.0, 140.0]),
        (0.75, [94.0, 201.0, 98.0]),
        (1.0, [253.0, 231.0, 37.0]),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    for w in STOPS.windows(2) {
        let (t0, c0) = w[0];
        let (t1, c1) = w[1];
        if t <= t1 {
            let f = (t - t0) / (t1 - t0);
            let c = |k: usize| (c0[k] + (c1[k] - c0[k]) * f).round() as u8;
            return RGBColor(c(0), c(1), c(2));
        }
    }
    RGBColor(253, 231, 37)
}

type Proj = fn([f64; 3]) -> (f64, f64);

fn top(p: [f64; 3]) -> (f64, f64) {
    (p[0], p[1])
}
fn side(p: [f64; 3]) -> (f64, f64) {
    (p[0], p[2])
}
fn iso(p: [f64; 3]) -> (f64, f64) {
    let c = (30f64).to_radians().cos();
    let s = 0.5;
    ((p[0] - p[1]) * c, (p[0] + p[1]) * s + p[2])
}

struct View {
    proj: Proj,
    /// Data → pixel: x' = ox + k x, y' = oy − k y.
    k: f64,
    ox: f64,
    oy: f64,
}

impl View {
    fn fit(proj: Proj, pts: &[[f64; 3]], x0: i32, size: u32, margin: f64) -> View {
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for p in pts {
            let (u, v) = proj(*p);
            lo = (lo.0.min(u), lo.1.min(v));
            hi = (hi.0.max(u), hi.1.max(v));
        }
        if !lo.0.is_finite() {
            lo = (0.0, 0.0);
            hi = (1.0, 1.0);
        }
        let avail = size as f64 - 2.0 * margin;
        let k = avail / (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-6);
        let cx = 0.5 * (lo.0 + hi.0);
        let cy = 0.5 * (lo.1 + hi.1);
        View {
            proj,
            k,
            ox: x0 as f64 + size as f64 / 2.0 - k * cx,
            oy: size as f64 / 2.0 + k * cy,
        }
    }
    fn px(&self, p: [f64; 3]) -> (i32, i32) {
        let (u, v) = (self.proj)(p);
        (
            (self.ox + self.k * u).round() as i32,
            (self.oy - self.k * v).round() as i32,
        )
    }
}

/// 3 × 5 glyphs for the labels (rows top to bottom, 3 bits each, MSB left).
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        '/' => [1, 1, 2, 4, 4],
        ':' => [0, 2, 0, 2, 0],
        'A' => [2, 5, 7, 5, 5],
        'C' => [7, 4, 4, 4, 7],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'I' => [7, 2, 2, 2, 7],
        'M' => [5, 7, 7, 5, 5],
        'O' => [7, 5, 5, 5, 7],
        'P' => [7, 5, 7, 4, 4],
        'R' => [6, 5, 6, 5, 5],
        'S' => [7, 4, 7, 1, 7],
        'T' => [7, 2, 2, 2, 2],
        'V' => [5, 5, 5, 5, 2],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        _ => [0; 5],
    }
}

fn label<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    text: &str,
    x: i32,
    y: i32,
    scale: i32,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let mut cx = x;
    for ch in text.chars() {
        let g = glyph(ch.to_ascii_uppercase());
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    let x0 = cx + col * scale;
                    let y0 = y + row as i32 * scale;
                    area.draw(&Rectangle::new(
                        [(x0, y0), (x0 + scale, y0 + scale)],
                        BLACK.filled(),
                    ))?;
                }
            }
        }
        cx += 4 * scale;
    }
    Ok(())
}

fn fmt_value(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    segs: &[Seg],
    profile: &Profile,
    o: &PreviewOptions,
) -> Result<PreviewSummary, DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let n = o.view_px;
    let b = &profile.bed;
    let bed = [
        [b.x_min_mm, b.y_min_mm, 0.0],
        [b.x_max_mm, b.y_min_mm, 0.0],
        [b.x_max_mm, b.y_max_mm, 0.0],
        [b.x_min_mm, b.y_max_mm, 0.0],
    ];
    let mut part: Vec<[f64; 3]> = Vec::new();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in segs.iter().filter(|s| s.print) {
        part.push(s.a);
        part.push(s.b);
        if s.value.is_finite() {
            lo = lo.min(s.value);
            hi = hi.max(s.value);
        }
    }
    if part.is_empty() {
        part.extend_from_slice(&bed);
    }
    if !lo.is_finite() {
        lo = 0.0;
        hi = 1.0;
    }
    let span = if hi - lo > 1e-12 { hi - lo } else { 1.0 };
    let margin = 24.0;
    let mut bed_and_part = part.clone();
    bed_and_part.extend_from_slice(&bed);
    let views = [
        ("TOP", View::fit(top, &bed_and_part, 0, n, margin)),
        ("SIDE", View::fit(side, &part, n as i32, n, margin)),
        ("ISO", View::fit(iso, &part, 2 * n as i32, n, margin)),
    ];
    // Colour buckets: consecutive segments of one bucket become one polyline.
    const BUCKETS: usize = 48;
    let bucket = |v: f64| (((v - lo) / span) * (BUCKETS - 1) as f64).round() as usize;
    let mut summary = PreviewSummary {
        print_moves: 0,
        travels: 0,
        range: (lo, hi),
    };
    for (vi, (name, view)) in views.iter().enumerate() {
        let panel = root.clone().shrink((vi as u32 * n, 0), (n, n));
        let x0 = (vi as u32 * n) as i32;
        // Bed outline (a line at z = 0 in the side view).
        let mut outline: Vec<(i32, i32)> = bed.iter().map(|p| view.px(*p)).collect();
        if let Some(first) = outline.first().copied() {
            outline.push(first);
        }
        let to_panel = |(x, y): (i32, i32)| (x - x0, y);
        for w in outline.windows(2) {
            let (a, b) = (to_panel(w[0]), to_panel(w[1]));
            if let Some((a, b)) = clip(a, b, n as i32) {
                panel.draw(&PathElement::new(
                    vec![a, b],
                    RGBColor(150, 150, 150).stroke_width(2),
                ))?;
            }
        }
        let mut line: Vec<(i32, i32)> = Vec::new();
        let mut cur: Option<(bool, usize)> = None;
        let flush = |line: &mut Vec<(i32, i32)>,
                     cur: Option<(bool, usize)>|
         -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
            if line.len() >= 2 {
                let style = match cur {
                    Some((true, k)) => colormap(k as f64 / (BUCKETS - 1) as f64).stroke_width(1),
                    _ => RGBColor(205, 205, 205).stroke_width(1),
                };
                panel.draw(&PathElement::new(std::mem::take(line), style))?;
            }
            line.clear();
            Ok(())
        };
        for s in segs {
            if !s.print && !o.travels {
                continue;
            }
            let key = (s.print, if s.print { bucket(s.value) } else { 0 });
            let a = to_panel(view.px(s.a));
            let b = to_panel(view.px(s.b));
            if cur != Some(key) || line.last() != Some(&a) {
                flush(&mut line, cur)?;
                cur = Some(key);
                line.push(a);
            }
            if line.last() != Some(&b) {
                line.push(b);
            }
            if vi == 0 {
                if s.print {
                    summary.print_moves += 1;
                } else {
                    summary.travels += 1;
                }
            }
        }
        flush(&mut line, cur)?;
        label(&panel, name, 8, 8, 3)?;
    }
    // Colour scale along the bottom of the top view.
    let bar_y = n as i32 - 18;
    for i in 0..200 {
        root.draw(&Rectangle::new(
            [(60 + i, bar_y), (61 + i, bar_y + 10)],
            colormap(i as f64 / 199.0).filled(),
        ))?;
    }
    let unit = match o.color_by {
        ColorBy::Speed => "MM/S",
        ColorBy::Cross => "MM2",
    };
    label(&root, &fmt_value(lo), 8, bar_y, 2)?;
    label(&root, &format!("{} {unit}", fmt_value(hi)), 266, bar_y, 2)?;
    root.present()?;
    Ok(summary)
}

/// Clips the segment a–b to the square 0..n (Liang–Barsky).
fn clip(a: (i32, i32), b: (i32, i32), n: i32) -> Option<((i32, i32), (i32, i32))> {
    let (x0, y0) = (a.0 as f64, a.1 as f64);
    let (dx, dy) = ((b.0 - a.0) as f64, (b.1 - a.1) as f64);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let max = (n - 1) as f64;
    for (p, q) in [(-dx, x0), (dx, max - x0), (-dy, y0), (dy, max - y0)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| ((x0 + dx * t).round() as i32, (y0 + dy * t).round() as i32);
    Some((at(t0), at(t1)))
}

/// Renders `input` to `out` (`.svg` or `.png`).
pub fn render(
    input: &[u8],
    profile: &Profile,
    out: &Path,
    o: &PreviewOptions,
) -> anyhow::Result<PreviewSummary> {
    let ext = out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if matches!(ext.as_str(), "html" | "htm") {
        // The turnable 3D page (job::preview_html); colour and travels are chosen in it.
        let title = out
            .file_stem()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let (page, s) = crate::job::preview_html::html(input, profile, &title)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        crate::fileio::write_bytes(out, page.as_bytes())?;
        return Ok(PreviewSummary {
            print_moves: s.print_moves,
            travels: s.travels,
            range: (0.0, s.time_s),
        });
    }
    let segs = read_segments(input, profile, o.color_by).map_err(|e| anyhow::anyhow!("{e}"))?;
    let size = (3 * o.view_px, o.view_px);
    // Drawn in memory, then written with the safe output writer (never half a picture, never
    // a device or link replaced by a regular file).
    let (bytes, summary) = match ext.as_str() {
        "svg" => {
            let mut text = String::new();
            let s = {
                let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                draw(root, &segs, profile, o).map_err(|e| anyhow::anyhow!("drawing SVG: {e}"))?
            };
            (text.into_bytes(), s)
        }
        "png" => {
            let mut rgb = vec![0u8; 3 * size.0 as usize * size.1 as usize];
            let s = {
                let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
                draw(root, &segs, profile, o).map_err(|e| anyhow::anyhow!("drawing PNG: {e}"))?
            };
            let img = image::RgbImage::from_raw(size.0, size.1, rgb)
                .ok_or_else(|| anyhow::anyhow!("drawing PNG: buffer size"))?;
            let mut png = std::io::Cursor::new(Vec::new());
            img.write_to(&mut png, image::ImageFormat::Png)
                .map_err(|e| anyhow::anyhow!("encoding PNG: {e}"))?;
            (png.into_inner(), s)
        }
        _ => anyhow::bail!(
            "{}: the output must end in .svg, .png or .html",
            out.display()
        ),
    };
    crate::fileio::write_bytes(out, &bytes)?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colormap_ends() {
        assert_eq!(colormap(0.0), RGBColor(68, 1, 84));
        assert_eq!(colormap(1.0), RGBColor(253, 231, 37));
        assert_eq!(colormap(f64::NAN), RGBColor(68, 1, 84));
    }

    #[test]
    fn renders_svg_and_png() {
        let g = b"G0 X100 Y100 Z0.2 F6000\nG1 X120 E1 F1200\nG1 Y120 E2 F2400\nG0 X50 Y50\n";
        let dir = std::env::temp_dir().join(format!("ht-preview-{}", std::process::id()));
        std::fs::create_dir_all(&dir).ok();
        let p = Profile::ender3();
        let svg = dir.join("a.svg");
        let s = render(g, &p, &svg, &PreviewOptions::default()).expect("svg");
        assert_eq!(s.print_moves, 2);
        assert_eq!(s.travels, 2);
        assert_eq!(s.range, (20.0, 40.0));
        let text = std::fs::read_to_string(&svg).unwrap_or_default();
        assert!(text.starts_with("<svg"));
        let png = dir.join("a.png");
        render(g, &p, &png, &PreviewOptions::default()).expect("png");
        let img = image::open(&png).expect("decode");
        assert_eq!(img.width(), 1800);
        assert!(render(g, &p, &dir.join("a.txt"), &PreviewOptions::default()).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
