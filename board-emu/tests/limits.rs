//! The image's account is true (issue 30): the step interrupt's travel limits and floors follow
//! M92, M350 and M203 at once, and moves before homing run as Marlin's default runs them —
//! the same on the emulated board as in `sim run` (the same library on virtual time), and as
//! the test's own count of the G-code says.

mod support;

use support::*;

/// The same job in `sim run` (it starts where the firmware believes it is, 0): the position
/// its steps end at.
fn sim_final_steps(job: &[&str]) -> [i64; 4] {
    let lines: Vec<String> = job.iter().map(|s| s.to_string()).collect();
    let sc = sim::run::Scenario::new(sim::run::Policy::Firmware, sim::run::Mode::Layer);
    let out = sim::run::run(&sim::exec::PrinterFactory, &sc, &lines).expect("sim runs");
    out.run.rec.pos.map(i64::from)
}

/// "Count X:… Y:… Z:…" of the last M114 answer, in steps.
fn m114_counts(lines: &[String]) -> [i64; 3] {
    let l = lines
        .iter()
        .rev()
        .find(|l| l.contains("Count "))
        .expect("an M114 answer with counts");
    let after = l.split("Count ").nth(1).unwrap_or("");
    let v = |k: &str| {
        after
            .split_whitespace()
            .find_map(|w| w.strip_prefix(k))
            .and_then(|n| n.parse::<i64>().ok())
            .unwrap_or_else(|| panic!("{k} in {l}"))
    };
    [v("X:"), v("Y:"), v("Z:")]
}

/// Carriage steps in the firmware's frame (the switches at 0) from the board's net steps.
fn from_switches(net: [i64; 4]) -> [i64; 3] {
    [0, 1, 2].map(|i| net[i] + (f64::from(START_MM[i]) * STEPS_PER_MM[i]).round() as i64)
}

#[test]
fn travel_limits_and_floors_follow_m92_m350_and_m203_to_the_far_end() {
    // M92 X160 (twice the steps), then X to its far end (235 mm = 37,600 steps; the boot
    // limits stopped it at 18,800, 117.5 mm, M114 saying 150 mm); M350 Y32 (twice the
    // microsteps: Y at 160 steps/mm), Y to its far end; M203 X50, X back at F12000: its
    // steps at 50 mm/s × 160 = 8 kHz at most.
    let job: &[&str] = &[
        "G28",
        "M400",
        "M92 X160",
        "G1 X235 F12000",
        "M400",
        "M350 Y32",
        "G1 Y235 F12000",
        "M400",
        "M203 X50",
        "G1 X0 F12000",
        "M400",
        "M114",
    ];
    let mut o = options();
    o.job = job.iter().map(|s| s.to_string()).collect();
    o.max_virtual_s = 60.0;
    let r = run(&o);
    let want = expected_net_steps(job, START_MM);
    assert_eq!(want[0], -800, "the test's count: X back where it homed");
    assert_eq!(want[1], 37_600 - 800);
    assert_eq!(net_steps(&r), want, "{:?}", lines_after(&r, "SD init"));
    // Both far ends were reached on the pins: X went 37,600 steps out.
    let x_out = r.runs["X"]
        .iter()
        .find(|run| run.dir == 1 && run.steps > 1_000)
        .expect("X's run out");
    assert_eq!(x_out.steps, 37_600, "{:?}", r.runs["X"]);
    // M114 tells where the pins put the carriage.
    assert_eq!(m114_counts(&r.lines), from_switches(net_steps(&r)));
    // The same in `sim run`.
    let sim = sim_final_steps(job);
    assert_eq!(from_switches(net_steps(&r)).to_vec(), sim[..3].to_vec());
    // M203 X50: the run back never faster than 50 mm/s at 160 steps/mm (the floors: 2 µs of
    // latency slack, as `emulated.rs` allows).
    let back = r.runs["X"]
        .iter()
        .rev()
        .find(|run| run.dir == -1 && run.steps > 1_000)
        .expect("X's run back");
    let hz = 168e6 / back.min_interval as f64;
    let limit: f64 = 50.0 * 160.0;
    assert!(
        hz <= 1.0 / (1.0 / limit - 2e-6),
        "X back at {hz} Hz > {limit} Hz"
    );
    assert!(r.faults.is_empty() && r.resets.is_empty());
    assert!(
        !r.lines.iter().any(|l| l.contains("steps refused")),
        "{:?}",
        r.lines
    );
}

#[test]
fn an_unhomed_job_moves_as_in_sim_run_and_as_its_gcode_says() {
    // The zigzag start: never homed, positions from where the axes stood.
    let job: &[&str] = &[
        "M302 P1",
        "G92 X20 Y20 Z0.2 E0",
        "G1 X30 Y20 E0.5 F1800",
        "G1 X30 Y24 E0.7",
        "G1 X20 Y24 E1.2",
        "G1 Z0.4 F600",
        "G1 X20 Y28 E1.4 F1800",
        "M400",
        "M92 X100",
        "G1 X30 Y28 E1.9",
        "M400",
        "M114",
    ];
    let mut o = options();
    o.job = job.iter().map(|s| s.to_string()).collect();
    let r = run(&o);
    // Power-on is 0 for the firmware: no start to subtract.
    let want = expected_net_steps(job, [0.0; 3]);
    assert_eq!(want[..3], [1_000, 640, 80], "the test's own count");
    assert_eq!(net_steps(&r), want, "{:?}", lines_after(&r, "SD init"));
    assert_eq!(net_steps(&r).to_vec(), sim_final_steps(job).to_vec());
    assert_eq!(m114_counts(&r.lines), [want[0], want[1], want[2]]);
    assert!(r.faults.is_empty() && r.resets.is_empty());
}
