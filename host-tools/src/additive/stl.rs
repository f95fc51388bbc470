//! Triangle meshes from STL files (binary and ASCII, via `stl_io`) and their validation.
//!
//! `stl_io` welds vertices that are bit-identical, so the mesh comes back indexed and its edge
//! topology can be checked: every edge of a closed, manifold mesh is shared by exactly two
//! triangles that traverse it in opposite directions.

use anyhow::{bail, Context};
use glam::DVec3;
use std::collections::HashMap;
use std::io::{Cursor, Write};
use std::path::Path;

/// An indexed triangle mesh in millimetres (f64).
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Welded vertices.
    pub vertices: Vec<DVec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside (STL rule).
    pub faces: Vec<[usize; 3]>,
    /// Normals as stored in the file (may be zero or wrong; see [`validate`]).
    pub stored_normals: Vec<DVec3>,
}

impl Mesh {
    /// Builds a mesh from triangles given by their corners, welding bit-identical vertices.
    /// Stored normals are set to the winding normals.
    pub fn from_triangles(tris: &[[DVec3; 3]]) -> Mesh {
        let mut index: HashMap<[u64; 3], usize> = HashMap::new();
        let mut mesh = Mesh::default();
        for t in tris {
            let mut f = [0usize; 3];
            for (k, v) in t.iter().enumerate() {
                let key = [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
                let next = mesh.vertices.len();
                let id = *index.entry(key).or_insert(next);
                if id == next {
                    mesh.vertices.push(*v);
                }
                f[k] = id;
            }
            mesh.faces.push(f);
            mesh.stored_normals.push(winding_normal(t[0], t[1], t[2]));
        }
        mesh
    }

    /// The three corners of face `i` (None if `i` is out of range).
    pub fn triangle(&self, i: usize) -> Option<[DVec3; 3]> {
        let f = self.faces.get(i)?;
        Some([
            *self.vertices.get(f[0])?,
            *self.vertices.get(f[1])?,
            *self.vertices.get(f[2])?,
        ])
    }

    /// Iterates over all triangles' corners.
    pub fn triangles(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        (0..self.faces.len()).filter_map(|i| self.triangle(i))
    }

    /// Axis-aligned bounding box `(min, max)`; `None` for an empty mesh.
    pub fn bbox(&self) -> Option<(DVec3, DVec3)> {
        let first = *self.vertices.first()?;
        Some(
            self.vertices
                .iter()
                .fold((first, first), |(lo, hi), v| (lo.min(*v), hi.max(*v))),
        )
    }

    /// Signed volume (positive for a closed mesh with outward-facing winding).
    pub fn signed_volume_mm3(&self) -> f64 {
        self.triangles()
            .map(|[a, b, c]| a.dot(b.cross(c)) / 6.0)
            .sum()
    }

    /// Returns a copy with every vertex mapped through `f`.
    pub fn map(&self, f: impl Fn(DVec3) -> DVec3) -> Mesh {
        Mesh {
            vertices: self.vertices.iter().map(|v| f(*v)).collect(),
            faces: self.faces.clone(),
            stored_normals: self.stored_normals.clone(),
        }
    }
}

/// Unit normal from the winding (right-hand rule), or zero for a degenerate triangle.
pub fn winding_normal(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    (b - a).cross(c - a).normalize_or_zero()
}

/// Reads a binary or ASCII STL file.
pub fn read_stl(path: &Path) -> anyhow::Result<Mesh> {
    let bytes = crate::fileio::read_bounded(path, crate::fileio::Limit::Stl)?;
    read_stl_bytes(&bytes).with_context(|| format!("parsing STL {}", path.display()))
}

/// Largest coordinate magnitude of a mesh vertex, mm (10 m: far beyond any printer, and small
/// enough that every derived toolpath number stays readable and every sampling stays bounded).
pub const MAX_COORD_MM: f64 = 10_000.0;

/// Reads a binary or ASCII STL from memory. Non-finite coordinates, coordinates beyond
/// ±[`MAX_COORD_MM`], a binary triangle count the file cannot hold, and empty meshes are errors.
pub fn read_stl_bytes(bytes: &[u8]) -> anyhow::Result<Mesh> {
    if bytes.len() < 15 {
        bail!("file too short to be an STL ({} bytes)", bytes.len());
    }
    if !bytes.starts_with(b"solid") && bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * n > bytes.len() as u64 {
            bail!(
                "binary STL header announces {n} triangles but the file has room for {}",
                (bytes.len() as u64 - 84) / 50
            );
        }
    }
    let mut cursor = Cursor::new(bytes);
    let indexed = stl_io::read_stl(&mut cursor).context("not a valid binary or ASCII STL")?;
    let mut mesh = Mesh {
        vertices: Vec::with_capacity(indexed.vertices.len()),
        faces: Vec::with_capacity(indexed.faces.len()),
        stored_normals: Vec::with_capacity(indexed.faces.len()),
    };
    for v in &indexed.vertices {
        let p = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        if !p.is_finite() {
            bail!("vertex with a non-finite coordinate: {:?}", v.0);
        }
        if p.abs().max_element() > MAX_COORD_MM {
            bail!(
                "vertex ({}, {}, {}) lies beyond ±{MAX_COORD_MM} mm",
                v[0],
                v[1],
                v[2]
            );
        }
        mesh.vertices.push(p);
    }
    for (i, f) in indexed.faces.iter().enumerate() {
        if f.vertices.iter().any(|&k| k >= mesh.vertices.len()) {
            bail!("triangle {i} refers to a missing vertex");
        }
        mesh.faces.push(f.vertices);
        let n = DVec3::new(f.normal[0] as f64, f.normal[1] as f64, f.normal[2] as f64);
        mesh.stored_normals
            .push(if n.is_finite() { n } else { DVec3::ZERO });
    }
    if mesh.faces.is_empty() {
        bail!("the STL has no triangles");
    }
    Ok(mesh)
}

