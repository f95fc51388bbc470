//! Raw G-code lines in a design (`t.gcode("M104 S0\nG28")`, [`StateChange::Gcode`]), read with
//! the printer's own parser (`firmware::gcode::parse_line`) into what they do: where the head
//! goes, homing, the hot-end target, the fan, cold-extrusion permission, the E axis and the feed.
//!
//! The writer and the checks both see raw lines through [`RawTracker`], so a raw line is part
//! of the design, not text passed by: a mid-print `G28` and an extrusion after the heater is
//! switched off are flagged by the checks, and the writer continues after a raw move or E
//! change from where the raw lines left the head and the filament.
//!
//! Refused when the design is built ([`check_text`]): lines the printer's parser rejects, and
//! lines that would change the frame every later move of the writer relies on — `M82`/`M83`
//! (the profile sets absolute or relative E), `G20` (inches), `G92` with X, Y or Z (shifts the
//! coordinates), and `G91` not followed by `G90` in the same text (a lift written `G91`,
//! `G1 Z5`, `G90` is fine).
//!
//! [`StateChange::Gcode`]: crate::design::model::StateChange::Gcode

use firmware::gcode::{parse_line, Command, Heater};
use firmware::gcode::{HeatCommand, MotionCommand};
use glam::DVec3;

/// What one raw text did, beyond moving the tracked state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RawEffects {
    /// A `G28` homed at least one axis.
    pub homes: bool,
    /// An X, Y or Z move, a home or an arc: the head is not where the design left it.
    pub moved: bool,
    /// An `F` word: the feed in force is not the writer's.
    pub feed: bool,
    /// `M106`/`M107`: the part fan was set.
    pub fan: bool,
    /// The last hot-end target set (`M104`/`M109` `S` or `R`), °C.
    pub hotend_c: Option<f64>,
    /// The last `M302 P` (cold extrusion allowed or forbidden).
    pub cold_allowed: Option<bool>,
    /// The last `M302 S` (lowest extrusion temperature), °C.
    pub cold_min_c: Option<f64>,
    /// The text moved E or set it (`G92 E`).
    pub e_changed: bool,
    /// `G90`/`G91`: on Marlin these switch E too, so the E mode must be set again after.
    pub modes: bool,
}

/// The head and filament state raw lines act on: the logical position (absolute, mm; `None`
/// while unknown) and the logical E, with the modes the design runs in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawTracker {
    /// Logical X, Y, Z, mm.
    pub pos: [Option<f64>; 3],
    /// Logical E, mm (absolute E: the number the next `E` word continues from).
    pub e_mm: f64,
    /// The profile's E mode: absolute (`M82`) when true.
    pub abs_e: bool,
    /// Where `G28` leaves the head (the bed's minimum corner at Z 0 for the checks).
    pub home: DVec3,
}

/// A raw text the printer's parser rejects, or one that would break the frame the writer keeps.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("gcode line {line} `{text}`: {msg}")]
pub struct RawError {
    /// 1-based line within the text.
    pub line: usize,
    /// The line.
    pub text: String,
    /// Why.
    pub msg: String,
}

fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .map(str::trim)
        .enumerate()
        .filter(|(_, l)| !l.is_empty())
        .map(|(i, l)| (i + 1, l))
}

/// Checks a raw text when the design is built: every line parses (firmware parser), and it
/// leaves the modes the writer relies on as they were (see the module docs).
pub fn check_text(text: &str) -> Result<(), RawError> {
    let mut relative_xyz: Option<(usize, String)> = None;
    for (n, l) in lines(text) {
        let bad = |msg: &str| RawError {
            line: n,
            text: l.to_string(),
            msg: msg.to_string(),
        };
        let parsed = parse_line(l.as_bytes()).map_err(|e| bad(&format!("{e}")))?;
        match parsed.command {
            Some(Command::Motion(MotionCommand::AbsoluteE) | Command::Motion(MotionCommand::RelativeE)) => {
                return Err(bad(
                    "changes absolute/relative E, which the printer profile sets for the whole file",
                ))
            }
            Some(Command::Motion(MotionCommand::Inches)) => {
                return Err(bad("switches to inches; the design is written in millimetres"))
            }
            Some(Command::Motion(MotionCommand::SetPosition(a))) if (0..3).any(|k| a.0[k].is_some()) => {
                return Err(bad(
                    "G92 with X, Y or Z shifts the coordinates of every later move; only `G92 E` is allowed",
                ))
            }
            Some(Command::Motion(MotionCommand::Relative)) => relative_xyz = Some((n, l.to_string())),
            Some(Command::Motion(MotionCommand::Absolute)) => relative_xyz = None,
            _ => {}
        }
    }
    match relative_xyz {
        Some((line, text)) => Err(RawError {
            line,
            text,
            msg: "relative positioning (G91) is not switched back with G90 in the same text".into(),
        }),
        None => Ok(()),
    }
}

impl RawTracker {
    /// A tracker at `pos` with logical E `e_mm`.
    pub fn new(pos: [Option<f64>; 3], e_mm: f64, abs_e: bool, home: DVec3) -> Self {
        RawTracker {
            pos,
            e_mm,
            abs_e,
            home,
        }
    }

