//! The unmodified SKR 2 image on the emulated board (docs/board-emu.md): boot, homing, a job,
//! a layer pause against `sim run`, settings across a reset, SD printing, and faults.
//! Each test builds nothing but the image (once) and runs the board for a few virtual seconds.

mod support;

use board_emu::rcc::ResetKind;
use support::*;

/// No axis steps faster than its limit (max feed × steps/mm). Step times are whole ticks of
/// the 4 MHz step timer, so an interval may be one tick (250 ns) short of the exact one.
fn assert_rates_within_limits(r: &board_emu::report::Report) {
    for (axis, limit) in &r.step_rate_limit_hz {
        if let Some(rate) = r.max_step_rate_hz[axis] {
            let tick_slack = 1.0 / (1.0 - 250e-9 * limit);
            assert!(rate <= limit * tick_slack, "{axis}: {rate} Hz > {limit} Hz");
        }
    }
}

#[test]
fn boots_and_answers_m115() {
    let r = run(&options());
    let m115 = r.m115.as_deref().expect("an M115 reply");
    assert!(m115.starts_with("FIRMWARE_NAME:LayerPause"), "{m115}");
    for axis in ["X", "Y", "Z", "E"] {
        assert!(
            r.lines.iter().any(|l| l.starts_with(&format!("echo:TMC2209 {axis}: "))),
            "driver {axis} configured over its UART: {:?}",
            r.lines
        );
    }
    assert_eq!(r.tmc_datagrams.iter().filter(|&&n| n > 0).count(), 4);
    assert!(r.faults.is_empty() && r.resets.is_empty(), "{:?} {:?}", r.faults, r.resets);
    assert!(r.safe_power_at_end);
    // The watchdog runs with the 2 s the image asks for (at the typical 32 kHz LSI).
    assert!((r.watchdog_timeout_s - 2.0).abs() < 0.01, "{}", r.watchdog_timeout_s);
    let (hw, size) = (r.stack_high_water_bytes.unwrap(), r.stack_size_bytes.unwrap());
    assert!(hw < size, "stack {hw} of {size} bytes");
}

#[test]
#[ignore = "needs image fix: the TFT port (USART1) stalls for good after M115's ~700-byte reply \
            (embassy-stm32 0.6 BufferedUartTx::write returns Pending without registering its \
            waker; reported to the lead)"]
fn the_tft_port_keeps_answering_after_m115() {
    let mut o = options();
    o.commands = vec!["M115".into(), "M105".into()];
    o.max_virtual_s = 6.0;
    let r = run(&o);
    let after = lines_after(&r, "Cap:");
    assert!(
        after.iter().filter(|l| l.starts_with("ok")).count() >= 2,
        "M115's ok and M105's answer: {after:?}"
    );
}

#[test]
fn g28_stops_each_axis_at_its_switch_bump_and_slow_approach() {
    let mut o = options();
    o.job = vec!["G28".into()];
    let r = run(&o);
    // Every axis ends on its switch: the carriage moved back exactly by its start offset
    // (Z: first raised 4 mm, Marlin's Z_HOMING_HEIGHT in the Ender-3 config).
    assert_eq!(r.net_steps["X"], -800);
    assert_eq!(r.net_steps["Y"], -800);
    assert_eq!(r.net_steps["Z"], -800);
    // The edge sequence of each axis: approach (towards the switch, ending pressed), bump
    // (away, 5 mm / 5 mm / 2 mm), slow approach (ending pressed, at a lower rate).
    let bump = [("X", 400), ("Y", 400), ("Z", 800)];
    for (axis, bump_steps) in bump {
        let mut runs = r.runs[axis].clone();
        if axis == "Z" {
            // The raise before X and Y home.
            assert_eq!(runs[0].dir, 1);
            assert_eq!(runs[0].steps, 1600, "Z raise: {runs:?}");
            runs.remove(0);
        }
        assert_eq!(runs.len(), 3, "{axis}: {runs:?}");
        assert!(runs[0].dir == -1 && runs[0].ended_pressed, "{axis} approach: {runs:?}");
        assert_eq!((runs[1].dir, runs[1].steps), (1, bump_steps), "{axis} bump: {runs:?}");
        assert!(runs[2].dir == -1 && runs[2].ended_pressed, "{axis} slow: {runs:?}");
        assert_eq!(runs[2].steps, bump_steps, "{axis}: back by the bump");
        assert!(
            runs[2].min_interval > runs[0].min_interval,
            "{axis}: the second approach is slower: {runs:?}"
        );
    }
    // X homes before Y, Y before Z's approach.
    assert!(r.runs["X"][0].t_first < r.runs["Y"][0].t_first);
    assert!(r.runs["Y"][2].t_last < r.runs["Z"][1].t_first);
    // Step pulses as the drivers need them (TMC2209: 100 ns high, 20 ns DIR setup).
    for axis in ["X", "Y", "Z"] {
        assert!(r.min_step_high_ns[axis].unwrap() >= 1000, "{:?}", r.min_step_high_ns);
        assert!(r.min_dir_setup_ns[axis].unwrap() >= 650, "{:?}", r.min_dir_setup_ns);
    }
}

