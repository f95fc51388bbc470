//! Property tests: the STL reader never panics, sections of random prisms have the exact
//! polygon area, offsets shrink convex loops by the expected area, simple star polygons pass
//! the stroke verification.

use glam::DVec2;
use host_tools::additive::offset::offset_loop;
use host_tools::additive::slice::{signed_area, slice_at};
use host_tools::additive::stl::{prism_mesh, read_stl_bytes, validate};
use host_tools::paste::grow::verify_simple;
use proptest::prelude::*;

fn regular(n: usize, r: f64, rot: f64) -> Vec<DVec2> {
    (0..n)
        .map(|i| DVec2::from_angle(rot + i as f64 / n as f64 * std::f64::consts::TAU) * r)
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn stl_reader_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = read_stl_bytes(&bytes);
        let mut ascii = b"solid x\n".to_vec();
        ascii.extend_from_slice(&bytes);
        let _ = read_stl_bytes(&ascii);
    }

    #[test]
    fn prism_sections_are_exact(n in 3usize..40, r in 1.0f64..50.0, rot in 0.0f64..6.3,
                                h in 1.0f64..30.0, t in 0.01f64..0.99) {
        let outline = regular(n, r, rot);
        let m = prism_mesh(&outline, 0.0, h, 1.0, DVec2::ZERO);
        prop_assert!(validate(&m).is_watertight());
        let s = slice_at(&m, t * h, 0.0);
        prop_assert_eq!(s.loops.len(), 1);
        let a = signed_area(&outline);
        prop_assert!((signed_area(&s.loops[0]) - a).abs() < 1e-9 * a.max(1.0));
    }

    #[test]
    fn convex_offsets_shrink_by_perimeter(n in 3usize..40, r in 5.0f64..50.0, d in 0.01f64..1.0) {
        let poly = regular(n, r, 0.3);
        let inr = r * (std::f64::consts::PI / n as f64).cos();
        prop_assume!(d < inr * 0.5);
        let o = offset_loop(&poly, d).unwrap();
        // Inward offset of a regular polygon: similar polygon with inradius − d.
        let k = (inr - d) / inr;
        let a = signed_area(&poly);
        prop_assert!((signed_area(&o) - a * k * k).abs() < 1e-7 * a);
    }

    #[test]
    fn star_polygons_are_simple(n in 3usize..200, seed in 0u64..1000) {
        let pts: Vec<DVec2> = (0..n)
            .map(|i| {
                let w = ((seed.wrapping_mul(31).wrapping_add(i as u64 * 7919)) % 97) as f64 / 97.0;
                DVec2::from_angle(i as f64 / n as f64 * std::f64::consts::TAU) * (1.0 + w)
            })
            .collect();
        prop_assert_eq!(verify_simple(&pts, true), None);
    }
}
