//! The unmodified SKR 2 image on the emulated board (docs/board-emu.md): boot, homing, a job,
//! a layer pause against `sim run`, settings across a reset, SD printing, and faults.
//! Each test builds nothing but the image (once) and runs the board for a few virtual seconds.

mod support;

use board_emu::rcc::ResetKind;
use support::*;

/// No axis steps faster than its limit (max feed × steps/mm). An edge interval may be shorter
/// than the scheduled one by a tick of the 4 MHz step timer (250 ns) and by the step
/// interrupt's entry jitter (a critical section in thread mode delays one entry more than
/// the next): 2 µs are allowed for both. A burst after a stall is ~100 times the limit.
fn assert_rates_within_limits(r: &board_emu::report::Report) {
    for (axis, limit) in &r.step_rate_limit_hz {
        if let Some(rate) = r.max_step_rate_hz[axis] {
            let allowed = 1.0 / (1.0 / limit - 2e-6);
            assert!(rate <= allowed, "{axis}: {rate} Hz > {limit} Hz");
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
            r.lines
                .iter()
                .any(|l| l.starts_with(&format!("echo:TMC2209 {axis}: "))),
            "driver {axis} configured over its UART: {:?}",
            r.lines
        );
    }
    assert_eq!(r.tmc_datagrams.iter().filter(|&&n| n > 0).count(), 4);
    assert!(
        r.faults.is_empty() && r.resets.is_empty(),
        "{:?} {:?}",
        r.faults,
        r.resets
    );
    assert!(r.safe_power_at_end);
    // The watchdog runs with the 2 s the image asks for (at the typical 32 kHz LSI).
    assert!(
        (r.watchdog_timeout_s - 2.0).abs() < 0.01,
        "{}",
        r.watchdog_timeout_s
    );
    let (hw, size) = (
        r.stack_high_water_bytes.unwrap(),
        r.stack_size_bytes.unwrap(),
    );
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
        assert!(
            runs[0].dir == -1 && runs[0].ended_pressed,
            "{axis} approach: {runs:?}"
        );
        assert_eq!(
            (runs[1].dir, runs[1].steps),
            (1, bump_steps),
            "{axis} bump: {runs:?}"
        );
        assert!(
            runs[2].dir == -1 && runs[2].ended_pressed,
            "{axis} slow: {runs:?}"
        );
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
        assert!(
            r.min_step_high_ns[axis].unwrap() >= 1000,
            "{:?}",
            r.min_step_high_ns
        );
        assert!(
            r.min_dir_setup_ns[axis].unwrap() >= 650,
            "{:?}",
            r.min_dir_setup_ns
        );
    }
}

#[test]
fn a_job_makes_exactly_the_steps_of_its_gcode() {
    let mut o = options();
    o.job = THREE_LAYERS.iter().map(|s| s.to_string()).collect();
    let r = run(&o);
    let want = expected_net_steps(THREE_LAYERS, o.start_mm);
    let got = [
        r.net_steps["X"],
        r.net_steps["Y"],
        r.net_steps["Z"],
        r.net_steps["E"],
    ];
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
    let got = r
        .pause_point_steps
        .expect("the emulated board paused and parked");
    let want: Vec<i64> = want.iter().map(|&v| i64::from(v)).collect();
    assert_eq!(got.to_vec(), want, "emulated vs sim run: {:?}", r.lines);
    // Resumed and finished: the whole job's steps, as without the pause.
    let full = expected_net_steps(THREE_LAYERS, o.start_mm);
    let end = [
        r.net_steps["X"],
        r.net_steps["Y"],
        r.net_steps["Z"],
        r.net_steps["E"],
    ];
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
        after
            .iter()
            .any(|l| l.contains("M92") && l.contains("X81.5")),
        "M503 after the reset: {after:?}"
    );
}

/// A long move (X 10 → 150 mm at 50 mm/s, about 2.8 s) with the hot end heating: faults are
/// injected 0.5 s after the first line is answered, while the head moves and the heater is
/// on.
const LONG_MOVE: &[&str] = &["M302 P1", "M104 S200", "G28", "G1 X150 Y100 F3000"];

fn with_fault(f: board_emu::fault::Fault) -> board_emu::report::Report {
    let mut o = options();
    o.job = LONG_MOVE.iter().map(|s| s.to_string()).collect();
    o.fault = Some(f);
    o.fault_after_s = 0.5;
    o.settle_s = 2.5;
    o.max_virtual_s = 20.0;
    run(&o)
}

#[test]
fn a_stalled_motion_task_ends_in_a_watchdog_reset_with_everything_off() {
    let r = with_fault(board_emu::fault::Fault::MotionStall);
    let a = r.after_fault.clone().expect("injected");
    assert!(a.heater_on_at_injection, "the heater was on: {a:?}");
    assert_eq!(r.watchdog_resets, 1, "{:?}", r.resets);
    // The reset comes within the watchdog's period and leaves heaters and drivers off.
    let reset = a.reset_after_s.expect("a reset");
    assert!(reset <= r.watchdog_timeout_s + 0.06, "{reset} s");
    assert!(a.safe_after_ms.unwrap() <= reset * 1e3 + 1.0, "{a:?}");
    assert!(!r.heaters_powered_at_end.iter().any(|h| *h));
    // The next start-up says why, as Marlin's `echo: Watchdog Reset`.
    assert!(
        r.lines.iter().any(|l| l.starts_with("echo:Watchdog Reset")),
        "{:?}",
        r.lines
    );
}

