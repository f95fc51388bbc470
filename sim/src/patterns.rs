//! Built-in jobs, written as ordinary G-code text so they go through the same host link and
//! front end as any file: the paper's zigzag for the latency lab and the demo part.

use std::fmt::Write as _;

/// Filament per mm of a 0.4 × 0.2 mm line of 1.75 mm filament (mm/mm).
pub const E_PER_MM: f64 = 0.4 * 0.2 / (std::f64::consts::PI * 0.875 * 0.875);

/// The paper's latency experiment: lines of equal length `len_mm` at `feed_mm_s`.
///
/// The lines zigzag ±`half_angle_deg` about the row direction (so consecutive lines meet at a
/// shallow corner the planner can take at full speed, as in the paper's arithmetic
/// 16 × L / v) and the row turns back (a full stop) when the next line would leave the
/// `area_mm` square. Each layer has `lines_per_layer` lines; `layers` layers are printed, each
/// with a `;LAYER_CHANGE` comment and a Z rise, so `layer` pauses have boundaries to stop at.
#[derive(Clone, Debug, PartialEq)]
pub struct Zigzag {
    /// Length of every line, mm.
    pub len_mm: f64,
    /// Print speed, mm/s (the paper: 30).
    pub feed_mm_s: f64,
    /// Lines per layer.
    pub lines_per_layer: usize,
    /// Number of layers.
    pub layers: usize,
    /// Zigzag half angle, degrees (lines at ±this about the row direction).
    pub half_angle_deg: f64,
    /// Side of the square the pattern stays in, mm, starting at (10, 10).
    pub area_mm: f64,
    /// Layer height, mm.
    pub layer_h_mm: f64,
}

impl Zigzag {
    /// The lab's default zigzag for line length `len_mm` at 30 mm/s.
    pub fn paper(len_mm: f64) -> Self {
        Self {
            len_mm,
            feed_mm_s: 30.0,
            lines_per_layer: 30,
            layers: 2,
            half_angle_deg: 5.0,
            area_mm: 200.0,
            layer_h_mm: 0.2,
        }
    }

    /// The G-code, one entry per line. Returns the lines and, for each layer, the index of its
    /// first printing line (the lab sends its pause request during line 3 of layer 0).
    pub fn gcode(&self) -> (Vec<String>, Vec<Vec<usize>>) {
        let mut out = vec![
            "; sim zigzag: lines of equal length".to_string(),
            format!("; L = {:.3} mm at {:.1} mm/s", self.len_mm, self.feed_mm_s),
            "G21".into(),
            "G90".into(),
            "M83".into(),
            "G92 X10 Y10 Z0 E0".into(),
        ];
        let mut print_lines = Vec::new();
        let (x0, y0) = (10.0, 10.0);
        let lim = x0 + self.area_mm;
        let ang = self.half_angle_deg.to_radians();
        let dx = self.len_mm * ang.cos();
        let dy = self.len_mm * ang.sin();
        let f = self.feed_mm_s * 60.0;
        for layer in 0..self.layers {
            let z = self.layer_h_mm * (layer as f64 + 1.0);
            out.push(";LAYER_CHANGE".into());
            out.push(format!(";Z:{z:.3}"));
            out.push(format!("G1 Z{z:.3} F600"));
            let (mut x, mut y) = (x0, y0 + 2.0 * layer as f64);
            out.push(format!("G1 X{x:.4} Y{y:.4} F6000"));
            let mut dir = 1.0;
            let mut up = true;
            let mut idx = Vec::new();
            for _ in 0..self.lines_per_layer {
                let mut nx = x + dir * dx;
                if nx > lim || nx < x0 {
                    dir = -dir;
                    nx = x + dir * dx;
                }
                let ny = if up { y + dy } else { y - dy };
                up = !up;
                idx.push(out.len());
                out.push(format!(
                    "G1 X{nx:.4} Y{ny:.4} E{:.5} F{f:.0}",
                    self.len_mm * E_PER_MM
                ));
                x = nx;
                y = ny;
            }
            print_lines.push(idx);
        }
        out.push(";END".into());
        out.push("G1 Z20 F600".into());
        (out, print_lines)
    }
}

/// The demo part: a 30 × 30 mm square, `layers` layers of two perimeters and a diagonal-free
/// zigzag infill (long lines, where a conventional pause is slow), PrusaSlicer-style comments.
pub fn demo_part(layers: usize) -> Vec<String> {
    demo_part_sized(layers, 30.0)
}

