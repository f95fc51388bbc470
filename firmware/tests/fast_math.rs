//! The MCU-cheap arithmetic the planner and the step generator use instead of library calls
//! (64-bit division, `fminf`/`fmaxf`, software `sqrtf`) gives exactly the results of the plain
//! operations, so the host and the MCU step identically.

use firmware::planner::{fmax, fmin, sqrtf};
use firmware::stepgen::div_small;
use proptest::prelude::*;

proptest! {
    #[test]
    fn div_small_is_exact(n in any::<u64>(), d in 1u32..) {
        let (q, r) = div_small(n, d);
        prop_assert_eq!(q, n / u64::from(d));
        prop_assert_eq!(u64::from(r), n % u64::from(d));
    }

    #[test]
    fn div_small_small_divisors(n in any::<u64>(), d in 1u32..70_000) {
        let (q, r) = div_small(n, d);
        prop_assert_eq!(q, n / u64::from(d));
        prop_assert_eq!(u64::from(r), n % u64::from(d));
    }

    #[test]
    fn min_max_match_std(a in any::<f32>(), b in any::<f32>()) {
        let (m, x) = (fmin(a, b), fmax(a, b));
        if a.is_nan() && b.is_nan() {
            prop_assert!(m.is_nan() && x.is_nan());
        } else if a == b {
            // ±0 may come back either way, as with fminf.
            prop_assert_eq!(m, a.min(b));
            prop_assert_eq!(x, a.max(b));
        } else {
            prop_assert_eq!(m.to_bits(), a.min(b).to_bits());
            prop_assert_eq!(x.to_bits(), a.max(b).to_bits());
        }
    }

    #[test]
    fn sqrt_matches_libm(x in 0.0f32..1.0e12) {
        prop_assert_eq!(sqrtf(x).to_bits(), libm::sqrtf(x).to_bits());
    }
}

#[test]
fn div_small_edges() {
    assert_eq!(div_small(0, 0), (0, 0)); // d = 0 is treated as 1
    assert_eq!(div_small(u64::MAX, 1), (u64::MAX, 0));
    assert_eq!(
        div_small(u64::MAX, 1000),
        (u64::MAX / 1000, (u64::MAX % 1000) as u32)
    );
    assert_eq!(
        div_small(1 << 32, 7),
        ((1u64 << 32) / 7, ((1u64 << 32) % 7) as u32)
    );
    assert_eq!(
        div_small(u64::MAX, u32::MAX),
        (u64::MAX / u64::from(u32::MAX), 0)
    );
}
