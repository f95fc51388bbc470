//! Additive machining geometry: STL reading and validation, the polygon frame and the paper's
//! transform against hand-computed cases, slicing of meshes with known sections, offsets, fill
//! and the head collision model.

use glam::{DMat4, DVec2, DVec3};
use host_tools::additive::collision::{check_path, BaseSamples, HeadModel};
use host_tools::additive::experiment::{slope_base, triangular_pyramid, SLOPE_FACE};
use host_tools::additive::fill::{fill_layer, hatch, FillParams, PathKind};
use host_tools::additive::frame::{
    local_to_world, nearest_face, paper_transform, Frame, Placement,
};
use host_tools::additive::job::{check, plan, FaceChoice, JobParams};
use host_tools::additive::offset::offset_loop;
use host_tools::additive::slice::{signed_area, slice_at, slice_layers};
use host_tools::additive::stl::{
    box_mesh, prism_mesh, read_stl_bytes, validate, write_stl_to, Mesh,
};

const EPS: f64 = 1e-9;

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-9
}

fn cube10() -> Mesh {
    box_mesh(DVec3::ZERO, DVec3::splat(10.0))
}

// ---------------------------------------------------------------- STL

#[test]
fn binary_round_trip_and_ascii() {
    let cube = cube10();
    let mut bytes = Vec::new();
    write_stl_to(&mut bytes, &cube).unwrap();
    assert_eq!(bytes.len(), 84 + 50 * 12);
    let back = read_stl_bytes(&bytes).unwrap();
    assert_eq!(back.faces.len(), 12);
    assert_eq!(back.vertices.len(), 8, "bit-identical corners are welded");
    assert!(validate(&back).is_watertight());
    assert!((back.signed_volume_mm3() - 1000.0).abs() < 1e-6);

    let ascii = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    let m = read_stl_bytes(ascii).unwrap();
    assert_eq!(m.faces.len(), 1);
    let r = validate(&m);
    assert_eq!(r.open_edges.len(), 3);
    assert!(r.inverted_normals.is_empty());
}

#[test]
fn garbage_is_an_error_not_a_panic() {
    assert!(read_stl_bytes(b"").is_err());
    assert!(read_stl_bytes(b"solid x\nfacet normal nonsense\n").is_err());
    // A binary header claiming more triangles than present.
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&1000u32.to_le_bytes());
    b.extend_from_slice(&[0u8; 50]);
    assert!(read_stl_bytes(&b).is_err());
}

#[test]
fn validation_finds_each_defect() {
    let cube = cube10();
    let r = validate(&cube);
    assert!(r.is_watertight(), "{}", r.summary());

    // Remove one triangle: three open edges.
    let mut holed = cube.clone();
    holed.faces.pop();
    holed.stored_normals.pop();
    let r = validate(&holed);
    assert_eq!(r.open_edges.len(), 3);
    assert!(!r.is_watertight());

    // Flip one triangle's winding: its three edges are used twice in one direction.
    let mut flipped = cube.clone();
    flipped.faces[0].swap(1, 2);
    let r = validate(&flipped);
    assert_eq!(r.inconsistent_edges.len(), 3);
    // Its stored normal now points against the winding.
    assert_eq!(r.inverted_normals, vec![0]);

    // A degenerate (zero-area) triangle.
    let mut degen = cube.clone();
    degen.faces.push([0, 0, 1]);
    degen.stored_normals.push(DVec3::Z);
    let r = validate(&degen);
    assert_eq!(r.degenerate, vec![12]);

    // A fin: a third triangle on an existing edge makes it non-manifold.
    let mut fin = cube.clone();
    let [a, b, _] = fin.faces[0];
    fin.vertices.push(DVec3::new(5.0, 5.0, -5.0));
    let v = fin.vertices.len() - 1;
    fin.faces.push([a, b, v]);
    fin.stored_normals.push(DVec3::ZERO);
    let r = validate(&fin);
    assert_eq!(r.non_manifold_edges.len(), 1);

    // Inside out: negative volume.
    let inv = cube.map(|v| v * DVec3::new(1.0, 1.0, -1.0));
    assert!(validate(&inv).signed_volume_mm3 < 0.0);
}

// ---------------------------------------------------------------- frame

