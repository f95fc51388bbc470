//! Pictures (SVG, via plotters; no system fonts needed): stop time against move length per
//! policy for `sim lab`, and the toolpath with the stop points for `sim demo`.

use plotters::prelude::*;
use std::path::Path;

/// One line of the stop-time plot.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend.
    pub label: String,
    /// (move length mm, stop time s), sorted by length.
    pub points: Vec<(f64, f64)>,
}

const COLORS: [RGBColor; 8] = [
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

/// Log-log plot of stop time against move length.
pub fn stop_time_plot(path: &Path, title: &str, series: &[Series]) -> anyhow::Result<()> {
    let mut xs = series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let first = xs.next().unwrap_or(1.0);
    let (mut x0, mut x1) = (first, first);
    for x in xs {
        x0 = x0.min(x);
        x1 = x1.max(x);
    }
    let ys: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .filter(|y| *y > 0.0)
        .collect();
    let y0 = ys.iter().copied().fold(f64::INFINITY, f64::min).min(0.01) * 0.8;
    let y1 = ys.iter().copied().fold(0.0, f64::max).max(1.0) * 1.5;
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (x0 * 0.8..x1 * 1.25).log_scale(),
            (y0.max(1e-4)..y1).log_scale(),
        )
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("move length L, mm")
        .y_desc("stop time after the request, s")
        .draw()
        .map_err(err)?;
    for (i, s) in series.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .map(|&(x, y)| (x, y.max(y0.max(1e-4))))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
            .map_err(err)?
            .label(s.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))
            .map_err(err)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// A marker on the toolpath picture.
#[derive(Clone, Debug)]
pub struct Marker {
    /// Legend.
    pub label: String,
    /// Position, mm.
    pub xy: (f64, f64),
}

/// The toolpath (printing moves dark, travel light) with markers, readable at a glance: the
/// view is the printed part and the markers (a travel leaving it, from the job's start, is
/// cut at the frame), the legend stands beside the plot (it covers nothing), and markers are
/// drawn as rings that shrink in legend order, so stop points on the same spot all show.
pub fn toolpath_plot(
    path: &Path,
    title: &str,
    printing: &[Vec<(f64, f64)>],
    travel: &[Vec<(f64, f64)>],
    markers: &[Marker],
) -> anyhow::Result<()> {
    let all = printing
        .iter()
        .flatten()
        .chain(markers.iter().map(|m| &m.xy));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    // A square view (mm the same both ways) around the part, a little margin.
    let side = (x1 - x0).max(y1 - y0).max(1.0) * 1.12;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (vx0, vx1, vy0, vy1) = (
        cx - side / 2.0,
        cx + side / 2.0,
        cy - side / 2.0,
        cy + side / 2.0,
    );
    let inside = |&(x, y): &(f64, f64)| x >= vx0 && x <= vx1 && y >= vy0 && y <= vy1;
    let root = SVGBackend::new(path, (1180, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let (left, right) = root.split_horizontally(800);
    let mut chart = ChartBuilder::on(&left)
        .caption(title, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(vx0..vx1, vy0..vy1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("X, mm")
        .y_desc("Y, mm")
        .light_line_style(WHITE)
        .draw()
        .map_err(err)?;
    for t in travel {
        // Travel inside the view only (the move from the job's start is cut off).
        if t.iter().all(inside) {
            chart
                .draw_series(LineSeries::new(t.clone(), RGBColor(170, 170, 210)))
                .map_err(err)?;
        }
    }
    for p in printing {
        chart
            .draw_series(LineSeries::new(
                p.clone(),
                RGBColor(60, 60, 60).stroke_width(1),
            ))
            .map_err(err)?;
    }
    let n = markers.len() as i32;
    for (i, m) in markers.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        // Largest first: a later marker on the same spot sits inside the earlier ones.
        let r = 6 + 4 * (n - i as i32);
        chart
            .draw_series(std::iter::once(Circle::new(m.xy, r, c.stroke_width(3))))
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(Circle::new(m.xy, 3, c.filled())))
            .map_err(err)?;
    }
    // The legend, beside the plot.
    let font = ("sans-serif", 15).into_font();
    for (i, m) in markers.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        let y = 70 + 34 * i as i32;
        right
            .draw(&Circle::new((22, y), 9, c.stroke_width(3)))
            .map_err(err)?;
        right
            .draw(&Circle::new((22, y), 3, c.filled()))
            .map_err(err)?;
        right
            .draw(&Text::new(m.label.clone(), (40, y - 8), font.clone()))
            .map_err(err)?;
    }
    let key_y = 80 + 34 * n;
    right
        .draw(&PathElement::new(
            vec![(12, key_y), (34, key_y)],
            RGBColor(60, 60, 60).stroke_width(2),
        ))
        .map_err(err)?;
    right
        .draw(&Text::new("printing moves", (40, key_y - 8), font.clone()))
        .map_err(err)?;
    right
        .draw(&PathElement::new(
            vec![(12, key_y + 26), (34, key_y + 26)],
            RGBColor(170, 170, 210).stroke_width(2),
        ))
        .map_err(err)?;
    right
        .draw(&Text::new("travel", (40, key_y + 18), font))
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_svg_files() {
        let dir = std::env::temp_dir().join(format!("sim-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("stop.svg");
        stop_time_plot(
            &p,
            "t",
            &[Series {
                label: "fifo".into(),
                points: vec![(1.0, 0.5), (100.0, 53.3)],
            }],
        )
        .unwrap();
        let s = std::fs::read_to_string(&p).unwrap();
        assert!(s.contains("<svg") && s.contains("fifo"));
        let q = dir.join("path.svg");
        toolpath_plot(
            &q,
            "t",
            &[vec![(0.0, 0.0), (10.0, 0.0)]],
            &[],
            &[Marker {
                label: "stop".into(),
                xy: (5.0, 0.0),
            }],
        )
        .unwrap();
        assert!(std::fs::read_to_string(&q).unwrap().contains("stop"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
