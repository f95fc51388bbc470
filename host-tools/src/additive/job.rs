//! The additive job: from a base mesh, a chosen face and an added shape to world-space
//! toolpaths stacked along the face normal, checked against the print head.
//!
//! The added shape is normalised first: its XY bounding-box centre becomes the local origin
//! and its lowest point `z = 0`, so it stands on the face at the user's offset. It is sliced
//! at the middle of each layer (`(k + ½)·layer`), filled, and layer `k` is printed at local
//! height `(k + 1)·layer` along the face normal.

use super::collision::{check_path, BaseSamples, Collision, HeadModel};
use super::fill::{fill_layer, FillParams, PathKind};
use super::frame::{closest_point_on_triangle, local_to_world, nearest_face, Frame, Placement};
use super::slice::slice_layers;
use super::stl::{validate, Mesh, MeshReport, MAX_COORD_MM};
use crate::design::profile::Profile;
use crate::design::travel::HeightMap;
use crate::gcode::read::{default_reader, BadLines, Event, GcodeReader};
use anyhow::bail;
use glam::{DMat4, DVec3};

/// How the base face is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaceChoice {
    /// Triangle index in the base STL.
    Index(usize),
    /// The triangle nearest to this point (world, mm).
    At(DVec3),
}

/// Parameters of an additive job.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JobParams {
    /// The base face.
    pub face: FaceChoice,
    /// Offset and rotation of the shape in the polygon frame.
    pub placement: Placement,
    /// Layer height along the face normal, mm.
    pub layer_mm: f64,
    /// Walls and infill.
    pub fill: FillParams,
    /// Gap tolerance for chaining slice contours, mm.
    pub gap_mm: f64,
    /// Print head geometry for the collision check.
    pub head: HeadModel,
    /// Resolution of the collision check, mm.
    pub collision_step_mm: f64,
    /// Where the nozzle is when the job starts (after the start code's `G28`), world mm. The
    /// head rises straight up from here to a safe height, crosses above everything, and
    /// descends onto the first point; the check covers that approach too.
    pub start_mm: DVec3,
}

impl Default for JobParams {
    fn default() -> Self {
        JobParams {
            face: FaceChoice::Index(0),
            placement: Placement::default(),
            layer_mm: 0.2,
            fill: FillParams::default(),
            gap_mm: 0.01,
            head: HeadModel::default(),
            collision_step_mm: 0.5,
            start_mm: DVec3::ZERO,
        }
    }
}

/// One extruded path in world coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldPath {
    /// Layer index (0 = on the face).
    pub layer: usize,
    /// Wall or infill.
    pub kind: PathKind,
    /// Points (world, mm).
    pub points: Vec<DVec3>,
}

/// A planned job.
#[derive(Debug, Clone)]
pub struct Job {
    /// Index of the chosen base face.
    pub face_index: usize,
    /// The polygon frame of that face.
    pub frame: Frame,
    /// Local shape coordinates → world (`T · T_wp⁻¹`).
    pub local_to_world: DMat4,
    /// Number of layers.
    pub layers: usize,
    /// Paths in print order.
    pub paths: Vec<WorldPath>,
    /// Validation of the base mesh.
    pub base_report: MeshReport,
    /// Validation of the added shape.
    pub shape_report: MeshReport,
    /// Slice chains that could not be closed (summed over layers).
    pub open_chains: usize,
    /// Largest face tilt the head can print on (unbounded flat face), degrees.
    pub max_tilt_deg: f64,
    /// The head's way from the start position to the first path point, first point excluded:
    /// straight up to the safe height, across above the base and the shape.
    pub approach: Vec<DVec3>,
}

impl Job {
    /// Nozzle positions in print order, the approach from the start position and the travels
    /// included (the polyline the head follows).
    pub fn tip_polyline(&self) -> Vec<DVec3> {
        let mut out = self.approach.clone();
        for (travel, path) in self.travels().into_iter().zip(&self.paths) {
            out.extend(travel);
            out.extend(path.points.iter().copied());
        }
        out
    }

    /// The travel before each path (the first path's is empty: the approach brings the head
    /// there): up above what the job printed so far under the way, across, down onto the
    /// path's first point ([`HeightMap::route`]), never straight through fresh walls.
    pub fn travels(&self) -> Vec<Vec<DVec3>> {
        let mut map = HeightMap::new();
        let mut at: Option<DVec3> = None;
        let mut out = Vec::with_capacity(self.paths.len());
        for path in &self.paths {
            let route = match (at, path.points.first()) {
                (Some(from), Some(first)) => map.route(from, *first),
                _ => Vec::new(),
            };
            out.push(route);
            for w in path.points.windows(2) {
                map.add_segment(w[0], w[1]);
            }
            if let Some(last) = path.points.last() {
                at = Some(*last);
            }
        }
        out
    }
}