#[test]
fn frame_on_15_degree_slope_hand_computed() {
    let (s, c) = 15f64.to_radians().sin_cos();
    let a = DVec3::ZERO;
    let b = DVec3::new(10.0, 0.0, 0.0);
    let cc = DVec3::new(0.0, 10.0 * c, 10.0 * s);
    let f = Frame::from_triangle(a, b, cc).unwrap();
    // Normal (b−a)×(c−a) = (0, −100 s, 100 c) / 100.
    assert!(close(f.z, DVec3::new(0.0, -s, c)));
    // Global Z projected onto the face: Z − c·n = s·(0, c, s) → Y' = (0, c, s), up the slope.
    assert!(close(f.y, DVec3::new(0.0, c, s)));
    // X' = Y' × Z' = (c² + s², 0, 0).
    assert!(close(f.x, DVec3::X));
    assert!(close(
        f.origin,
        DVec3::new(10.0 / 3.0, 10.0 * c / 3.0, 10.0 * s / 3.0)
    ));
    assert!((f.tilt_deg() - 15.0).abs() < 1e-9);
    assert!(!f.horizontal_fallback);
}

#[test]
fn frame_on_horizontal_faces_uses_the_fallback() {
    let top = Frame::from_triangle(
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::new(3.0, 0.0, 5.0),
        DVec3::new(0.0, 3.0, 5.0),
    )
    .unwrap();
    assert!(top.horizontal_fallback);
    assert!(close(top.z, DVec3::Z) && close(top.y, DVec3::Y) && close(top.x, DVec3::X));
    assert!(close(top.origin, DVec3::new(1.0, 1.0, 5.0)));

    let bottom = Frame::from_triangle(
        DVec3::ZERO,
        DVec3::new(0.0, 3.0, 0.0),
        DVec3::new(3.0, 0.0, 0.0),
    )
    .unwrap();
    assert!(bottom.horizontal_fallback);
    assert!(close(bottom.z, -DVec3::Z) && close(bottom.y, DVec3::Y));
    assert!(close(bottom.x, -DVec3::X));
    // Right-handed: X' × Y' = Z'.
    assert!(close(bottom.x.cross(bottom.y), bottom.z));
}

#[test]
fn frame_on_vertical_face() {
    // Front face of a box, normal −Y.
    let f = Frame::from_triangle(
        DVec3::ZERO,
        DVec3::new(10.0, 0.0, 0.0),
        DVec3::new(0.0, 0.0, 10.0),
    )
    .unwrap();
    assert!(close(f.z, -DVec3::Y));
    assert!(close(f.y, DVec3::Z));
    assert!(close(f.x, DVec3::X));
    assert!((f.tilt_deg() - 90.0).abs() < 1e-9);
}

#[test]
fn degenerate_face_has_no_frame() {
    assert!(Frame::from_triangle(DVec3::ZERO, DVec3::X, DVec3::X * 2.0).is_err());
}

#[test]
fn paper_transform_hand_computed() {
    let (s, c) = 15f64.to_radians().sin_cos();
    let f = Frame::from_triangle(
        DVec3::ZERO,
        DVec3::new(10.0, 0.0, 0.0),
        DVec3::new(0.0, 10.0 * c, 10.0 * s),
    )
    .unwrap();
    assert!(
        (f.from_world() * f.to_world()).abs_diff_eq(DMat4::IDENTITY, EPS),
        "T_wp · T_wp⁻¹ = I"
    );
    let pl = Placement {
        offset_mm: DVec2::new(5.0, 0.0),
        rotate_deg: 90.0,
    };
    let m = local_to_world(&f, &pl);
    // Local (1, 0, 2): rotated 90° → (0, 1, 2), offset → (5, 1, 2) in the polygon frame,
    // world = origin + 5 X' + 1 Y' + 2 Z'.
    let o = DVec3::new(10.0 / 3.0, 10.0 * c / 3.0, 10.0 * s / 3.0);
    let expect =
        o + DVec3::new(5.0, 0.0, 0.0) + DVec3::new(0.0, c, s) + 2.0 * DVec3::new(0.0, -s, c);
    assert!(close(m.transform_point3(DVec3::new(1.0, 0.0, 2.0)), expect));
    // The literal product equals the closed form T_wp⁻¹ · Trans(offset) · R_z · T_wp.
    let closed = f.to_world()
        * DMat4::from_translation(DVec3::new(5.0, 0.0, 0.0))
        * DMat4::from_rotation_z(90f64.to_radians())
        * f.from_world();
    assert!(paper_transform(&f, &pl).abs_diff_eq(closed, EPS));
    // Layers stack along the face normal: height above the face = local z.
    for z in [0.2, 1.0, 7.5] {
        let w = m.transform_point3(DVec3::new(0.3, -0.7, z));
        assert!(((w - f.origin).dot(f.z) - z).abs() < EPS);
    }
}