/// Writes a binary STL (normals from the winding).
pub fn write_stl(path: &Path, mesh: &Mesh) -> anyhow::Result<()> {
    let mut out = Vec::new();
    write_stl_to(&mut out, mesh)?;
    crate::fileio::write_bytes(path, &out)
}

/// Writes a binary STL to any writer.
pub fn write_stl_to(w: &mut impl Write, mesh: &Mesh) -> anyhow::Result<()> {
    let f = |v: DVec3| stl_io::Vector::new([v.x as f32, v.y as f32, v.z as f32]);
    let tris: Vec<stl_io::Triangle> = mesh
        .triangles()
        .map(|[a, b, c]| stl_io::Triangle {
            normal: f(winding_normal(a, b, c)),
            vertices: [f(a), f(b), f(c)],
        })
        .collect();
    stl_io::write_stl(w, tris.iter())?;
    Ok(())
}

/// What [`validate`] found in a mesh. Every list holds triangle indices (edges: vertex pairs).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct MeshReport {
    /// Number of triangles.
    pub triangles: usize,
    /// Number of welded vertices.
    pub vertices: usize,
    /// Triangles with (nearly) zero area or repeated vertices.
    pub degenerate: Vec<usize>,
    /// Edges used by only one triangle (holes in the surface).
    pub open_edges: Vec<[usize; 2]>,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: Vec<[usize; 2]>,
    /// Edges traversed twice in the same direction (a neighbour's winding is flipped).
    pub inconsistent_edges: Vec<[usize; 2]>,
    /// Triangles whose stored normal points against the winding normal.
    pub inverted_normals: Vec<usize>,
    /// Signed volume; negative for a closed mesh means the whole mesh is inside out.
    pub signed_volume_mm3: f64,
}

impl MeshReport {
    /// True when the mesh is closed, manifold, consistently wound, outward-facing and has no
    /// degenerate triangles (stored normals are advisory and not part of this test).
    pub fn is_watertight(&self) -> bool {
        self.degenerate.is_empty()
            && self.open_edges.is_empty()
            && self.non_manifold_edges.is_empty()
            && self.inconsistent_edges.is_empty()
            && self.signed_volume_mm3 > 0.0
    }

    /// One-paragraph human summary.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} triangles, {} vertices, volume {:.1} mm³",
            self.triangles, self.vertices, self.signed_volume_mm3
        );
        let mut add = |what: &str, n: usize| {
            if n > 0 {
                s.push_str(&format!("; {n} {what}"));
            }
        };
        add("degenerate triangles", self.degenerate.len());
        add("open edges", self.open_edges.len());
        add("non-manifold edges", self.non_manifold_edges.len());
        add("inconsistently wound edges", self.inconsistent_edges.len());
        add(
            "stored normals against the winding",
            self.inverted_normals.len(),
        );
        if self.signed_volume_mm3 < 0.0 {
            s.push_str("; mesh is inside out (negative volume)");
        }
        s
    }
}

/// Relative area below which a triangle counts as degenerate (times the squared bbox diagonal).
const DEGENERATE_REL_AREA: f64 = 1e-12;