/// Resolves the face choice to a triangle index.
pub fn choose_face(base: &Mesh, face: FaceChoice) -> anyhow::Result<usize> {
    match face {
        FaceChoice::Index(i) => {
            if i >= base.faces.len() {
                bail!(
                    "--face {i}: the base has {} triangles (0..{})",
                    base.faces.len(),
                    base.faces.len().saturating_sub(1)
                );
            }
            Ok(i)
        }
        FaceChoice::At(p) => {
            if !p.is_finite() {
                bail!("--at: point must be finite");
            }
            nearest_face(base, p)
                .map(|(i, _)| i)
                .ok_or_else(|| anyhow::anyhow!("the base mesh has no triangles"))
        }
    }
}

/// Moves the shape so its XY bounding-box centre is the origin and its lowest point is z = 0.
pub fn normalise_shape(shape: &Mesh) -> Mesh {
    match shape.bbox() {
        Some((lo, hi)) => {
            let shift = DVec3::new(-(lo.x + hi.x) * 0.5, -(lo.y + hi.y) * 0.5, -lo.z);
            shape.map(|v| v + shift)
        }
        None => shape.clone(),
    }
}

/// Most layers a job may have.
pub const MAX_LAYERS: usize = 100_000;
/// Most toolpath points a job may have (about 1 GB of paths and G-code).
pub const MAX_POINTS: usize = 20_000_000;
/// Most walls.
pub const MAX_WALLS: usize = 100;

/// Plans the job: frame, slicing, fill, transform. Does not check collisions (see [`check`]).
///
/// Bounds (errors beyond them): layer height 0.01–50 mm, line width 0.05–50 mm, at most
/// [`MAX_WALLS`] walls, [`MAX_LAYERS`] layers and [`MAX_POINTS`] toolpath points, offsets
/// within ±[`MAX_COORD_MM`].
pub fn plan(base: &Mesh, shape: &Mesh, p: &JobParams) -> anyhow::Result<Job> {
    if !(p.layer_mm.is_finite() && (0.01..=50.0).contains(&p.layer_mm)) {
        bail!("layer height {} mm is outside 0.01..=50 mm", p.layer_mm);
    }
    let w = p.fill.line_width_mm;
    if !(w.is_finite() && (0.05..=50.0).contains(&w)) {
        bail!("line width {w} mm is outside 0.05..=50 mm");
    }
    if p.fill.walls > MAX_WALLS || p.fill.solid_layers > MAX_LAYERS {
        bail!(
            "{} walls / {} solid layers: at most {MAX_WALLS} / {MAX_LAYERS}",
            p.fill.walls,
            p.fill.solid_layers
        );
    }
    if p.placement.offset_mm.abs().max_element() > MAX_COORD_MM
        || !p.start_mm.is_finite()
        || p.start_mm.abs().max_element() > MAX_COORD_MM
    {
        bail!("offset and start position must lie within ±{MAX_COORD_MM} mm");
    }
    if !(0.0..=100.0).contains(&p.fill.infill_percent) {
        bail!("infill must be between 0 and 100 %");
    }
    if !p.placement.offset_mm.is_finite() || !p.placement.rotate_deg.is_finite() {
        bail!("offset and rotation must be finite");
    }
    let base_report = validate(base);
    let shape_report = validate(shape);
    let face_index = choose_face(base, p.face)?;
    let mut frame = Frame::from_face(base, face_index)?;
    if let (FaceChoice::At(at), Some([a, b, c])) = (p.face, base.triangle(face_index)) {
        // `--at` names the spot: the shape stands on the face point nearest to it.
        frame.origin = closest_point_on_triangle(at, a, b, c);
    }
    let m = local_to_world(&frame, &p.placement);
    let local = normalise_shape(shape);
    if let Some((lo, hi)) = local.bbox() {
        if (hi.z - lo.z) / p.layer_mm > MAX_LAYERS as f64 {
            bail!(
                "the shape is {:.1} mm tall: more than {MAX_LAYERS} layers of {} mm",
                hi.z - lo.z,
                p.layer_mm
            );
        }
    }
    let sections = slice_layers(&local, p.layer_mm, p.gap_mm);
    let layers = sections.len();
    if layers == 0 {
        bail!(
            "the added shape is thinner than one layer ({} mm)",
            p.layer_mm
        );
    }
    let mut paths = Vec::new();
    let mut open_chains = 0;
    let mut points = 0usize;
    for (k, sec) in sections.iter().enumerate() {
        open_chains += sec.open_chains;
        let z = (k as f64 + 1.0) * p.layer_mm;
        for lp in fill_layer(&sec.loops, &p.fill, k, layers) {
            points += lp.points.len();
            if points > MAX_POINTS {
                bail!("the job has more than {MAX_POINTS} toolpath points (layer {k}); use a larger layer height or line width");
            }
            paths.push(WorldPath {
                layer: k,
                kind: lp.kind,
                points: lp
                    .points
                    .iter()
                    .map(|q| m.transform_point3(q.extend(z)))
                    .collect(),
            });
        }
    }
    let approach = approach(base, shape_top(&paths), p.start_mm, &paths);
    Ok(Job {
        approach,
        face_index,
        frame,
        local_to_world: m,
        layers,
        paths,
        base_report,
        shape_report,
        open_chains,
        max_tilt_deg: p.head.max_face_tilt_deg(p.layer_mm),
    })
}