#[test]
fn nearest_face_by_point() {
    let cube = cube10();
    let (i, d) = nearest_face(&cube, DVec3::new(5.0, 5.0, 10.5)).unwrap();
    let f = Frame::from_face(&cube, i).unwrap();
    assert!(close(f.z, DVec3::Z), "top face chosen");
    assert!((d - 0.5).abs() < EPS);
    let (i, _) = nearest_face(&cube, DVec3::new(-1.0, 5.0, 5.0)).unwrap();
    assert!(close(Frame::from_face(&cube, i).unwrap().z, -DVec3::X));
}

// ---------------------------------------------------------------- slicing

#[test]
fn cube_sections_including_planes_through_vertices() {
    let cube = cube10();
    let s = slice_at(&cube, 5.0, 0.0);
    assert_eq!(s.loops.len(), 1);
    assert_eq!(s.open_chains, 0);
    assert!(
        (signed_area(&s.loops[0]) - 100.0).abs() < EPS,
        "CCW, 100 mm²"
    );
    // Plane through the top vertices: those count as above, the section is the full square.
    let top = slice_at(&cube, 10.0, 0.0);
    assert_eq!(top.loops.len(), 1);
    assert!((signed_area(&top.loops[0]) - 100.0).abs() < EPS);
    // Plane through the bottom face (coplanar): every vertex is "above", nothing is cut.
    assert!(slice_at(&cube, 0.0, 0.0).loops.is_empty());
    assert!(slice_at(&cube, 10.5, 0.0).loops.is_empty());
}

#[test]
fn cylinder_section_is_the_polygon() {
    let n = 64;
    let r = 5.0;
    let outline: Vec<DVec2> = (0..n)
        .map(|i| DVec2::from_angle(i as f64 / n as f64 * std::f64::consts::TAU) * r)
        .collect();
    let cyl = prism_mesh(&outline, 0.0, 20.0, 1.0, DVec2::ZERO);
    assert!(
        validate(&cyl).is_watertight(),
        "{}",
        validate(&cyl).summary()
    );
    let expect = 0.5 * n as f64 * r * r * (std::f64::consts::TAU / n as f64).sin();
    for z in [0.1, 7.3, 19.9] {
        let s = slice_at(&cyl, z, 0.0);
        assert_eq!(s.loops.len(), 1);
        assert_eq!(s.loops[0].len(), n);
        assert!((signed_area(&s.loops[0]) - expect).abs() < 1e-9);
    }
}

#[test]
fn pyramid_sections_shrink_linearly() {
    let square = [
        DVec2::new(-5.0, -5.0),
        DVec2::new(5.0, -5.0),
        DVec2::new(5.0, 5.0),
        DVec2::new(-5.0, 5.0),
    ];
    let pyr = prism_mesh(&square, 0.0, 10.0, 0.0, DVec2::ZERO);
    assert!(validate(&pyr).is_watertight());
    for z in [0.5, 2.5, 5.0, 9.0] {
        let s = slice_at(&pyr, z, 0.0);
        assert_eq!(s.loops.len(), 1);
        let side = 10.0 * (1.0 - z / 10.0);
        assert!(
            (signed_area(&s.loops[0]) - side * side).abs() < 1e-9,
            "z={z}"
        );
    }
    let tri = triangular_pyramid(20.0, 15.0);
    assert!(validate(&tri).is_watertight());
    let base_area = 3f64.sqrt() / 4.0 * 400.0;
    let s = slice_at(&tri, 7.5, 0.0);
    assert!((signed_area(&s.loops[0]) - base_area * 0.25).abs() < 1e-9);
    // Through the apex: nothing.
    assert!(slice_at(&tri, 15.0, 0.0).loops.is_empty());
}

