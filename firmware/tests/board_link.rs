//! What the board tells the executive about itself, through the executive's public API as the
//! SKR 2 image calls it: a driver module plugged in backwards (Marlin's report on every port,
//! then a halt), the board's measurements in M115, and the flash store's erase-ahead while
//! idle (`Printer::service_store`). Cost: well under 1 s.

use firmware::config::MachineConfig;
use firmware::link::PortId;
use firmware::printer::{BoardStats, Policy, Printer, State, ERASE_AHEAD_IDLE_US};
use firmware::storage::{Moment, NorFlashModel, RecordStore, SettingsStore};
use firmware::thermal::HeaterId;

fn output(p: &mut Printer, port: PortId) -> String {
    let mut s = String::new();
    p.write_output_on(port, &mut s).unwrap();
    s
}

#[test]
fn a_backward_driver_is_reported_on_every_port_and_halts() {
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    // A host set a temperature before (the check runs at start-up, but the halt must hold
    // whatever came first).
    assert_eq!(p.receive_on(PortId::Usb, b"M104 S200\n", 0), 10);
    p.poll(1_000);
    assert_eq!(p.thermal().target_c(HeaterId::Hotend), 200.0);
    p.drivers_backward(&["X", "E0"]);
    p.poll(2_000);
    for port in [PortId::Usb, PortId::Tft] {
        let out = output(&mut p, port);
        // Marlin: SERIAL_ERROR_START, the axis, " driver is backward!".
        assert!(
            out.contains("Error:X driver is backward!\n"),
            "{port:?}: {out}"
        );
        assert!(
            out.contains("Error:E0 driver is backward!\n"),
            "{port:?}: {out}"
        );
        assert!(!out.contains("Error:Y driver"), "{out}");
        assert!(out.contains("SAFE_POWER"), "{out}");
    }
    assert_eq!(p.state(), State::Halted);
    assert_eq!(p.thermal().target_c(HeaterId::Hotend), 0.0);
    // Nothing moves, nothing heats afterwards.
    let _ = p.receive_on(PortId::Usb, b"M104 S200\nG1 X10 F3000\n", 3_000);
    for t in 4..200u64 {
        p.poll(t * 1000);
    }
    assert_eq!(p.thermal().target_c(HeaterId::Hotend), 0.0);
    assert_eq!(p.next_step_ns(), None);
    assert_eq!(p.state(), State::Halted);
}

#[test]
fn m115_reports_the_board_measurements_when_the_board_gives_them() {
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    assert_eq!(p.receive_on(PortId::Usb, b"M115\n", 0), 5);
    p.poll(1_000);
    let out = output(&mut p, PortId::Usb);
    assert!(
        out.contains("FIRMWARE_NAME:") && !out.contains("board:"),
        "{out}"
    );
    p.set_board_stats(BoardStats {
        stack_used_bytes: 9876,
        stack_size_bytes: 75_776,
        steps_late: 3,
        steps_capped: 7,
        worst_late_us: 5012,
    });
    assert_eq!(p.receive_on(PortId::Usb, b"M115\n", 2_000), 5);
    p.poll(3_000);
    let out = output(&mut p, PortId::Usb);
    let line = out
        .lines()
        .find(|l| l.starts_with("echo:board:"))
        .unwrap_or_else(|| panic!("{out}"));
    for want in [
        "9876 of 75776 bytes",
        "stall 3",
        "worst 5012 us",
        "axis limit 7",
    ] {
        assert!(line.contains(want), "{want}: {line}");
    }
    // After the capabilities, before the ok.
    let cap = out.rfind("Cap:").unwrap();
    let board = out.find("echo:board:").unwrap();
    let ok = out.rfind("ok").unwrap();
    assert!(cap < board && board < ok, "{out}");
}

type Flash = NorFlashModel<Vec<u8>, 16, 4096>;

/// A store of two sectors, as the board's, whose current sector is nearly full (under the
/// reserve): the erase-ahead's switch to the other sector, and the erase of this one, are due.
fn nearly_full_store() -> SettingsStore<Flash> {
    let mut st = SettingsStore::new(Flash::erased(vec![0; 2 * 4096]), 0..2 * 4096).unwrap();
    let s = Printer::new(MachineConfig::ENDER3).settings();
    while st
        .free_bytes()
        .unwrap()
        .is_none_or(|f| f >= st.reserve_bytes())
    {
        st.save_settings(&s, Moment::Idle).unwrap();
    }
    st
}

#[test]
fn the_store_erases_ahead_only_after_ten_seconds_idle_and_once() {
    let mut st = nearly_full_store();
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    p.load_settings(&mut st);
    let erases = |st: &mut SettingsStore<Flash>| st.flash_mut().erases();
    let e0 = erases(&mut st);
    // Busy (a move) for a while, then idle: nothing before 10 s of idle.
    assert_eq!(p.receive(b"G1 X50 F600\n", 0), 12);
    let mut t = 0u64;
    let mut idle_at = None;
    let mut erased_at = None;
    while t < 30_000_000 {
        while p.next_step_ns().is_some_and(|ns| ns <= t * 1000) {
            let _ = p.next_step();
        }
        p.poll(t);
        if p.state() == State::Idle && idle_at.is_none() {
            idle_at = Some(t);
        }
        p.service_store(&mut st);
        if erased_at.is_none() && erases(&mut st) > e0 {
            erased_at = Some(t);
        }
        t += 1_000;
    }
    let idle_at = idle_at.expect("went idle");
    let erased_at = erased_at.expect("erased ahead");
    assert!(idle_at > 1_000_000, "the move took a while: {idle_at}");
    assert!(
        erased_at >= idle_at + ERASE_AHEAD_IDLE_US
            && erased_at < idle_at + ERASE_AHEAD_IDLE_US + 2_000,
        "idle at {idle_at}, erased at {erased_at}"
    );
    assert_eq!(erases(&mut st), e0 + 1, "once per idle period");
    assert!(st.free_bytes().unwrap().unwrap() >= st.reserve_bytes());
    // The settings survived.
    assert!(st.load_settings().unwrap().is_some());
}
