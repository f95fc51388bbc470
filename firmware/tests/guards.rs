//! Machine safety at the executive: cold and over-long extrusion, per-axis speed limits (E
//! included), arcs and the pause park inside the build volume. Refusals are `echo:` lines (no
//! `Error:`: OctoPrint ends a print on one) and change nothing.
mod support;

use support::*;

/// Issue 16: the chord points of `G3 X3 J200 I4` under G20 leave the machine although the end
/// point is inside: refused with an `echo:`, nothing queued, the position unchanged.
#[test]
fn arc_leaving_the_volume_is_refused_with_echo() {
    let mut p = printer();
    let r = run_gcode(&mut p, &["G20", "G3 X3 J200 I4", "M114"], &[], 5_000_000);
    assert!(
        r.out
            .contains("echo:refused: arc leaves the build volume (Y)"),
        "{}",
        r.out
    );
    assert!(!r.out.contains("Error"), "{}", r.out);
    assert!(r.trace.is_empty());
    assert!(r.out.contains("X:0.00 Y:0.00 Z:0.00"), "{}", r.out);
}