#[test]
fn a_job_makes_exactly_the_steps_of_its_gcode() {
    let mut o = options();
    o.job = THREE_LAYERS.iter().map(|s| s.to_string()).collect();
    let r = run(&o);
    let want = expected_net_steps(THREE_LAYERS, o.start_mm);
    let got = [r.net_steps["X"], r.net_steps["Y"], r.net_steps["Z"], r.net_steps["E"]];
    assert_eq!(got, want, "{:?}", lines_after(&r, "SD init"));
    assert!(r.faults.is_empty() && r.resets.is_empty());
    assert_rates_within_limits(&r);
}

#[test]
fn a_layer_pause_stops_where_sim_run_stops() {
    let job: Vec<String> = THREE_LAYERS.iter().map(|s| s.to_string()).collect();
    // The simulator, the same library on virtual time, with the host `sim run` uses.
    let mut sc = sim::run::Scenario::new(sim::run::Policy::Firmware, sim::run::Mode::Layer);
    sc.pause = Some(sim::run::PauseWhen::AtLayer(2));
    sc.resume_after_us = Some(1_000_000);
    let out = sim::run::run(&sim::exec::PrinterFactory, &sc, &job).expect("sim runs");
    let want = out.report.pause_point_steps.expect("sim paused");
    let mut o = options();
    o.job = job;
    o.pause_at_layer = Some(2);
    let r = run(&o);
    let got = r.pause_point_steps.expect("the emulated board paused and parked");
    let want: Vec<i64> = want.iter().map(|&v| i64::from(v)).collect();
    assert_eq!(got.to_vec(), want, "emulated vs sim run: {:?}", r.lines);
    // Resumed and finished: the whole job's steps, as without the pause.
    let full = expected_net_steps(THREE_LAYERS, o.start_mm);
    let end = [r.net_steps["X"], r.net_steps["Y"], r.net_steps["Z"], r.net_steps["E"]];
    assert_eq!(end, full);
}

#[test]
fn settings_saved_with_m500_survive_a_reset() {
    let mut o = options();
    let flash = temp("settings.bin");
    let _ = std::fs::remove_file(&flash);
    o.flash_file = Some(flash.clone());
    o.commands = vec![
        "M92 X81.5".into(),
        "M500".into(),
        "@wait 300".into(),
        "@reset".into(),
        "@until SD init".into(),
        "M503".into(),
    ];
    let r = run(&o);
    let _ = std::fs::remove_file(&flash);
    assert_eq!(r.resets.len(), 1);
    assert_eq!(r.resets[0].kind, ResetKind::Pin);
    let after = lines_after(&r, "SD init");
    assert!(
        after.iter().any(|l| l.contains("M92") && l.contains("X81.5")),
        "M503 after the reset: {after:?}"
    );
}
