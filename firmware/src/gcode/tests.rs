use super::*;
use crate::motion::PauseMode;
use proptest::prelude::*;

/// The command `s` parses to (panics, naming `s`, if it parses to none or to an error).
pub(super) fn cmd(s: &str) -> Command {
    match parse_line(s.as_bytes()) {
        Ok(Line {
            command: Some(c), ..
        }) => c,
        other => panic!("{s:?}: {other:?}"),
    }
}

/// The kind of error `s` parses to (panics, naming `s`, if it parses).
pub(super) fn kind(s: &str) -> ParseErrorKind {
    match parse_line(s.as_bytes()) {
        Err(e) => e.kind,
        Ok(l) => panic!("{s:?} parsed: {l:?}"),
    }
}

fn emit(c: &Command) -> heapless::String<256> {
    let mut s = heapless::String::new();
    core::fmt::Write::write_fmt(&mut s, format_args!("{c}")).unwrap();
    s
}

#[test]
fn moves() {
    assert_eq!(
        cmd("G1 X10 Y-2.5 Z.3 E0.05 F1800"),
        Command::Motion(MotionCommand::Move {
            rapid: false,
            axes: AxisWords([Some(10.0), Some(-2.5), Some(0.3), Some(0.05)]),
            feed: Some(1800.0)
        })
    );
    assert_eq!(
        cmd("g0x1y2"),
        Command::Motion(MotionCommand::Move {
            rapid: true,
            axes: AxisWords([Some(1.0), Some(2.0), None, None]),
            feed: None
        })
    );
    assert_eq!(cmd("G01 X1"), cmd("G1 X1"));
    // E is a letter after a blank or a complete number, an exponent inside one (as C's
    // `strtof`, Marlin's reader, takes it): `X1e-05` is one number, never X1 and E-05.
    assert_eq!(
        cmd("G1 X1 E5"),
        Command::Motion(MotionCommand::Move {
            rapid: false,
            axes: AxisWords([Some(1.0), None, None, Some(5.0)]),
            feed: None
        })
    );
    assert_eq!(
        cmd("G1 X1e-05 Y20"),
        Command::Motion(MotionCommand::Move {
            rapid: false,
            axes: AxisWords([Some(1e-5), Some(20.0), None, None]),
            feed: None
        })
    );
    assert_eq!(
        cmd("G1 X1E5"),
        Command::Motion(MotionCommand::Move {
            rapid: false,
            axes: AxisWords([Some(1e5), None, None, None]),
            feed: None
        })
    );
}

#[test]
fn comments() {
    let l = parse_line(b";LAYER_CHANGE").unwrap();
    assert_eq!(l.command, None);
    assert_eq!(l.comment, Some(&b"LAYER_CHANGE"[..]));
    let l = parse_line(b"G28 (home) X ; all\r\n").unwrap();
    assert_eq!(
        l.command,
        Some(Command::Motion(MotionCommand::Home(AxisFlags([
            true, false, false, false
        ]))))
    );
    assert_eq!(l.comment, Some(&b" all"[..]));
    let l = parse_line(b"(only paren)").unwrap();
    assert_eq!(l.comment, Some(&b"only paren"[..]));
    assert_eq!(parse_line(b"   ").unwrap().command, None);
    assert_eq!(parse_line(b"").unwrap().command, None);
    assert_eq!(kind("G1 (open X1"), ParseErrorKind::UnclosedComment);
}

