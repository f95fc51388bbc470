//! `host-tools grow`: differential growth filling a region with one continuous stroke.

use super::range::{count, within, LAYER_MM, LINE_WIDTH_MM, SIZE_MM, SPEED_MM_S};
use crate::design::profile::Profile;
use crate::design::writer::{GcodeWriter, WriteOptions};
use crate::paste::grow::{
    builtin_boundary, grow, read_boundary, to_model, verify_simple, Boundary, GrowParams,
    StackParams,
};
use anyhow::Context;
use glam::DVec2;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `host-tools grow`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Boundary: `circle`, `square`, `blob`, or a file (SVG polygon/polyline/path, or `x y`
    /// lines).
    #[arg(long)]
    pub boundary: String,
    /// Size of a built-in boundary (diameter or side), mm.
    #[arg(long, default_value_t = 120.0, value_parser = within(0.1, SIZE_MM))]
    pub size: f64,
    /// Covered fraction of the area, 0 < d ≤ 1: stroke spacing = line width ÷ density.
    #[arg(long, default_value_t = 0.5)]
    pub density: f64,
    /// Extruded line width, mm (paste printers: about 10).
    #[arg(long, default_value_t = 0.45, value_parser = within(LINE_WIDTH_MM.0, LINE_WIDTH_MM.1))]
    pub line_width: f64,
    /// Layers to stack (at most 100 000).
    #[arg(long, default_value_t = 1, value_parser = count(1, 100_000))]
    pub layers: usize,
    /// Layer height, mm.
    #[arg(long, default_value_t = 0.2, value_parser = within(LAYER_MM.0, LAYER_MM.1))]
    pub layer_height: f64,
    /// Stop growing at this many nodes (also stops when the region is full; at most 5 000 000).
    #[arg(long, default_value_t = 50_000, value_parser = count(3, 5_000_000))]
    pub nodes: usize,
    /// Iteration limit (at most 10 000 000).
    #[arg(long, default_value_t = 20_000, value_parser = count(1, 10_000_000))]
    pub max_iterations: usize,
    /// Print speed, mm/s (paste, ArchiFAB-like: 16.7 = 1000 mm/min).
    #[arg(long, default_value_t = 25.0, value_parser = within(SPEED_MM_S.0, SPEED_MM_S.1))]
    pub speed: f64,
    /// Printer profile: built-in name or TOML path (e.g. host-tools/profiles/paste.toml).
    #[arg(long, default_value = "ender3")]
    pub printer: String,
    /// Seed of the symmetry-breaking jitter.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output G-code.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the stroke inside its boundary as an SVG drawing.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Also render the G-code with `preview` (top, side, isometric) to this .svg/.png.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Most strings (nodes × layers) one growth job may write.
pub const MAX_STRINGS: usize = 20_000_000;

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    let outputs: Vec<&Path> = std::iter::once(a.output.as_path())
        .chain(a.svg.as_deref())
        .chain(a.preview.as_deref())
        .collect();
    crate::fileio::refuse_inputs_as_outputs(
        &outputs,
        &[Path::new(&a.boundary), Path::new(&a.printer)],
    )?;
    if !(a.density > 0.0 && a.density <= 1.0) {
        anyhow::bail!("--density must be in (0, 1], got {}", a.density);
    }
    // Every layer repeats the whole stroke: bound the strings written.
    if a.nodes.saturating_mul(a.layers) > MAX_STRINGS {
        anyhow::bail!(
            "--nodes {} × --layers {} is more than {MAX_STRINGS} strings",
            a.nodes,
            a.layers
        );
    }
    let profile = Profile::load(&a.printer)?;
    let polygon = match builtin_boundary(&a.boundary, a.size) {
        Some(p) => p,
        None => {
            let path = std::path::Path::new(&a.boundary);
            let text = crate::fileio::read_text_bounded(path, crate::fileio::Limit::Drawing)
                .with_context(|| {
                    format!(
                        "--boundary {}: not circle/square/blob and not a readable file",
                        a.boundary
                    )
                })?;
            read_boundary(&text).with_context(|| format!("reading boundary {}", a.boundary))?
        }
    };
    // Built-in shapes are centred on the origin: their origin goes to the bed centre. File
    // boundaries may lie anywhere: the centre of their bounding box goes to the bed centre.
    let (lo, hi) = polygon
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    if !(lo.is_finite() && hi.is_finite()) || (hi - lo).max_element() > SIZE_MM {
        anyhow::bail!("--boundary {}: larger than {SIZE_MM} mm", a.boundary);
    }
    let offset = if builtin_boundary(&a.boundary, a.size).is_some() {
        DVec2::from(profile.bed_center())
    } else {
        DVec2::from(profile.bed_center()) - 0.5 * (lo + hi)
    };
    let b = &profile.bed;
    let half_w = 0.5 * a.line_width;
    if lo.x + offset.x - half_w < b.x_min_mm
        || hi.x + offset.x + half_w > b.x_max_mm
        || lo.y + offset.y - half_w < b.y_min_mm
        || hi.y + offset.y + half_w > b.y_max_mm
        || a.layers as f64 * a.layer_height > b.z_max_mm
    {
        anyhow::bail!(
            "the growth region ({:.1} × {:.1} mm, {:.1} mm tall) does not fit the bed of printer {} ({:.0}–{:.0} × {:.0}–{:.0} mm, Z up to {:.0} mm); nothing written",
            hi.x - lo.x,
            hi.y - lo.y,
            a.layers as f64 * a.layer_height,
            profile.name,
            b.x_min_mm,
            b.x_max_mm,
            b.y_min_mm,
            b.y_max_mm,
            b.z_max_mm
        );
    }
    let boundary = Boundary::new(polygon, 512)?;
    let spacing = a.line_width / a.density;
    let params = GrowParams {
        max_nodes: a.nodes,
        max_iterations: a.max_iterations,
        seed: a.seed,
        ..GrowParams::with_spacing(spacing)
    };
    let bar = if a.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(a.nodes as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("growing {bar:40} {pos}/{len} nodes {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    // Grow, verify, and on the rare self-contact retry with the next seed (up to 3 runs).
    let mut attempt = 0;
    let (g, grow_s, verify_s) = loop {
        let t0 = Instant::now();
        let g = grow(
            &boundary,
            &GrowParams {
                seed: a.seed + attempt,
                ..params
            },
            |n| bar.set_position(n as u64),
        )?;
        let grow_s = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let crossing = verify_simple(&g.nodes, true);
        let verify_s = t1.elapsed().as_secs_f64();
        match crossing {
            None => break (g, grow_s, verify_s),
            Some((i, j)) if attempt >= 2 => {
                bar.finish_and_clear();
                anyhow::bail!(
                    "growth produced a self-intersecting stroke 3 times (last: edges {i} and {j} at {:?}); try another --seed or a lower --density",
                    g.nodes.get(i)
                );
            }
            Some((i, j)) => {
                eprintln!(
                    "seed {}: edges {i} and {j} cross (verification); growing again with seed {}",
                    a.seed + attempt,
                    a.seed + attempt + 1
                );
                attempt += 1;
            }
        }
    };
    bar.finish_and_clear();
    let stack = StackParams {
        layers: a.layers,
        layer_mm: a.layer_height,
        line_width_mm: a.line_width,
        speed_mm_s: a.speed,
    };
    let model = to_model(&g.nodes, offset, &stack);
    let writer = GcodeWriter::new(
        &profile,
        WriteOptions {
            bare: false,
            header: Some(format!(
                "host-tools grow --boundary {} --density {} (spacing {:.3} mm)",
                a.boundary, a.density, spacing
            )),
        },
    );
    let summary = super::write_gcode(&writer, &model, &a.output, a.preview.as_deref(), &profile)?;
    if let Some(svg) = &a.svg {
        crate::fileio::write_bytes(
            svg,
            stroke_svg(&g.nodes, &boundary.polygon, a.line_width).as_bytes(),
        )?;
    }
    let len: f64 = (0..g.nodes.len())
        .map(|i| g.nodes[i].distance(g.nodes[(i + 1) % g.nodes.len()]))
        .sum();
    let area = boundary.area_mm2();
    crate::fileio::say(format_args!(
        "mean spacing (boundary area / stroke length) {:.3} mm; meaningful once the region is full",
        area / len.max(1e-9)
    ))?;
    crate::fileio::say(format_args!(
        "grew {} nodes in {} iterations, {:.2} s ({:.0} nodes/s; stopped: {}); stroke {:.0} mm per layer, spacing {:.3} mm; verified single closed stroke without self-intersection in {:.3} s",
        g.nodes.len(),
        g.iterations,
        grow_s,
        g.nodes.len() as f64 / grow_s.max(1e-9),
        g.stop,
        len,
        spacing,
        verify_s
    ))?;
    crate::fileio::say(format_args!(
        "wrote {} ({} layers, {} strings, {} travels, {} retractions, filament {:.0} mm)",
        a.output.display(),
        a.layers,
        summary.strings,
        summary.travels,
        summary.retractions,
        summary.filament_mm
    ))
}

/// An SVG drawing of the stroke inside its boundary.
pub fn stroke_svg(nodes: &[DVec2], boundary: &[DVec2], width_mm: f64) -> String {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in boundary.iter().chain(nodes) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let pad = (hi - lo).max_element() * 0.02 + width_mm;
    let (lo, hi) = (lo - DVec2::splat(pad), hi + DVec2::splat(pad));
    let pts = |v: &[DVec2]| {
        v.iter()
            .map(|p| format!("{:.3},{:.3}", p.x, hi.y - (p.y - lo.y)))
            .collect::<Vec<_>>()
            .join(" ")
    };
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"{:.3} {:.3} {:.3} {:.3}\" width=\"800\" height=\"{:.0}\">\n<rect x=\"{:.3}\" y=\"{:.3}\" width=\"{:.3}\" height=\"{:.3}\" fill=\"white\"/>\n<polygon points=\"{}\" fill=\"none\" stroke=\"#888\" stroke-width=\"{:.3}\"/>\n<polygon points=\"{}\" fill=\"none\" stroke=\"#b5542c\" stroke-width=\"{:.3}\" stroke-linejoin=\"round\"/>\n</svg>\n",
        lo.x,
        lo.y,
        hi.x - lo.x,
        hi.y - lo.y,
        800.0 * (hi.y - lo.y) / (hi.x - lo.x),
        lo.x,
        lo.y,
        hi.x - lo.x,
        hi.y - lo.y,
        pts(boundary),
        width_mm * 0.3,
        pts(nodes),
        width_mm
    )
}