#[test]
fn a_hardfault_reaches_the_safe_state_and_is_reported() {
    let r = with_fault(board_emu::fault::Fault::HardFault);
    let a = r.after_fault.clone().expect("injected");
    assert!(a.heater_on_at_injection);
    assert_eq!(r.faults.len(), 1, "{:?}", r.faults);
    // Heaters and drivers off within a millisecond, then a reset, then the reason.
    assert!(a.safe_after_ms.unwrap() < 1.0, "{a:?}");
    assert_eq!(r.resets.first().map(|x| x.kind), Some(ResetKind::Software));
    assert!(
        r.lines
            .iter()
            .any(|l| l.contains("firmware fault (HardFault) before this reset")),
        "{:?}",
        r.lines
    );
}

#[test]
#[ignore = "needs image fix: DefaultHandler reaching the safe state (branch image); today an \
            unexpected interrupt hangs in cortex-m-rt's loop with the heater on until the \
            watchdog resets the board ~2 s later"]
fn an_unexpected_interrupt_reaches_the_safe_state_at_once() {
    let r = with_fault(board_emu::fault::Fault::UnexpectedIrq);
    let a = r.after_fault.clone().expect("injected");
    assert!(a.heater_on_at_injection);
    assert!(a.safe_after_ms.unwrap() < 1.0, "{a:?}");
}

#[test]
#[ignore = "needs image fix: no step burst after a stall (branch image); today a 5 ms \
            executor stall fires the overdue steps back to back at ~280 kHz"]
fn an_executor_stall_while_moving_makes_no_step_burst() {
    let r = with_fault(board_emu::fault::Fault::ExecutorStall);
    assert!(r.after_fault.is_some());
    assert_rates_within_limits(&r);
    assert!(r.resets.is_empty() && r.faults.is_empty());
}

#[test]
#[ignore = "needs image fix: reversed-driver check before PC13 (branch image); today SAFE_POWER \
            goes high whatever the EN pins read"]
fn a_driver_plugged_in_backwards_is_never_powered() {
    let mut o = options();
    o.reversed_driver = Some(0);
    o.max_virtual_s = 5.0;
    let r = run(&o);
    assert_eq!(r.safe_power_first_high_s, None, "SAFE_POWER must stay low");
    assert!(
        r.lines
            .iter()
            .any(|l| l.starts_with("Error:") && l.contains('X')),
        "{:?}",
        r.lines
    );
}

#[test]
fn a_print_from_the_card_pauses_at_its_layer_and_finishes() {
    let img = temp("card.img");
    let job: String = THREE_LAYERS[1..].iter().map(|l| format!("{l}\n")).collect();
    sim::sd::write_image(&img, &[("JOB.GCO".into(), job.into_bytes())]).expect("card image");
    let mut o = options();
    o.sd_image = Some(img.clone());
    o.commands = vec![
        "M302 P1".into(),
        "M761 L2".into(),
        "M23 JOB.GCO".into(),
        "M24".into(),
        "@until Done printing".into(),
        "M400".into(),
    ];
    o.pause_at_layer = None;
    let r = run(&o);
    let _ = std::fs::remove_file(&img);
    assert!(r.sd_blocks_read > 0);
    assert!(
        r.lines.iter().any(|l| l.starts_with("//action:paused")),
        "paused at layer 2: {:?}",
        r.lines
    );
    assert!(
        r.lines.iter().any(|l| l.contains("Done printing")),
        "{:?}",
        r.lines
    );
    let want = expected_net_steps(&THREE_LAYERS[1..], o.start_mm);
    let got = [
        r.net_steps["X"],
        r.net_steps["Y"],
        r.net_steps["Z"],
        r.net_steps["E"],
    ];
    assert_eq!(got, want);
    assert!(r.pause_point_steps.is_some());
}

fn boots_to_the_prompt(r: &board_emu::report::Report) {
    assert!(
        r.faults.is_empty() && r.resets.is_empty(),
        "{:?} {:?}",
        r.faults,
        r.resets
    );
    assert!(r.m115.is_some(), "reached the prompt: {:?}", r.lines);
}

#[test]
#[ignore = "needs image fix: the TFT port stall (embassy BufferedUartTx::write) — the longer \
            boot output with a foreign settings area fills the UART ring while the drivers \
            are configured, and the port never sends again (M115 unanswered)"]
fn boots_with_a_foreign_settings_area_of_zeros() {
    let mut o = options();
    o.flash_fill = Some(board_emu::scenario::FlashFill::Zeros);
    boots_to_the_prompt(&run(&o));
}

#[test]
fn boots_with_a_foreign_settings_area_of_random_bytes() {
    let mut o = options();
    o.flash_fill = Some(board_emu::scenario::FlashFill::Random);
    boots_to_the_prompt(&run(&o));
}

#[test]
#[ignore = "needs faults fix (branch faults, issue 24): embedded-sdmmc divides by zero at \
            mount; today the board panics and resets every 0.54 s"]
fn boots_with_a_card_whose_boot_sector_has_zero_sectors_per_cluster() {
    let img = temp("broken.img");
    sim::sd::write_image(&img, &[("A.GCO".into(), b"G28\n".to_vec())]).expect("card image");
    let mut card = std::fs::read(&img).expect("image");
    // The partition's boot sector (block 2048): BPB_SecPerClus at byte 13 := 0.
    card[2048 * 512 + 13] = 0;
    std::fs::write(&img, &card).expect("write");
    let mut o = options();
    o.sd_image = Some(img.clone());
    o.commands = vec!["M21".into()];
    let r = run(&o);
    let _ = std::fs::remove_file(&img);
    boots_to_the_prompt(&r);
}