#[test]
fn errors_are_specific() {
    assert_eq!(kind("G1 X"), ParseErrorKind::MissingNumber);
    assert_eq!(kind("G1 Xnan"), ParseErrorKind::MissingNumber);
    assert_eq!(kind("G1 Xinf"), ParseErrorKind::MissingNumber);
    assert_eq!(kind("G1 X-"), ParseErrorKind::MissingNumber);
    // An exponent is part of the number: out of range is refused at the word, never an E.
    assert_eq!(kind("M104 S1e30"), ParseErrorKind::OutOfRange);
    assert_eq!(kind("G1 X1e39"), ParseErrorKind::OutOfRange);
    assert_eq!(kind("G1 X20 E1e9"), ParseErrorKind::OutOfRange);
    assert_eq!(parse_line(b"G1 X20 E1e9").unwrap_err().at, 8);
    assert_eq!(kind("G1 X1e5.5"), ParseErrorKind::BadNumber);
    assert_eq!(
        kind("G1 X1000000000000000000000000000000"),
        ParseErrorKind::TooManyDigits
    );
    assert_eq!(kind("G1 X99999999"), ParseErrorKind::OutOfRange);
    assert_eq!(kind("G1 Q5"), ParseErrorKind::UnexpectedLetter);
    assert_eq!(kind("G1 X1 X2"), ParseErrorKind::DuplicateLetter);
    assert_eq!(kind("G1 X1.2.3"), ParseErrorKind::BadByte);
    assert_eq!(kind("G1 X1,5"), ParseErrorKind::BadByte);
    assert_eq!(kind("G1 X1\u{7}"), ParseErrorKind::BadByte);
    assert_eq!(kind("G1 X\u{e9}"), ParseErrorKind::BadByte);
    assert_eq!(kind("G"), ParseErrorKind::MissingNumber);
    assert_eq!(kind("X10 Y10"), ParseErrorKind::NoCommand);
    assert_eq!(kind("1234"), ParseErrorKind::NoCommand);
    assert_eq!(kind("G999999"), ParseErrorKind::BadCode);
    assert_eq!(kind("M110 N1.5"), ParseErrorKind::NotWhole);
    assert_eq!(kind("M110 N-2"), ParseErrorKind::Negative);
    assert_eq!(kind("M106 S300"), ParseErrorKind::OutOfRange);
    assert_eq!(kind("M761 L3 Z2"), ParseErrorKind::BadValue);
    assert_eq!(kind("M25 S2"), ParseErrorKind::BadValue);
    assert_eq!(kind("T300"), ParseErrorKind::OutOfRange);
    // A refused value names its word's column (issue 31: these blamed column 1).
    for (line, col) in [
        ("M569 S2 X", 7),
        ("M113 S1000000", 7),
        ("M155 S61", 7),
        ("M106 S300", 7),
        ("G2 X1 Y1 I1 P200", 14),
        ("M761 L3 Z2", 9),
        ("M761 C1", 7),
        ("M27 S99999", 6),
    ] {
        let e = parse_line(line.as_bytes()).unwrap_err();
        assert_eq!(e.at + 1, col, "{line}: {e}");
        assert!(format!("{e}").ends_with(&format!("(column {col})")), "{e}");
    }
    // Every error has a message and a position.
    let e = parse_line(b"G1 X1 X2").unwrap_err();
    assert_eq!(e.at, 6);
    assert_eq!(e.message(), "parameter given twice");
}

#[test]
fn unknown_commands() {
    assert_eq!(
        cmd("M999 X1"),
        Command::Unknown(Text::try_from("M999 X1").unwrap())
    );
    assert_eq!(
        cmd("M862.3 P \"MK3S\" ; check"),
        Command::Unknown(Text::try_from("M862.3 P \"MK3S\"").unwrap())
    );
    assert_eq!(
        cmd("M928 my_file.gco"),
        Command::Unknown(Text::try_from("M928 my_file.gco").unwrap())
    );
    assert_eq!(
        cmd("EXCLUDE_OBJECT_START NAME=part_1"),
        Command::Unknown(Text::try_from("EXCLUDE_OBJECT_START NAME=part_1").unwrap())
    );
    // Known codes keep strict syntax.
    assert_eq!(kind("M104 my_file.gco"), ParseErrorKind::BadByte);
}

#[test]
fn text_commands() {
    assert_eq!(
        cmd("M117 Printing 1/3 (ok) ; c"),
        Command::Report(ReportCommand::Message(
            Text::try_from("Printing 1/3 (ok)").unwrap()
        ))
    );
    assert_eq!(
        cmd("M117"),
        Command::Report(ReportCommand::Message(Text::new()))
    );
    assert_eq!(
        cmd("M118 E1 hello"),
        Command::Report(ReportCommand::Echo(Text::try_from("E1 hello").unwrap()))
    );
    // Display text is cut, never refused (a long M117 must not stop a job).
    let long = format!("M117 {}", "x".repeat(TEXT_CAP + 1));
    assert_eq!(
        cmd(&long),
        Command::Report(ReportCommand::Message(
            Text::try_from("x".repeat(TEXT_CAP).as_str()).unwrap()
        ))
    );
    // ... at a character boundary: `é` (2 bytes) straddling the cap is dropped whole.
    let long = format!("M118 {}é{}", "x".repeat(TEXT_CAP - 1), "y".repeat(9));
    assert_eq!(
        cmd(&long),
        Command::Report(ReportCommand::Echo(
            Text::try_from("x".repeat(TEXT_CAP - 1).as_str()).unwrap()
        ))
    );
    let long = format!(
        "EXCLUDE_OBJECT_DEFINE NAME=a POLYGON=[{}]",
        "[1,2],".repeat(40)
    );
    assert!(matches!(cmd(&long), Command::Unknown(t) if t.len() == TEXT_CAP));
    assert_eq!(kind("M117 a\u{1}b"), ParseErrorKind::BadText);
}

