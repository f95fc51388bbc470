//! Reports hosts expect of a Marlin-class firmware (printer/report.rs): temperature lines during
//! M109 about once a second (Marlin's `wait_for_hotend`), M155 auto-report, M113 keep-alive
//! period, M31 print time, M27 without an SD card, and M115's truthful capabilities.
mod support;

use support::*;

fn lines_starting<'a>(out: &'a str, prefix: &str) -> Vec<&'a str> {
    out.lines().filter(|l| l.starts_with(prefix)).collect()
}

#[test]
fn temperatures_about_once_a_second_while_waiting_for_the_hotend() {
    let mut p = printer();
    // No heater samples in this harness: the wait never ends; 5.5 s of it.
    let r = run_gcode(&mut p, &["M104 S200", "M109 S200"], &[], 5_500_000);
    let temps = lines_starting(&r.out, "T:");
    assert!((5..=7).contains(&temps.len()), "{}", r.out);
    assert!(
        temps
            .iter()
            .all(|l| l.contains(" /200.0") && l.contains(" B:")),
        "{temps:?}"
    );
    // busy: keep-alives go on (Marlin's default 2 s).
    assert!(lines_starting(&r.out, "busy:").len() >= 2, "{}", r.out);
}

#[test]
fn m113_sets_the_busy_period_and_s0_silences_it() {
    let mut p = printer();
    let r = run_gcode(
        &mut p,
        &["M113 S0", "M104 S200", "M109 S200"],
        &[],
        5_500_000,
    );
    assert!(lines_starting(&r.out, "busy:").is_empty(), "{}", r.out);
    let mut p = printer();
    let r = run_gcode(
        &mut p,
        &["M113", "M113 S1", "M104 S200", "M109 S200"],
        &[],
        5_500_000,
    );
    assert!(r.out.contains("echo:M113 S2"), "{}", r.out);
    assert!(lines_starting(&r.out, "busy:").len() >= 4, "{}", r.out);
}

#[test]
fn m155_reports_temperatures_periodically_until_s0() {
    let mut p = printer();
    let r = run_gcode(&mut p, &["M155 S1", "G4 P3500"], &[], 4_000_000);
    let n = lines_starting(&r.out, "T:").len();
    assert!((3..=5).contains(&n), "{}", r.out);
    let r = run_gcode(&mut p, &["M155 S0", "G4 P3000"], &[], 4_000_000);
    assert!(lines_starting(&r.out, "T:").is_empty(), "{}", r.out);
    assert!(run_gcode(&mut p, &["M155 S61"], &[], 100_000)
        .out
        .lines()
        .any(|l| l.starts_with("Error:") || l.starts_with("echo:")));
}

#[test]
fn m31_times_the_job_from_its_heater_wait_and_m27_answers_without_sd() {
    let mut p = printer();
    let r = run_gcode(&mut p, &["M104 S200", "M109 S200"], &[], 3_200_000);
    assert!(lines_starting(&r.out, "T:").len() >= 3, "{}", r.out);
    // The wait still runs: M31 is answered at once (it takes no queue room).
    assert_eq!(p.receive(b"M31\n", 3_300_000), 4);
    p.poll(3_300_000);
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    assert!(out.contains("echo:Print time: 3s"), "{out}");
    assert_eq!(p.receive(b"M73 P42\nM27\n", 3_400_000), 12);
    p.poll(3_400_000);
    out.clear();
    p.write_output(&mut out).unwrap();
    assert!(out.contains("echo:Not SD printing"), "{out}");
    assert!(out.contains("progress 42%"), "{out}");
}

#[test]
fn m115_reports_autoreport_temp_and_progress() {
    let mut p = printer();
    let r = run_gcode(&mut p, &["M115"], &[], 100_000);
    assert!(r.out.contains("Cap:AUTOREPORT_TEMP:1"), "{}", r.out);
    assert!(r.out.contains("Cap:PROGRESS:1"), "{}", r.out);
}
