//! `host-tools additive`: print a shape onto a face of an existing part (polygon frame).

use super::range::{count, within, LAYER_MM, LINE_WIDTH_MM, SIZE_MM};
use crate::additive::collision::HeadModel;
use crate::additive::fill::FillParams;
use crate::additive::frame::Placement;
use crate::additive::job::{
    check, explain, plan, start_position, to_model, FaceChoice, JobParams, Speeds, MAX_LAYERS,
    MAX_WALLS,
};
use crate::additive::stl::read_stl;
use crate::design::profile::Profile;
use crate::design::writer::{GcodeWriter, WriteOptions};
use glam::{DVec2, DVec3};
use std::path::{Path, PathBuf};

/// Arguments of `host-tools additive`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The existing part (STL, binary or ASCII), in printer coordinates.
    #[arg(long)]
    pub base: PathBuf,
    /// Base triangle to print on, by index.
    #[arg(long, conflicts_with = "at", required_unless_present = "at")]
    pub face: Option<usize>,
    /// Base triangle to print on: the one nearest to this point, `x,y,z` mm.
    #[arg(long, value_parser = parse_xyz, allow_hyphen_values = true)]
    pub at: Option<DVec3>,
    /// The shape to add (STL); its XY bounding-box centre and lowest point stand on the face.
    #[arg(long)]
    pub shape: PathBuf,
    /// Offset of the shape in the face frame, `x,y` mm.
    #[arg(long, value_parser = parse_xy, default_value = "0,0", allow_hyphen_values = true)]
    pub offset: DVec2,
    /// Rotation of the shape about its local Z, degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub rotate: f64,
    /// Number of walls.
    #[arg(long, default_value_t = 2, value_parser = count(0, MAX_WALLS))]
    pub walls: usize,
    /// Infill density, per cent (0 = hollow like the paper, 100 = solid).
    #[arg(long, default_value_t = 30.0, value_parser = within(0.0, 100.0))]
    pub infill: f64,
    /// Solid bottom and top layers.
    #[arg(long, default_value_t = 3, value_parser = count(0, MAX_LAYERS))]
    pub solid_layers: usize,
    /// Layer height along the face normal, mm.
    #[arg(long, default_value_t = 0.2, value_parser = within(LAYER_MM.0, LAYER_MM.1))]
    pub layer_height: f64,
    /// Line width, mm.
    #[arg(long, default_value_t = 0.45, value_parser = within(LINE_WIDTH_MM.0, LINE_WIDTH_MM.1))]
    pub line_width: f64,
    /// Printer profile (built-in name or TOML path).
    #[arg(long, default_value = "ender3")]
    pub printer: String,
    /// Nozzle tip radius, mm (collision model).
    #[arg(long, default_value_t = 0.5, value_parser = within(0.0, 1000.0))]
    pub tip_radius: f64,
    /// Nozzle cone half angle, degrees.
    #[arg(long, default_value_t = 45.0, value_parser = within(0.0, 89.9))]
    pub nozzle_angle: f64,
    /// Free nozzle length below the heater block / shroud, mm.
    #[arg(long, default_value_t = 8.0, value_parser = within(0.0, 1000.0))]
    pub nozzle_length: f64,
    /// Radius of the cylinder modelling heater block, shroud and carriage, mm.
    #[arg(long, default_value_t = 20.0, value_parser = within(0.0, 1000.0))]
    pub carriage_radius: f64,
    /// Height of that cylinder, mm.
    #[arg(long, default_value_t = 60.0, value_parser = within(0.0, 1000.0))]
    pub carriage_height: f64,
    /// Also render the G-code with `preview` (top, side, isometric) to this .svg/.png.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Output G-code.
    #[arg(short, long)]
    pub output: PathBuf,
}

fn parse_nums(s: &str, n: usize) -> Result<Vec<f64>, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("bad number `{t}`"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != n || v.iter().any(|x| !(x.is_finite() && x.abs() <= SIZE_MM)) {
        return Err(format!(
            "expected {n} comma-separated numbers within ±{SIZE_MM} mm, got `{s}`"
        ));
    }
    Ok(v)
}