    /// Runs a raw text (lines the parser rejects are skipped: [`check_text`] refused them when
    /// the design was built). Returns what the text did.
    pub fn apply(&mut self, text: &str) -> RawEffects {
        let mut fx = RawEffects::default();
        let mut relative = false;
        let mut abs_e = self.abs_e;
        for (_, l) in lines(text) {
            let Ok(line) = parse_line(l.as_bytes()) else {
                continue;
            };
            let Some(cmd) = line.command else { continue };
            match cmd {
                Command::Motion(MotionCommand::Move { axes, feed, .. })
                | Command::Motion(MotionCommand::Arc { axes, feed, .. }) => {
                    fx.feed |= feed.is_some();
                    let arc = matches!(cmd, Command::Motion(MotionCommand::Arc { .. }));
                    for k in 0..3 {
                        if let Some(v) = axes.0[k] {
                            let v = f64::from(v);
                            self.pos[k] = if relative {
                                self.pos[k].map(|p| p + v)
                            } else {
                                Some(v)
                            };
                            fx.moved = true;
                        }
                    }
                    fx.moved |= arc;
                    if let Some(e) = axes.0[3] {
                        let e = f64::from(e);
                        self.e_mm = if abs_e && !relative { e } else { self.e_mm + e };
                        fx.e_changed = true;
                    }
                }
                Command::Motion(MotionCommand::Home(flags)) => {
                    fx.homes = true;
                    fx.moved = true;
                    let home = self.home.to_array();
                    for (k, h) in home.iter().enumerate() {
                        if flags.0[..3].iter().all(|f| !f) || flags.0[k] {
                            self.pos[k] = Some(*h);
                        }
                    }
                }
                Command::Motion(MotionCommand::SetPosition(a)) => {
                    if let Some(e) = a.0[3] {
                        self.e_mm = f64::from(e);
                        fx.e_changed = true;
                    }
                }
                Command::Motion(MotionCommand::Relative) => {
                    relative = true;
                    fx.modes = true;
                }
                Command::Motion(MotionCommand::Absolute) => {
                    relative = false;
                    fx.modes = true;
                }
                Command::Motion(MotionCommand::AbsoluteE) => abs_e = true,
                Command::Motion(MotionCommand::RelativeE) => abs_e = false,
                Command::Heat(HeatCommand::SetTemperature {
                    heater: Heater::Hotend,
                    s,
                    r,
                    ..
                }) => {
                    if let Some(c) = s.or(r) {
                        fx.hotend_c = Some(f64::from(c));
                    }
                }
                Command::Heat(HeatCommand::FanOn { .. })
                | Command::Heat(HeatCommand::FanOff { .. }) => fx.fan = true,
                Command::Heat(HeatCommand::ColdExtrusion { min_temp_c, allow }) => {
                    if let Some(a) = allow {
                        fx.cold_allowed = Some(a);
                    }
                    if let Some(c) = min_temp_c {
                        fx.cold_min_c = Some(f64::from(c));
                    }
                }
                _ => {}
            }
        }
        fx
    }

    /// The tracked position when all three axes are known.
    pub fn position(&self) -> Option<DVec3> {
        match self.pos {
            [Some(x), Some(y), Some(z)] => Some(DVec3::new(x, y, z)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refused_lines_name_the_line_and_the_reason() {
        assert!(check_text("M104 S0\nG28").is_ok());
        assert!(check_text("G91\nG1 Z5 F600\nG90\nG92 E0").is_ok());
        let e = check_text("M106 S128\nG1 Xnan").expect_err("parser");
        assert_eq!(e.line, 2);
        let e = check_text("M83").expect_err("E mode");
        assert!(e.msg.contains("absolute/relative E"), "{e}");
        assert!(check_text("G92 X0").is_err());
        assert!(check_text("G20").is_err());
        let e = check_text("G91\nG1 Z5").expect_err("left relative");
        assert_eq!(e.line, 1);
    }

    #[test]
    fn tracker_follows_moves_homes_and_e() {
        let mut t = RawTracker::new([Some(10.0), Some(20.0), Some(1.0)], 50.0, true, DVec3::ZERO);
        let fx = t.apply("G91\nG1 Z5 E-2 F600\nG90\nM104 S0");
        assert!(fx.moved && fx.feed && fx.e_changed && !fx.homes);
        assert_eq!(t.position(), Some(DVec3::new(10.0, 20.0, 6.0)));
        assert!((t.e_mm - 48.0).abs() < 1e-9);
        assert_eq!(fx.hotend_c, Some(0.0));
        let fx = t.apply("G28 X\nG92 E0");
        assert!(fx.homes);
        assert_eq!(t.position(), Some(DVec3::new(0.0, 20.0, 6.0)));
        assert_eq!(t.e_mm, 0.0);
        let fx = t.apply("M302 P1 S120\nM106 S255");
        assert_eq!(
            (fx.cold_allowed, fx.cold_min_c, fx.fan),
            (Some(true), Some(120.0), true)
        );
        // Relative E: an E word adds.
        let mut r = RawTracker::new([None; 3], 3.0, false, DVec3::ZERO);
        r.apply("G1 E-1");
        assert!((r.e_mm - 2.0).abs() < 1e-9);
        assert_eq!(r.position(), None);
    }
}
