//! Basic execution through the Printer: moves arrive, segments execute once, in order.
mod support;

use firmware::config::MachineConfig;
use support::*;

#[test]
fn straight_move_is_segmented_and_reaches_target() {
    let cfg = MachineConfig::ENDER3;
    let mut p = printer();
    let cmds = commands(&cfg, &[Item::Move([10.0, 0.0, 0.0, 0.0], 50.0)]);
    let r = run(&mut p, &cmds, &[], 10_000_000);
    assert_eq!(r.end, to_steps(&cfg, [10.0, 0.0, 0.0, 0.0]));
    assert_eq!(r.executed.len(), 50);
    for (i, e) in r.executed.iter().enumerate() {
        assert_eq!(*e, (1, i as u32));
    }
    // 10 mm at 50 mm/s, 500 mm/s²: 0.1 s accel + 0.1 s decel over 5 mm, 5 mm cruise 0.1 s.
    let t_end = r.trace.last().unwrap().0 as f64 / 1e9;
    assert!((t_end - 0.3).abs() < 0.01, "took {t_end}");
}