/// [`demo_part`] with a square of `side` mm (the demo's emulated board prints a 10 mm one:
/// the same moves, a ninth of the time).
pub fn demo_part_sized(layers: usize, side: f64) -> Vec<String> {
    let mut g = String::new();
    let _ = writeln!(
        g,
        "; sim demo part: {side} x {side} mm square, {layers} layers"
    );
    for l in ["G21", "G90", "M83", "G92 X0 Y0 Z0 E0", "G1 Z2 F600"] {
        let _ = writeln!(g, "{l}");
    }
    let (x0, y0) = (100.0f64, 100.0f64);
    let h = 0.2;
    let spacing = 0.45;
    for layer in 0..layers {
        let z = h * (layer as f64 + 1.0);
        let _ = writeln!(g, ";LAYER_CHANGE");
        let _ = writeln!(g, ";Z:{z:.2}");
        let _ = writeln!(g, "G1 E-0.8 F2100");
        let _ = writeln!(g, "G1 Z{z:.2} F600");
        for (k, inset) in [0.0f64, spacing].iter().enumerate() {
            let (a, b) = (x0 + inset, x0 + side - inset);
            let (c, d) = (y0 + inset, y0 + side - inset);
            let _ = writeln!(
                g,
                ";TYPE:{}",
                if k == 0 {
                    "External perimeter"
                } else {
                    "Perimeter"
                }
            );
            let _ = writeln!(g, "G1 X{a:.3} Y{c:.3} F9000");
            if k == 0 {
                let _ = writeln!(g, "G1 E0.8 F2100");
            }
            let len = side - 2.0 * inset;
            let e = len * E_PER_MM;
            let _ = writeln!(g, "G1 X{b:.3} Y{c:.3} E{e:.5} F1800");
            let _ = writeln!(g, "G1 X{b:.3} Y{d:.3} E{e:.5}");
            let _ = writeln!(g, "G1 X{a:.3} Y{d:.3} E{e:.5}");
            let _ = writeln!(g, "G1 X{a:.3} Y{c:.3} E{e:.5}");
        }
        let _ = writeln!(g, ";TYPE:Solid infill");
        let inner = 2.0 * spacing;
        let (a, b) = (x0 + inner, x0 + side - inner);
        let n = ((side - 2.0 * inner) / spacing).floor() as usize;
        let horizontal = layer % 2 == 0;
        let len = side - 2.0 * inner;
        let e = len * E_PER_MM;
        let _ = writeln!(g, "G1 X{a:.3} Y{a:.3} F9000", a = a);
        for i in 0..=n {
            let p = x0 + inner + i as f64 * spacing;
            let (s, t) = if i % 2 == 0 { (a, b) } else { (b, a) };
            if horizontal {
                let _ = writeln!(g, "G1 X{s:.3} Y{p:.3} F9000");
                let _ = writeln!(g, "G1 X{t:.3} Y{p:.3} E{e:.5} F3600");
            } else {
                let _ = writeln!(g, "G1 X{p:.3} Y{s:.3} F9000");
                let _ = writeln!(g, "G1 X{p:.3} Y{t:.3} E{e:.5} F3600");
            }
        }
    }
    let _ = writeln!(g, ";END");
    let _ = writeln!(g, "G1 E-0.8 F2100");
    let _ = writeln!(g, "G1 Z20 F600");
    g.lines().map(str::to_string).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zigzag_lines_have_equal_length_and_stay_on_the_bed() {
        let z = Zigzag::paper(100.0);
        let (lines, idx) = z.gcode();
        assert_eq!(idx.len(), 2);
        assert_eq!(idx[0].len(), 30);
        let mut prev: Option<(f64, f64)> = None;
        for &i in &idx[0] {
            let words: Vec<&str> = lines[i].split_whitespace().collect();
            let x: f64 = words[1][1..].parse().unwrap();
            let y: f64 = words[2][1..].parse().unwrap();
            assert!((10.0..=210.0001).contains(&x), "{x}");
            if let Some((px, py)) = prev {
                let d = ((x - px).powi(2) + (y - py).powi(2)).sqrt();
                assert!((d - 100.0).abs() < 1e-3, "{d}");
            }
            prev = Some((x, y));
        }
    }

    #[test]
    fn demo_part_has_layers() {
        let g = demo_part(3);
        assert_eq!(g.iter().filter(|l| *l == ";LAYER_CHANGE").count(), 3);
    }
}