fn parse_xyz(s: &str) -> Result<DVec3, String> {
    parse_nums(s, 3).map(|v| DVec3::new(v[0], v[1], v[2]))
}

fn parse_xy(s: &str) -> Result<DVec2, String> {
    parse_nums(s, 2).map(|v| DVec2::new(v[0], v[1]))
}

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    let outputs: Vec<&Path> = std::iter::once(a.output.as_path())
        .chain(a.preview.as_deref())
        .collect();
    crate::fileio::refuse_inputs_as_outputs(&outputs, &[&a.base, &a.shape, Path::new(&a.printer)])?;
    let profile = Profile::load(&a.printer)?;
    let base = read_stl(&a.base)?;
    let shape = read_stl(&a.shape)?;
    let face = match (a.face, a.at) {
        (Some(i), _) => FaceChoice::Index(i),
        (None, Some(p)) => FaceChoice::At(p),
        (None, None) => anyhow::bail!("give --face N or --at x,y,z"),
    };
    let params = JobParams {
        face,
        placement: Placement {
            offset_mm: a.offset,
            rotate_deg: a.rotate,
        },
        layer_mm: a.layer_height,
        fill: FillParams {
            line_width_mm: a.line_width,
            walls: a.walls,
            infill_percent: a.infill,
            solid_layers: a.solid_layers,
            ..FillParams::default()
        },
        head: HeadModel {
            tip_radius_mm: a.tip_radius,
            cone_half_angle_deg: a.nozzle_angle,
            cone_height_mm: a.nozzle_length,
            carriage_radius_mm: a.carriage_radius,
            carriage_height_mm: a.carriage_height,
        },
        start_mm: start_position(&profile)?,
        ..JobParams::default()
    };
    let job = plan(&base, &shape, &params)?;
    crate::fileio::say(format_args!("base:  {}", job.base_report.summary()))?;
    crate::fileio::say(format_args!("shape: {}", job.shape_report.summary()))?;
    let f = &job.frame;
    crate::fileio::say(format_args!(
        "face {}: tilt {:.2}°, origin ({:.3}, {:.3}, {:.3}), X' ({:.4}, {:.4}, {:.4}), Y' ({:.4}, {:.4}, {:.4}), Z' ({:.4}, {:.4}, {:.4}){}",
        job.face_index,
        f.tilt_deg(),
        f.origin.x, f.origin.y, f.origin.z,
        f.x.x, f.x.y, f.x.z,
        f.y.x, f.y.y, f.y.z,
        f.z.x, f.z.y, f.z.z,
        if f.horizontal_fallback { " (horizontal face: Y' = global Y projected)" } else { "" }
    ))?;
    crate::fileio::say(format_args!(
        "head: largest printable face tilt {:.1}° (cone {}°, {} mm below a carriage of radius {} mm)",
        job.max_tilt_deg, a.nozzle_angle, a.nozzle_length, a.carriage_radius
    ))?;
    if job.open_chains > 0 {
        crate::fileio::say(format_args!(
            "warning: {} slice chains could not be closed (open shape mesh) and were dropped",
            job.open_chains
        ))?;
    }
    if let Some(c) = check(&base, &job, &params)? {
        anyhow::bail!("refused: {}", explain(&job, &params.head, &c));
    }
    let model = to_model(&job, &params, &Speeds::default());
    let writer = GcodeWriter::new(
        &profile,
        WriteOptions {
            bare: false,
            header: Some(format!(
                "host-tools additive --base {} --shape {}",
                a.base.display(),
                a.shape.display()
            )),
        },
    );
    let summary = super::write_gcode(&writer, &model, &a.output, a.preview.as_deref(), &profile)?;
    crate::fileio::say(format_args!(
        "collision check passed; wrote {}: {} layers, {} paths, {} strings, {} travels, filament {:.0} mm",
        a.output.display(),
        job.layers,
        job.paths.len(),
        summary.strings,
        summary.travels,
        summary.filament_mm
    ))?;
    Ok(())
}
