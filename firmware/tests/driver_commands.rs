//! The stepper-driver M-codes (TMC2209) through the printer's host link (M569, M350, M122, M906 through
//! the settings path), and the board's TMC2209 results as host messages, with the driver model
//! of `firmware::drivers::tmc2209` standing in for the board's UART lines.

use firmware::config::MachineConfig;
use firmware::drivers::tmc2209::{DriverReport, TmcError};
use firmware::motion::Axis;
use firmware::printer::{DriverRequest, Policy, Printer};

fn printer() -> Printer {
    Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE)
}

/// Send one line, run the executive until its `ok`, return the output.
fn send(p: &mut Printer, line: &str) -> String {
    let text = format!("{line}\n");
    assert_eq!(p.receive(text.as_bytes(), 0), text.len(), "line not taken");
    let mut out = String::new();
    for t in 0..1000u64 {
        p.poll(t * 1000);
        p.write_output(&mut out).unwrap();
        if out.lines().any(|l| l.starts_with("ok")) {
            break;
        }
    }
    out
}

#[test]
fn m569_switches_chopper_mode_and_asks_the_board() {
    let mut p = printer();
    assert!(
        send(&mut p, "M569").contains("X:stealthChop Y:stealthChop Z:stealthChop E:stealthChop")
    );
    send(&mut p, "M569 S0 X Y");
    assert_eq!(
        p.take_driver_request(),
        Some(DriverRequest::Apply { mask: 0b0011 })
    );
    assert!(!p.driver_settings(Axis::X).stealthchop);
    assert!(p.driver_settings(Axis::Z).stealthchop);
    assert!(send(&mut p, "M569").contains("X:spreadCycle Y:spreadCycle Z:stealthChop"));
}

#[test]
fn m350_scales_steps_per_mm_and_refuses_odd_values() {
    let mut p = printer();
    send(&mut p, "M350 X32 E8");
    assert_eq!(p.config().axis(Axis::X).steps_per_mm, 160.0);
    assert_eq!(p.config().axis(Axis::E).steps_per_mm, 46.5);
    assert_eq!(p.driver_settings(Axis::X).microsteps, 32);
    assert_eq!(
        p.take_driver_request(),
        Some(DriverRequest::Apply { mask: 0b1001 })
    );
    // M92 afterwards sets steps/mm at the new microstepping.
    send(&mut p, "M92 X161");
    assert_eq!(p.config().axis(Axis::X).steps_per_mm, 161.0);
    // A value the TMC2209 does not have changes nothing.
    let out = send(&mut p, "M350 S16 Y12");
    assert!(out.contains("echo:refused: M350 Y12"), "{out}");
    assert_eq!(p.config().axis(Axis::Y).steps_per_mm, 80.0);
    assert_eq!(p.config().axis(Axis::X).microsteps, 32);
    assert_eq!(p.take_driver_request(), None);
    assert!(send(&mut p, "M350").contains("M350 X32 Y16 Z16 E8"));
}

#[test]
fn m906_changes_what_the_board_applies() {
    let mut p = printer();
    assert_eq!(p.driver_settings(Axis::E).run_ma, 650);
    send(&mut p, "M906 E700");
    assert_eq!(p.driver_settings(Axis::E).run_ma, 700);
}

#[test]
fn m122_asks_the_board_and_prints_its_readings() {
    let mut p = printer();
    send(&mut p, "M122 Z");
    assert_eq!(
        p.take_driver_request(),
        Some(DriverRequest::Report { mask: 0b0100 })
    );
    send(&mut p, "M122");
    assert_eq!(
        p.take_driver_request(),
        Some(DriverRequest::Report { mask: 0b1111 })
    );
    let rep = DriverReport {
        gconf: 0x1C0,
        chopconf: 0x1401_0104,
        drv_status: (16 << 16) | (1 << 30) | 1,
        gstat: 0,
    };
    p.driver_report(Axis::Z, Ok(rep));
    p.driver_report(Axis::E, Err(TmcError::NoReply(0)));
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    assert!(out.contains("echo:Z: TMC2209 ok,"), "{out}");
    assert!(out.contains("1/16, stealthChop"), "{out}");
    assert!(out.contains("over-temperature warning"), "{out}");
    assert!(out.contains("echo:E: TMC2209 no answer on UART"), "{out}");
}

#[test]
fn a_driver_that_does_not_answer_is_an_error_line() {
    let mut p = printer();
    p.driver_configured(Axis::Y, Err(TmcError::NoReply(0)));
    p.driver_configured(Axis::X, Ok(()));
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    assert!(
        out.contains("Error:TMC2209 Y: no answer on UART: motion disabled."),
        "{out}"
    );
    assert!(
        out.contains("echo:TMC2209 X: 580 mA, 1/16 microsteps, stealthChop"),
        "{out}"
    );
}

/// The board's start-up notice after a fault or watchdog reset reaches every port (the USB
/// host too, which could not be told at the moment of the fault).
#[test]
fn a_reset_cause_is_said_on_every_port() {
    use firmware::link::PortId;
    let mut p = printer();
    p.board_notice("Watchdog Reset: a loop stopped");
    for port in [PortId::Usb, PortId::Tft] {
        let mut buf = [0u8; 256];
        let n = p.read_output_on(port, &mut buf);
        let text = String::from_utf8_lossy(&buf[..n]);
        assert!(
            text.lines()
                .any(|l| l == "echo:Watchdog Reset: a loop stopped"),
            "{port:?}: {text}"
        );
    }
}