#[test]
fn firmware_specific() {
    assert_eq!(
        cmd("M760 R2 Z5 X235 Y235 F3600 S3 V12 L0.2 T45"),
        Command::Pause(PauseCommand::Params(PauseParams {
            retract_mm: Some(2.0),
            lift_z_mm: Some(5.0),
            park_x_mm: Some(235.0),
            park_y_mm: Some(235.0),
            park_feed_mm_min: Some(3600.0),
            speedup_factor: Some(3.0),
            max_volumetric_mm3_s: Some(12.0),
            segment_len_mm: Some(0.2),
            nozzle_timeout_s: Some(45.0),
        }))
    );
    assert_eq!(
        cmd("M760"),
        Command::Pause(PauseCommand::Params(PauseParams::default()))
    );
    assert_eq!(
        cmd("M761 L12"),
        Command::Pause(PauseCommand::Schedule(PauseSchedule::Layer(12)))
    );
    assert_eq!(
        cmd("M761 Z4.2"),
        Command::Pause(PauseCommand::Schedule(PauseSchedule::Z(4.2)))
    );
    assert_eq!(
        cmd("M761 C"),
        Command::Pause(PauseCommand::Schedule(PauseSchedule::Clear))
    );
    assert_eq!(
        cmd("M761"),
        Command::Pause(PauseCommand::Schedule(PauseSchedule::Report))
    );
    assert_eq!(
        cmd("M25 S1"),
        Command::Pause(PauseCommand::Pause {
            m601: false,
            mode: PauseMode::Now
        })
    );
    assert_eq!(
        cmd("M601"),
        Command::Pause(PauseCommand::Pause {
            m601: true,
            mode: PauseMode::Layer
        })
    );
    assert_eq!(
        cmd("SET_PRINT_STATS_INFO CURRENT_LAYER=3 TOTAL_LAYER=10"),
        Command::Report(ReportCommand::PrintStatsInfo {
            current_layer: Some(3),
            total_layer: Some(10)
        })
    );
    assert_eq!(
        kind("SET_PRINT_STATS_INFO CURRENT_LAYER=x"),
        ParseErrorKind::MissingNumber
    );
    assert_eq!(
        cmd("M73 P10 R20 L4"),
        Command::Report(ReportCommand::Progress(Progress {
            percent: Some(10.0),
            remaining_min: Some(20.0),
            layer: Some(4),
            ..Progress::default()
        }))
    );
}

#[test]
fn every_listed_code_is_known() {
    for s in [
        "G0",
        "G1",
        "G2 I1",
        "G3 R2",
        "G4 P10",
        "G10",
        "G11",
        "G20",
        "G21",
        "G28",
        "G90",
        "G91",
        "G92 E0",
        "M0",
        "M1",
        "M17",
        "M18",
        "M84",
        "M24",
        "M25",
        "M82",
        "M83",
        "M104 S200",
        "M105",
        "M106",
        "M107",
        "M108",
        "M109 S200",
        "M110 N0",
        "M112",
        "M114",
        "M115",
        "M117 hi",
        "M118 hi",
        "M140 S60",
        "M190 S60",
        "M204 P500",
        "M220 S100",
        "M221 S100",
        "M400",
        "M410",
        "M524",
        "M600",
        "M601",
        "M602",
        "M301 P1 I2 D3",
        "M303 E0 S200 C5 U1",
        "M304 P1",
        "M73 P1",
        "M760",
        "M761",
        "T0",
    ] {
        assert!(!matches!(cmd(s), Command::Unknown(_)), "{s}");
        // And the emitter writes something that parses back to the same command.
        let c = cmd(s);
        assert_eq!(cmd(&emit(&c)), c, "{s}");
    }
}

