//! Issue 31's small wrong answers, through the real `Printer` as a host sees them: each line
//! is refused with its reason and the word it names, and nothing changes (docs/frontend.md,
//! "Refusals: the reason and the word"). Cost: well under a second.

mod support;

use firmware::link::PortId;
use firmware::printer::Printer;
use firmware::thermal::HeaterId;

/// Send one line, let the printer answer; the answer.
fn ask(p: &mut Printer, now: &mut u64, line: &str) -> String {
    let l = format!("{line}\n");
    assert_eq!(p.receive(l.as_bytes(), *now), l.len(), "{line}");
    *now += 1000;
    p.poll(*now);
    let mut s = String::new();
    p.write_output_on(PortId::Usb, &mut s).unwrap();
    assert!(s.lines().any(|x| x.starts_with("ok")), "{line}: no ok: {s}");
    s
}

fn refused(answer: &str) -> &str {
    answer
        .lines()
        .find_map(|l| l.strip_prefix("echo:refused: "))
        .unwrap_or_else(|| panic!("not refused: {answer}"))
}

#[test]
fn an_extruder_or_fan_that_is_not_there_is_refused_never_applied_to_the_one_that_is() {
    let mut p = support::printer();
    let mut now = 1000;
    ask(&mut p, &mut now, "M104 S200");
    assert_eq!(p.thermal().target_c(HeaterId::Hotend), 200.0);
    for (line, why) in [
        // Issue 31: it heated the only hotend.
        (
            "M104 T9 S210",
            "M104 T9: invalid extruder (this printer has T0 only)",
        ),
        // Issue 32: FlashPrint's dual-extruder header switched the only hotend off.
        (
            "M104 S0 T1",
            "M104 T1: invalid extruder (this printer has T0 only)",
        ),
        (
            "M109 T1 S0",
            "M109 T1: invalid extruder (this printer has T0 only)",
        ),
        // Marlin on one extruder: invalid_extruder_error, nothing else.
        ("T1", "T1: invalid extruder (this printer has T0 only)"),
    ] {
        assert_eq!(refused(&ask(&mut p, &mut now, line)), why);
        assert_eq!(p.thermal().target_c(HeaterId::Hotend), 200.0, "{line}");
    }
    // T0 and M104 T0 are the hotend that is there.
    assert!(!ask(&mut p, &mut now, "T0").contains("refused"));
    ask(&mut p, &mut now, "M104 T0 S190");
    assert_eq!(p.thermal().target_c(HeaterId::Hotend), 190.0);

    ask(&mut p, &mut now, "M106 S128");
    assert_eq!(p.fan_pwm(), 128);
    // A fan that is not there: said as a note (not a refusal: Bambu's auxiliary `M106 P2` is
    // no lost move), and the fan that is there keeps its speed.
    for (line, note) in [
        (
            "M106 P9 S255",
            "echo:M106 P9: no such fan, ignored (this printer has P0 only)",
        ),
        (
            "M107 P1",
            "echo:M107 P1: no such fan, ignored (this printer has P0 only)",
        ),
    ] {
        let out = ask(&mut p, &mut now, line);
        assert!(
            out.contains(note) && !out.contains("refused"),
            "{line}: {out}"
        );
        assert_eq!(p.fan_pwm(), 128, "{line}");
    }
    ask(&mut p, &mut now, "M106 P0 S0");
    assert_eq!(p.fan_pwm(), 0);
}

#[test]
fn m303_names_a_heater_that_is_not_there() {
    let mut p = support::printer();
    let mut now = 1000;
    // Issue 31: it answered "heater busy".
    assert_eq!(
        refused(&ask(&mut p, &mut now, "M303 E5 S200")),
        "M303 E5: no such heater (E0 the hotend, E-1 the bed)"
    );
    assert!(p.thermal().autotune_status(HeaterId::Hotend).is_none());
}

#[test]
fn a_refused_value_names_its_word_and_a_slow_feed_is_refused() {
    let mut p = support::printer();
    let mut now = 1000;
    for (line, why) in [
        // Issue 31: these blamed "(column 1)".
        ("M569 S2 X", "number out of range (column 7)"),
        ("M113 S1000000", "number out of range (column 7)"),
        // Issue 31: exponents are one number, refused at their word when out of range.
        ("G1 X1e39", "number out of range (column 5)"),
        ("G1 X20 E1e9", "number out of range (column 9)"),
        // Issue 31: an 83-day move.
        ("G1 X13 F0.0001", "feed rate below 6 mm/min"),
        ("M104 S500", "M104 S500: target above limit 260C"),
    ] {
        assert_eq!(refused(&ask(&mut p, &mut now, line)), why, "{line}");
    }
    assert_eq!(p.status().position, [0; 4]);
    assert_eq!(p.next_step_ns(), None);
}
