//! What the cure check found, for people: the text summary (every violation, the layers with
//! violations) and the heat map (rows = layers, columns = progress through the layer, colour
//! = shortest elapsed time relative to the cure time). The check itself is
//! [`crate::paste::cure`].

use crate::paste::cure::CureReport;
use crate::paste::timebased::Sample;

/// Text summary (and every violation when `list` is set).
pub fn summary(r: &CureReport, list: bool) -> String {
    let mut out = String::new();
    if list {
        for v in &r.violations {
            out.push_str(&format!(
                "violation: layer {} at ({:.2}, {:.2}, {:.2}) t={:.1} s: {:.1} s after the material below (needs {:.1} s)\n",
                v.layer,
                v.x,
                v.y,
                v.z,
                v.index as f64 * r.period_s,
                v.elapsed_s,
                r.cure_s
            ));
        }
    }
    out.push_str(&format!(
        "{} samples ({} deposited, {} on material below); {} spots below the cure time of {:.1} s; shortest elapsed {}\n",
        r.samples,
        r.deposited,
        r.supported,
        r.violation_count,
        r.cure_s,
        r.min_elapsed_s
            .map_or("n/a (nothing is laid on earlier material)".to_string(), |m| format!("{m:.1} s"))
    ));
    let bad: Vec<String> = r
        .layers
        .iter()
        .filter(|l| l.violations > 0)
        .map(|l| {
            format!(
                "{} ({} spots, min {:.1} s)",
                l.layer,
                l.violations,
                l.min_elapsed_s.unwrap_or(0.0)
            )
        })
        .collect();
    if !bad.is_empty() {
        out.push_str(&format!("layers with violations: {}\n", bad.join(", ")));
    }
    out
}

/// Heat map (SVG): one row per layer (bottom layer at the bottom), columns the progress
/// through the layer in 200 bins; colour the shortest elapsed time in the bin relative to the
/// cure time (red below it, yellow at it, green at 3× and beyond); grey where nothing is below.
pub fn heat_map_svg(samples: &[Sample], r: &CureReport) -> String {
    const BINS: usize = 200;
    let (w, row_h) = (800.0, 6.0f64);
    // Indices of deposited samples per layer.
    let mut per_layer: Vec<Vec<usize>> = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        if s.extruding {
            let l = s.layer as usize;
            if per_layer.len() <= l {
                per_layer.resize(l + 1, Vec::new());
            }
            per_layer[l].push(i);
        }
    }
    let rows: Vec<(usize, &Vec<usize>)> = per_layer
        .iter()
        .enumerate()
        .filter(|(_, v)| !v.is_empty())
        .collect();
    let row_h = if rows.len() as f64 * row_h > 900.0 {
        (900.0 / rows.len().max(1) as f64).max(0.5)
    } else {
        row_h
    };
    let h = rows.len() as f64 * row_h;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{:.0}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        w + 160.0,
        h + 70.0
    );
    svg.push_str(&format!(
        "<text x=\"60\" y=\"16\">elapsed time over the material below, per layer (cure {:.1} s; {} violations)</text>\n",
        r.cure_s, r.violation_count
    ));
    for (row, (layer, idx)) in rows.iter().enumerate() {
        let y = 30.0 + h - (row as f64 + 1.0) * row_h;
        let mut bins: Vec<Option<f64>> = vec![None; BINS];
        let mut seen = [false; BINS];
        for (k, &i) in idx.iter().enumerate() {
            let b = k * BINS / idx.len();
            seen[b] = true;
            if let Some(e) = r.elapsed_s[i] {
                bins[b] = Some(bins[b].map_or(e, |m: f64| m.min(e)));
            }
        }
        for b in 0..BINS {
            if !seen[b] {
                continue;
            }
            let color = match bins[b] {
                None => "#d0d0d0".to_string(),
                Some(e) => heat_color(e / r.cure_s.max(1e-9)),
            };
            svg.push_str(&format!(
                "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"{}\"/>\n",
                60.0 + b as f64 * w / BINS as f64,
                y,
                w / BINS as f64 + 0.05,
                row_h + 0.05,
                color
            ));
        }
        if row % (20.0 / row_h).ceil().max(1.0) as usize == 0 {
            svg.push_str(&format!(
                "<text x=\"4\" y=\"{:.1}\">L{}</text>\n",
                y + row_h,
                layer
            ));
        }
    }
    // Legend.
    let ly = h + 45.0;
    for k in 0..=30 {
        let ratio = k as f64 / 10.0;
        svg.push_str(&format!(
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"{}\"/>\n",
            60.0 + k as f64 * 10.0,
            ly,
            heat_color(ratio)
        ));
    }
    svg.push_str(&format!(
        "<text x=\"60\" y=\"{:.1}\">0</text><text x=\"155\" y=\"{:.1}\">cure</text><text x=\"355\" y=\"{:.1}\">3× cure</text><rect x=\"420\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"#d0d0d0\"/><text x=\"435\" y=\"{:.1}\">nothing below</text>\n</svg>\n",
        ly + 24.0, ly + 24.0, ly + 24.0, ly, ly + 10.0
    ));
    svg
}

/// Red below 1, red→yellow→green from 1 to 3.
fn heat_color(ratio: f64) -> String {
    if ratio < 1.0 {
        let k = (ratio.max(0.0) * 120.0) as u8;
        return format!("rgb({},{},{})", 200 + k / 3, k / 3, k / 3);
    }
    let t = ((ratio - 1.0) / 2.0).clamp(0.0, 1.0);
    let (r, g) = if t < 0.5 {
        (255.0, 180.0 + 150.0 * t)
    } else {
        (
            255.0 * (1.0 - (t - 0.5) * 2.0) + 60.0 * (t - 0.5) * 2.0,
            255.0 - 75.0 * (t - 0.5) * 2.0,
        )
    };
    format!("rgb({:.0},{:.0},60)", r.min(255.0), g.min(255.0))
}