/// Words of a command whose Marlin handler reads none are taken and reported, as Marlin's
/// parser takes any word and the handler never looks (BambuStudio's `M400 P100`); commands
/// that read parameters still refuse a letter they do not take.
#[test]
fn words_of_parameterless_commands_are_ignored() {
    let bit = |c: u8| 1u32 << (c - b'A');
    for (s, want, ignored) in [
        (
            "M400 P100",
            Command::Motion(MotionCommand::WaitMoves),
            bit(b'P'),
        ),
        ("M400", Command::Motion(MotionCommand::WaitMoves), 0),
        ("G90 X", Command::Motion(MotionCommand::Absolute), bit(b'X')),
        (
            "M83 S1 T2",
            Command::Motion(MotionCommand::RelativeE),
            bit(b'S') | bit(b'T'),
        ),
        (
            "M112 Q",
            Command::Pause(PauseCommand::EmergencyStop),
            bit(b'Q'),
        ),
    ] {
        let l = parse_line(s.as_bytes()).unwrap();
        assert_eq!((l.command, l.ignored), (Some(want), ignored), "{s}");
    }
    // Lines with nothing ignored say so.
    assert_eq!(parse_line(b"G1 X1").unwrap().ignored, 0);
    // M24 S<pos> means "resume at this file position" in Marlin: not ignored.
    assert_eq!(kind("M24 S100"), ParseErrorKind::UnexpectedLetter);
    assert_eq!(kind("G1 X1 P2"), ParseErrorKind::UnexpectedLetter);
    assert_eq!(kind("M104 S200 Q1"), ParseErrorKind::UnexpectedLetter);
    // G2/G3 P: circles, emitted and read back.
    let c = cmd("G3 Z.88 I-.86 J.861 P1  F30000");
    assert!(
        matches!(c, Command::Motion(MotionCommand::Arc { circles: 1, .. })),
        "{c:?}"
    );
    assert_eq!(emit(&c).as_str(), "G3 Z0.88 I-0.86 J0.861 P1 F30000");
    assert_eq!(cmd(&emit(&c)), c);
}

/// Numbers as G-code writes them: up to 5 decimals, within a printer's range.
fn num() -> impl Strategy<Value = f32> {
    (-10_000_000i64..10_000_000, 0u32..6).prop_map(|(m, s)| {
        let v = m as f64 / 10f64.powi(s as i32);
        // Round through text exactly as a slicer would write it.
        format!("{v:.*}", s as usize).parse::<f32>().unwrap_or(0.0)
    })
}

fn onum() -> impl Strategy<Value = Option<f32>> {
    proptest::option::of(num())
}

fn axes() -> impl Strategy<Value = AxisWords> {
    [onum(), onum(), onum(), onum()].prop_map(AxisWords)
}

fn flags() -> impl Strategy<Value = AxisFlags> {
    any::<[bool; 4]>().prop_map(AxisFlags)
}

fn text() -> impl Strategy<Value = Text> {
    "[ -:<-~]{0,40}".prop_map(|s| Text::try_from(s.trim()).unwrap_or_default())
}

fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        (any::<bool>(), axes(), onum()).prop_map(|(rapid, axes, feed)| Command::Motion(
            MotionCommand::Move { rapid, axes, feed }
        )),
        (
            any::<bool>(),
            axes(),
            (onum(), onum(), onum()),
            0..=crate::gcode::ARC_MAX_CIRCLES,
            onum()
        )
            .prop_map(
                |(clockwise, axes, (i, j, r), circles, feed)| Command::Motion(MotionCommand::Arc {
                    clockwise,
                    axes,
                    i,
                    j,
                    r,
                    circles,
                    feed
                })
            ),
        (onum(), onum()).prop_map(|(ms, s)| Command::Motion(MotionCommand::Dwell { ms, s })),
        flags().prop_map(|mut f| {
            f.0[3] = false;
            Command::Motion(MotionCommand::Home(f))
        }),
        axes().prop_map(|v| Command::Motion(MotionCommand::SetPosition(v))),
        (any::<bool>(), flags(), onum()).prop_map(|(m18, axes, s)| Command::Driver(
            DriverCommand::DisableSteppers { m18, axes, s }
        )),
        (any::<bool>(), any::<bool>()).prop_map(|(m601, now)| Command::Pause(
            PauseCommand::Pause {
                m601,
                mode: if now {
                    PauseMode::Now
                } else {
                    PauseMode::Layer
                }
            }
        )),
        (any::<bool>(), onum(), onum(), proptest::option::of(0u8..8)).prop_map(
            |(wait, s, r, tool)| Command::Heat(HeatCommand::SetTemperature {
                heater: Heater::Hotend,
                wait,
                s,
                r: if wait { r } else { None },
                tool
            })
        ),
        (
            proptest::option::of(0u8..=255),
            proptest::option::of(0u8..4)
        )
            .prop_map(|(s, fan)| {
                Command::Heat(HeatCommand::FanOn {
                    speed: s.map(f32::from),
                    fan,
                })
            }),
        proptest::option::of(any::<u32>())
            .prop_map(|v| Command::Report(ReportCommand::SetLineNumber(v))),
        text().prop_map(|v| Command::Report(ReportCommand::Message(v))),
        text().prop_map(|v| Command::Report(ReportCommand::Echo(v))),
        (
            onum(),
            onum(),
            onum(),
            onum(),
            onum(),
            proptest::option::of(any::<u32>())
        )
            .prop_map(
                |(p, r, q, s, c, l)| Command::Report(ReportCommand::Progress(Progress {
                    percent: p,
                    remaining_min: r,
                    silent_percent: q,
                    silent_remaining_min: s,
                    change_min: c,
                    layer: l
                }))
            ),
        (
            onum(),
            onum(),
            onum(),
            onum(),
            onum(),
            onum(),
            onum(),
            onum(),
            onum()
        )
            .prop_map(
                |(a, b, c, d, e, f, g, h, i)| Command::Pause(PauseCommand::Params(PauseParams {
                    retract_mm: a,
                    lift_z_mm: b,
                    park_x_mm: c,
                    park_y_mm: d,
                    park_feed_mm_min: e,
                    speedup_factor: f,
                    max_volumetric_mm3_s: g,
                    segment_len_mm: h,
                    nozzle_timeout_s: i
                }))
            ),
        prop_oneof![
            Just(PauseSchedule::Report),
            Just(PauseSchedule::Clear),
            any::<u32>().prop_map(PauseSchedule::Layer),
            num().prop_map(PauseSchedule::Z),
        ]
        .prop_map(|v| Command::Pause(PauseCommand::Schedule(v))),
        (
            proptest::option::of(-1i32..2),
            onum(),
            proptest::option::of(0u32..20),
            any::<bool>()
        )
            .prop_map(|(heater_index, target_c, cycles, use_result)| {
                Command::Heat(HeatCommand::Autotune {
                    heater_index,
                    target_c,
                    cycles,
                    use_result,
                })
            }),
        (
            proptest::option::of(any::<u32>()),
            proptest::option::of(any::<u32>())
        )
            .prop_map(|(current_layer, total_layer)| Command::Report(
                ReportCommand::PrintStatsInfo {
                    current_layer,
                    total_layer
                }
            )),
        (onum(), proptest::option::of(any::<bool>())).prop_map(
            |(min_temp_c, allow)| Command::Heat(HeatCommand::ColdExtrusion { min_temp_c, allow })
        ),
        Just(Command::Report(ReportCommand::Endstops)),
        any::<u8>().prop_map(Command::Tool),
        (1000u16..9999, axes()).prop_map(|(code, a)| {
            let mut t = Text::new();
            let _ = core::fmt::Write::write_fmt(&mut t, format_args!("M{code}"));
            let mut s = heapless::String::<200>::new();
            let _ = emit::write_command(
                &mut s,
                &Command::Motion(MotionCommand::Move {
                    rapid: false,
                    axes: a,
                    feed: None,
                }),
            );
            let _ = t.push_str(s.get(2..).unwrap_or(""));
            Command::Unknown(t)
        }),
    ]
}

proptest! {
    #[test]
    fn parse_emit_round_trip(c in command()) {
        let s = emit(&c);
        let back = parse_line(s.as_bytes());
        prop_assert_eq!(back.map(|l| l.command), Ok(Some(c)), "{}", s);
    }

    #[test]
    fn emit_parse_round_trip(s in "[GMT][0-9]{1,3}( [XYZEFSPIJRL][-+]?[0-9]{0,4}(\\.[0-9]{0,4})?){0,5}( ;[ -~]{0,10})?") {
        // Whatever parses, emits to text that parses to the same command.
        if let Ok(l) = parse_line(s.as_bytes()) {
            if let Some(c) = l.command {
                let again = emit(&c);
                prop_assert_eq!(parse_line(again.as_bytes()).map(|l| l.command), Ok(Some(c)), "{} -> {}", s, again);
            }
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..200)) {
        let _ = parse_line(&b);
    }
}