#[test]
fn hollow_box_gives_outer_ccw_and_hole_cw() {
    let outer = box_mesh(DVec3::ZERO, DVec3::splat(10.0));
    // Inner cavity: an inside-out box.
    let inner = box_mesh(DVec3::splat(3.0), DVec3::splat(7.0));
    let mut tris: Vec<[DVec3; 3]> = outer.triangles().collect();
    tris.extend(inner.triangles().map(|[a, b, c]| [a, c, b]));
    let m = Mesh::from_triangles(&tris);
    assert!(validate(&m).is_watertight());
    assert!((m.signed_volume_mm3() - (1000.0 - 64.0)).abs() < 1e-9);
    let s = slice_at(&m, 5.0, 0.0);
    let mut areas: Vec<f64> = s.loops.iter().map(|l| signed_area(l)).collect();
    areas.sort_by(f64::total_cmp);
    assert!((areas[0] + 16.0).abs() < EPS && (areas[1] - 100.0).abs() < EPS);
}

#[test]
fn small_gaps_are_bridged_only_within_tolerance() {
    // Unwelded cube: each triangle's corners nudged by up to 1 µm, so no edge is shared.
    let mut k = 0u32;
    let tris: Vec<[DVec3; 3]> = cube10()
        .triangles()
        .map(|t| {
            t.map(|v| {
                k = k.wrapping_mul(1_103_515_245).wrapping_add(12345);
                v + DVec3::splat((k % 1000) as f64 * 1e-9)
            })
        })
        .collect();
    let m = Mesh::from_triangles(&tris);
    assert!(!validate(&m).open_edges.is_empty());
    let s = slice_at(&m, 5.0, 0.01);
    assert_eq!(s.loops.len(), 1);
    assert_eq!(s.open_chains, 0);
    assert!((signed_area(&s.loops[0]) - 100.0).abs() < 1e-4);
    let strict = slice_at(&m, 5.0, 0.0);
    assert!(strict.open_chains > 0 && strict.loops.is_empty());
}

#[test]
fn layers_cover_the_height() {
    let secs = slice_layers(&cube10(), 0.2, 0.0);
    assert_eq!(secs.len(), 50);
    assert!((secs[0].z - 0.1).abs() < EPS && (secs[49].z - 9.9).abs() < 1e-9);
}

// ---------------------------------------------------------------- offsets and fill

#[test]
fn offsets_of_square_and_triangle() {
    let sq = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(10.0, 0.0),
        DVec2::new(10.0, 10.0),
        DVec2::new(0.0, 10.0),
    ];
    let o = offset_loop(&sq, 1.0).unwrap();
    assert!((signed_area(&o) - 64.0).abs() < EPS);
    assert!(offset_loop(&sq, 5.0).is_none(), "collapses at the centre");
    // Hole (CW) grows into the material when offset to its left.
    let hole: Vec<DVec2> = sq.iter().rev().copied().collect();
    assert!((signed_area(&offset_loop(&hole, 1.0).unwrap()) + 144.0).abs() < EPS);
    // Equilateral triangle of side 20: inradius 20/(2√3) ≈ 5.77; offset d shrinks the
    // inradius by d, so the area scales by ((r − d)/r)².
    let r_in = 20.0 / (2.0 * 3f64.sqrt());
    let tri: Vec<DVec2> = (0..3)
        .map(|i| DVec2::from_angle((90.0 + 120.0 * i as f64).to_radians()) * (20.0 / 3f64.sqrt()))
        .collect();
    let a0 = signed_area(&tri);
    let o = offset_loop(&tri, 2.0).unwrap();
    assert!((signed_area(&o) - a0 * ((r_in - 2.0) / r_in).powi(2)).abs() < 1e-9);
    assert!(offset_loop(&tri, r_in + 0.01).is_none());
    // L shape (one reflex corner) keeps its topology.
    let l = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(10.0, 0.0),
        DVec2::new(10.0, 4.0),
        DVec2::new(4.0, 4.0),
        DVec2::new(4.0, 10.0),
        DVec2::new(0.0, 10.0),
    ];
    let o = offset_loop(&l, 1.0).unwrap();
    // Exact inward offset of this L: 8×2 + 2×6 = 28 mm².
    assert!((signed_area(&o) - 28.0).abs() < 1e-9);
}