/// Highest toolpath point, world Z.
fn shape_top(paths: &[WorldPath]) -> f64 {
    paths
        .iter()
        .flat_map(|p| p.points.iter())
        .fold(f64::NEG_INFINITY, |z, q| z.max(q.z))
}

/// Where the profile's start code leaves the nozzle (its last move, read by the project's
/// G-code reader; after a bare `G28`, the bed's minimum corner at Z 0): the approach starts
/// there, so the first move out of the start code is the checked one. Lines the firmware would
/// reject are skipped as the printer skips them (vendor start codes carry other firmwares'
/// commands).
pub fn start_position(profile: &Profile) -> anyhow::Result<DVec3> {
    let code = profile.start_code(profile.hotend_c, profile.bed_c);
    let mut last = None;
    let mut reader = default_reader();
    reader.bad_line_policy = BadLines::Skip;
    reader
        .read(code.as_bytes(), &mut |e| {
            if let Event::Move { to, .. } = e {
                last = Some(DVec3::new(to[0], to[1], to[2]));
            }
        })
        .map_err(|e| anyhow::anyhow!("printer profile {}: start code: {e}", profile.name))?;
    Ok(last.unwrap_or(DVec3::new(profile.bed.x_min_mm, profile.bed.y_min_mm, 0.0)))
}

/// Clearance of the approach above the base part and the shape, mm.
pub const APPROACH_CLEARANCE_MM: f64 = 5.0;

/// The head's way from `start` to the first path point (first point excluded): straight up
/// to [`APPROACH_CLEARANCE_MM`] above the base part and the shape, across, and (by the first
/// path point itself) straight down.
fn approach(base: &Mesh, top_z: f64, start: DVec3, paths: &[WorldPath]) -> Vec<DVec3> {
    let Some(first) = paths.iter().find_map(|p| p.points.first().copied()) else {
        return Vec::new();
    };
    let base_top = base.bbox().map_or(f64::NEG_INFINITY, |(_, hi)| hi.z);
    let safe_z = base_top.max(top_z).max(start.z) + APPROACH_CLEARANCE_MM;
    vec![
        start,
        DVec3::new(start.x, start.y, safe_z),
        DVec3::new(first.x, first.y, safe_z),
    ]
}

/// Checks the head along the whole toolpath (the approach from the start position and the
/// travels included) against the base part. Errors when the base part is too large to sample
/// at the collision step.
pub fn check(base: &Mesh, job: &Job, p: &JobParams) -> anyhow::Result<Option<Collision>> {
    let samples = BaseSamples::new(base, p.collision_step_mm, p.head.max_radius_mm())?;
    Ok(check_path(
        &samples,
        &p.head,
        &job.tip_polyline(),
        p.collision_step_mm,
    ))
}