/// Validates a mesh: degenerate triangles, open / non-manifold / inconsistently wound edges and
/// stored normals that disagree with the winding.
pub fn validate(mesh: &Mesh) -> MeshReport {
    let diag2 = mesh
        .bbox()
        .map(|(lo, hi)| (hi - lo).length_squared())
        .unwrap_or(0.0);
    let mut report = MeshReport {
        triangles: mesh.faces.len(),
        vertices: mesh.vertices.len(),
        signed_volume_mm3: mesh.signed_volume_mm3(),
        ..MeshReport::default()
    };
    // Directed edge counts keyed by the undirected edge: (forward, backward).
    let mut edges: HashMap<[usize; 2], (u32, u32)> = HashMap::new();
    for (i, f) in mesh.faces.iter().enumerate() {
        let Some([a, b, c]) = mesh.triangle(i) else {
            report.degenerate.push(i);
            continue;
        };
        let area2 = (b - a).cross(c - a).length_squared();
        if f[0] == f[1]
            || f[1] == f[2]
            || f[0] == f[2]
            || area2 <= DEGENERATE_REL_AREA * diag2 * diag2
        {
            report.degenerate.push(i);
        } else if let Some(n) = mesh.stored_normals.get(i) {
            if n.length_squared() > 0.0 && n.dot(winding_normal(a, b, c)) < 0.0 {
                report.inverted_normals.push(i);
            }
        }
        for k in 0..3 {
            let (u, v) = (f[k], f[(k + 1) % 3]);
            if u == v {
                continue;
            }
            let e = edges.entry([u.min(v), u.max(v)]).or_insert((0, 0));
            if u < v {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    let mut keys: Vec<_> = edges.into_iter().collect();
    keys.sort_unstable_by_key(|(k, _)| *k);
    for (key, (fw, bw)) in keys {
        match fw + bw {
            1 => report.open_edges.push(key),
            2 if fw != 1 => report.inconsistent_edges.push(key),
            2 => {}
            _ => report.non_manifold_edges.push(key),
        }
    }
    report
}

/// Builds a closed box mesh (outward winding) from its two opposite corners.
pub fn box_mesh(lo: DVec3, hi: DVec3) -> Mesh {
    let p = |x: bool, y: bool, z: bool| {
        DVec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let quads = [
        [
            p(false, false, false),
            p(false, true, false),
            p(true, true, false),
            p(true, false, false),
        ], // bottom
        [
            p(false, false, true),
            p(true, false, true),
            p(true, true, true),
            p(false, true, true),
        ], // top
        [
            p(false, false, false),
            p(true, false, false),
            p(true, false, true),
            p(false, false, true),
        ], // front
        [
            p(false, true, false),
            p(false, true, true),
            p(true, true, true),
            p(true, true, false),
        ], // back
        [
            p(false, false, false),
            p(false, false, true),
            p(false, true, true),
            p(false, true, false),
        ], // left
        [
            p(true, false, false),
            p(true, true, false),
            p(true, true, true),
            p(true, false, true),
        ], // right
    ];
    let mut tris = Vec::new();
    for q in quads {
        tris.push([q[0], q[1], q[2]]);
        tris.push([q[0], q[2], q[3]]);
    }
    Mesh::from_triangles(&tris)
}

/// A closed prism: the polygon `outline` (counter-clockwise, in XY) extruded from `z0` to `z1`.
/// With `top_scale` != 1 the top outline is scaled about `top_center` (a frustum; 0 gives a
/// pyramid apex at `top_center`).
pub fn prism_mesh(
    outline: &[glam::DVec2],
    z0: f64,
    z1: f64,
    top_scale: f64,
    top_center: glam::DVec2,
) -> Mesh {
    let n = outline.len();
    let bottom: Vec<DVec3> = outline.iter().map(|p| p.extend(z0)).collect();
    let top: Vec<DVec3> = outline
        .iter()
        .map(|p| (top_center + (*p - top_center) * top_scale).extend(z1))
        .collect();
    let cb = (outline.iter().copied().sum::<glam::DVec2>() / n.max(1) as f64).extend(z0);
    let ct = top_center.extend(z1);
    let mut tris = Vec::new();
    for i in 0..n {
        let j = (i + 1) % n;
        tris.push([cb, bottom[j], bottom[i]]);
        if top_scale == 0.0 {
            tris.push([bottom[i], bottom[j], ct]);
        } else {
            tris.push([ct, top[i], top[j]]);
            tris.push([bottom[i], bottom[j], top[j]]);
            tris.push([bottom[i], top[j], top[i]]);
        }
    }
    Mesh::from_triangles(&tris)
}