#[test]
fn solid_fill_covers_the_area_and_sparse_is_thinner() {
    let sq = vec![vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(20.0, 0.0),
        DVec2::new(20.0, 20.0),
        DVec2::new(0.0, 20.0),
    ]];
    let p = FillParams {
        line_width_mm: 0.5,
        walls: 2,
        infill_percent: 100.0,
        infill_angle_deg: 0.0,
        solid_layers: 0,
    };
    let paths = fill_layer(&sq, &p, 0, 10);
    let walls: Vec<_> = paths
        .iter()
        .filter(|p| matches!(p.kind, PathKind::Wall(_)))
        .collect();
    assert_eq!(walls.len(), 2);
    // Wall 0 centreline: square of side 19.5 (offset 0.25).
    let len = |pts: &[DVec2]| pts.windows(2).map(|w| w[0].distance(w[1])).sum::<f64>();
    assert!((len(&walls[0].points) - 4.0 * 19.5).abs() < 1e-9);
    let infill_len: f64 = paths
        .iter()
        .filter(|p| p.kind == PathKind::Infill)
        .map(|p| len(&p.points))
        .sum();
    // Region inside the walls: side 20 − 2·(2·0.5 + 0.125) = 17.75; lines 0.5 apart.
    let side = 20.0 - 2.0 * 1.125;
    assert!(
        (infill_len - side * side / 0.5).abs() < side,
        "{infill_len}"
    );
    let sparse = fill_layer(
        &sq,
        &FillParams {
            infill_percent: 25.0,
            ..p
        },
        0,
        10,
    );
    let sparse_len: f64 = sparse
        .iter()
        .filter(|p| p.kind == PathKind::Infill)
        .map(|p| len(&p.points))
        .sum();
    assert!((sparse_len / infill_len - 0.25).abs() < 0.05);
    // Every infill end lies inside the walls' region.
    for p in paths.iter().filter(|p| p.kind == PathKind::Infill) {
        for q in &p.points {
            assert!(q.x >= 1.125 - 1e-9 && q.x <= 18.875 + 1e-9);
        }
    }
}

#[test]
fn hatch_respects_holes() {
    let outer = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(10.0, 0.0),
        DVec2::new(10.0, 10.0),
        DVec2::new(0.0, 10.0),
    ];
    let hole = vec![
        DVec2::new(4.0, 4.0),
        DVec2::new(4.0, 6.0),
        DVec2::new(6.0, 6.0),
        DVec2::new(6.0, 4.0),
    ];
    let segs = hatch(&[outer, hole], 1.0, 0.0);
    for [a, b] in &segs {
        let mid = (*a + *b) * 0.5;
        assert!(!(mid.x > 4.0 && mid.x < 6.0 && mid.y > 4.0 && mid.y < 6.0));
    }
    // Rows through the hole (y = 4.5, 5.5) are split in two.
    assert_eq!(segs.len(), 10 + 2);
}

// ---------------------------------------------------------------- head and job

#[test]
fn max_tilt_of_the_default_head() {
    let h = HeadModel::default();
    // The carriage (radius 20 mm, 8 mm above the tip) limits: the face rising from 0.2 mm
    // below the tip must stay under 8 mm at 20 mm: 20 tan θ − 0.2 / cos θ < 8 → θ ≈ 22.3°.
    let t = h.max_face_tilt_deg(0.2);
    let (s, c) = t.to_radians().sin_cos();
    assert!((20.0 * s / c - 0.2 / c - 8.0).abs() < 0.02, "{t}");
    // A needle nozzle without a carriage: only the cone limits, at 90° − half angle.
    let needle = HeadModel {
        tip_radius_mm: 0.0,
        cone_half_angle_deg: 30.0,
        cone_height_mm: 20.0,
        carriage_radius_mm: 0.0,
        carriage_height_mm: 0.0,
    };
    assert!((needle.max_face_tilt_deg(0.0) - 60.0).abs() < 0.05);
}

#[test]
fn collision_against_a_wall() {
    // A 30 mm tall wall at x = 10..12; the head moves towards it 1 mm above the bed.
    let wall = box_mesh(DVec3::new(10.0, -20.0, 0.0), DVec3::new(12.0, 20.0, 30.0));
    let samples = BaseSamples::new(&wall, 0.5, 20.0).expect("samples");
    let head = HeadModel::default();
    let tips = [DVec3::new(-40.0, 0.0, 1.0), DVec3::new(0.0, 0.0, 1.0)];
    let hit = check_path(&samples, &head, &tips, 0.5).expect("carriage must hit the wall");
    assert_eq!(hit.part, "carriage");
    // The carriage (radius 20) reaches the wall's face at x = 10 when the tip is at x = −10.
    assert!((hit.tip[0] + 10.0).abs() <= 0.5, "{:?}", hit);
    let far = [DVec3::new(-40.0, 0.0, 1.0), DVec3::new(-11.0, 0.0, 1.0)];
    assert!(check_path(&samples, &head, &far, 0.5).is_none());
}