/// Why the head hits the base part, in words: the real cause, not always the face's tilt.
/// A hit on the approach (the head at, or rising from, where the start code leaves it) is
/// the start position lying within the head's reach of the base part; a hit while printing
/// is the face's tilt only when the tilt is beyond what the head can print on.
pub fn explain(job: &Job, head: &HeadModel, c: &Collision) -> String {
    let hit = format!(
        "the {} hits the base part at ({:.2}, {:.2}, {:.2}) with the nozzle at ({:.2}, {:.2}, {:.2})",
        c.part, c.base_point[0], c.base_point[1], c.base_point[2], c.tip[0], c.tip[1], c.tip[2]
    );
    let tilt = job.frame.tilt_deg();
    match job.approach.first() {
        Some(start) if c.path_index < 2 && job.approach.len() >= 2 => {
            let dxy = (DVec3::from_array(c.base_point) - *start).truncate().length();
            format!(
                "{hit} {} the start position ({:.1}, {:.1}, {:.1}), where the printer's start code leaves the head: the base part is {dxy:.1} mm from it, within the head's reach of {:.0} mm (carriage radius). Place the base part farther from the start position (or use a profile whose start code parks elsewhere); the face tilt ({tilt:.1}°) is not the cause",
                if c.path_index == 0 { "at" } else { "rising from" },
                start.x,
                start.y,
                start.z,
                head.max_radius_mm()
            )
        }
        _ if c.path_index < job.approach.len() => format!(
            "{hit} on the approach across, {:.0} mm above the base part's top: the base part is taller than its bounding box says?",
            APPROACH_CLEARANCE_MM
        ),
        _ if tilt > job.max_tilt_deg => format!(
            "{hit} (toolpath point {}): the face tilt is {tilt:.1}°, the head can print on up to {:.1}°",
            c.path_index, job.max_tilt_deg
        ),
        _ => format!(
            "{hit} (toolpath point {}): the face tilt ({tilt:.1}°) is within the head's {:.1}°, so another part of the base rises into the head's reach of the shape (move the shape with --offset, or use a head model with a smaller carriage)",
            c.path_index, job.max_tilt_deg
        ),
    }
}

/// Speeds of the emitted paths, mm/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Speeds {
    /// First layer (on the base part).
    pub first_layer_mm_s: f64,
    /// Walls.
    pub wall_mm_s: f64,
    /// Infill.
    pub infill_mm_s: f64,
}

impl Default for Speeds {
    fn default() -> Self {
        Speeds {
            first_layer_mm_s: 15.0,
            wall_mm_s: 25.0,
            infill_mm_s: 40.0,
        }
    }
}

/// The job as a design-compiler model (strings of cross-section `line width × layer height`),
/// ready for the shared G-code writer. Layer markers carry the height along the face normal.
pub fn to_model(job: &Job, p: &JobParams, speeds: &Speeds) -> crate::design::model::Model {
    use crate::design::model::{MarkerKind, Model, Step, Str};
    let mut m = Model::new([job.frame.origin.x, job.frame.origin.y]);
    m.push(Step::Comment(format!(
        "additive job on base face {} (tilt {:.2} deg), frame origin {:.3},{:.3},{:.3} normal {:.4},{:.4},{:.4}",
        job.face_index,
        job.frame.tilt_deg(),
        job.frame.origin.x,
        job.frame.origin.y,
        job.frame.origin.z,
        job.frame.z.x,
        job.frame.z.y,
        job.frame.z.z
    )));
    let cross = p.fill.line_width_mm * p.layer_mm;
    // The approach (the start position itself is where the start code left the head).
    for &to in job.approach.iter().skip(1) {
        m.push(Step::Travel {
            to,
            speed_mm_s: None,
        });
    }
    let mut layer = usize::MAX;
    let mut kind: Option<PathKind> = None;
    for (travel, path) in job.travels().into_iter().zip(&job.paths) {
        if path.layer != layer {
            layer = path.layer;
            kind = None;
            m.push(Step::Marker {
                kind: MarkerKind::Layer,
                z_mm: (layer as f64 + 1.0) * p.layer_mm,
                height_mm: p.layer_mm,
            });
        }
        if kind != Some(path.kind) {
            kind = Some(path.kind);
            m.push(Step::Type(
                match path.kind {
                    PathKind::Wall(0) => "External perimeter",
                    PathKind::Wall(_) => "Perimeter",
                    PathKind::Infill => "Solid infill",
                }
                .into(),
            ));
        }
        let speed = if layer == 0 {
            speeds.first_layer_mm_s
        } else if path.kind == PathKind::Infill {
            speeds.infill_mm_s
        } else {
            speeds.wall_mm_s
        };
        for to in travel {
            m.push(Step::Travel {
                to,
                speed_mm_s: None,
            });
        }
        if let Some(first) = path.points.first() {
            m.push(Step::Travel {
                to: *first,
                speed_mm_s: None,
            });
        }
        for w in path.points.windows(2) {
            if w[0] != w[1] {
                m.push(Step::String(Str::line(w[0], w[1], cross, speed)));
            }
        }
    }
    m
}