#[test]
fn pyramid_on_15_degree_slope_stacks_along_the_normal() {
    let base = slope_base(DVec2::new(80.0, 80.0), 60.0, 60.0, 10.0, 15.0);
    assert!(
        validate(&base).is_watertight(),
        "{}",
        validate(&base).summary()
    );
    let shape = triangular_pyramid(20.0, 15.0);
    let params = JobParams {
        face: FaceChoice::Index(SLOPE_FACE),
        placement: Placement {
            offset_mm: DVec2::new(0.0, 0.0),
            rotate_deg: 30.0,
        },
        ..JobParams::default()
    };
    let job = plan(&base, &shape, &params).unwrap();
    assert!((job.frame.tilt_deg() - 15.0).abs() < 1e-9);
    assert_eq!(job.layers, 75);
    assert_eq!(job.open_chains, 0);
    for p in &job.paths {
        for q in &p.points {
            let h = (*q - job.frame.origin).dot(job.frame.z);
            assert!((h - (p.layer as f64 + 1.0) * 0.2).abs() < 1e-9);
        }
    }
    assert!(job.paths.iter().any(|p| p.kind == PathKind::Infill));
    assert!(
        check(&base, &job, &params).expect("check").is_none(),
        "centred pyramid is printable"
    );
    // The same job chosen by a point on the slope picks a slope triangle.
    let at = JobParams {
        face: FaceChoice::At(DVec3::new(100.0, 100.0, 30.0)),
        ..params
    };
    let j2 = plan(&base, &shape, &at).unwrap();
    assert!((j2.frame.tilt_deg() - 15.0).abs() < 1e-9);
    // A steep face (60°) is refused by the collision check.
    let steep = slope_base(DVec2::new(80.0, 80.0), 60.0, 60.0, 10.0, 60.0);
    let job = plan(
        &steep,
        &shape,
        &JobParams {
            face: FaceChoice::Index(SLOPE_FACE),
            ..params
        },
    )
    .unwrap();
    assert!(check(&steep, &job, &params).expect("check").is_some());
}

/// A refusal names the real cause: a base part within the carriage's reach of the start
/// position is not a face-tilt problem (issue 23: the message blamed the 15° face).
#[test]
fn refusal_names_the_start_position_when_that_is_the_cause() {
    use host_tools::additive::job::explain;
    let base = slope_base(DVec2::new(80.0, 80.0), 60.0, 60.0, 10.0, 15.0);
    let shape = triangular_pyramid(20.0, 15.0);
    let params = JobParams {
        face: FaceChoice::Index(SLOPE_FACE),
        // 10 mm beside the base part, at the bed: inside the 20 mm carriage.
        start_mm: DVec3::new(70.0, 100.0, 0.0),
        ..JobParams::default()
    };
    let job = plan(&base, &shape, &params).unwrap();
    let c = check(&base, &job, &params).expect("check").expect("hits");
    let msg = explain(&job, &params.head, &c);
    assert!(
        msg.contains("start position") && msg.contains("not the cause"),
        "{msg}"
    );
    // The steep face: the tilt is the cause and is named.
    let steep = slope_base(DVec2::new(80.0, 80.0), 60.0, 60.0, 10.0, 60.0);
    let far = JobParams {
        start_mm: DVec3::ZERO,
        ..params
    };
    let job = plan(&steep, &shape, &far).unwrap();
    let c = check(&steep, &job, &far).expect("check").expect("hits");
    let msg = explain(&job, &far.head, &c);
    assert!(msg.contains("tilt is 60.0°"), "{msg}");
}

#[test]
fn bad_job_parameters_are_errors() {
    let base = cube10();
    let shape = triangular_pyramid(5.0, 5.0);
    let p = JobParams {
        face: FaceChoice::Index(99),
        ..JobParams::default()
    };
    assert!(plan(&base, &shape, &p).is_err());
    let p = JobParams {
        layer_mm: 0.0,
        ..JobParams::default()
    };
    assert!(plan(&base, &shape, &p).is_err());
}
