//! The paper's host-side pause for stock firmware without a layer-aware pause (SPEC §1): moves
//! are split into 0.1–0.2 mm pieces just before sending (arcs are first cut into the chords our
//! firmware would cut them into), so a 16-command firmware buffer holds at most 1.6–3.2 mm of
//! travel; after a layer pause request the rest of the layer runs faster (×3, bounded by the
//! extruder's volumetric flow, with the firmware's own speed-up formula); the host stops sending
//! at the layer end and sends the pause sequence (relative E, retract, absolute E, lift, park at
//! the back corner); on resume it returns XY then Z, un-retracts, and restores E, the E mode and
//! the feed rate.

use crate::job::gcode::{self, Command};
use crate::job::modal::{fmt_mm, Modal, Move, E, X, Y, Z};

/// Host-side pause parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct HostPause {
    /// Filament retracted at the pause, mm (paper: 2).
    pub retract_mm: f64,
    /// Retract / un-retract feed, mm/min.
    pub retract_feed_mm_min: f64,
    /// Z lift before parking, mm (0 = the paper's sequence, which parks at print height).
    pub lift_mm: f64,
    /// Park position at the back corner, mm (paper: X200 Y200).
    pub park_xy_mm: (f64, f64),
    /// Park travel feed, mm/min (paper: F3600).
    pub park_feed_mm_min: f64,
    /// Longest piece a move is split into, mm (0.1–0.2; 0 disables splitting).
    pub split_mm: f64,
    /// Feed factor for the rest of the layer after a layer pause request (paper: ×3; 1 = off).
    pub speedup_factor: f64,
    /// Highest volumetric flow the extruder can melt, mm³/s: bounds the speed-up of extruding
    /// moves.
    pub max_volumetric_mm3_s: f64,
    /// Filament diameter, mm (for the volumetric flow).
    pub filament_diameter_mm: f64,
}

impl Default for HostPause {
    fn default() -> Self {
        let p = firmware::config::MachineConfig::ENDER3.pause;
        HostPause {
            retract_mm: p.retract_mm as f64,
            retract_feed_mm_min: p.retract_feed_mm_s as f64 * 60.0,
            lift_mm: 1.0,
            park_xy_mm: (p.park_x_mm as f64, p.park_y_mm as f64),
            park_feed_mm_min: p.park_feed_mm_s as f64 * 60.0,
            split_mm: p.segment_len_mm as f64,
            speedup_factor: p.speedup_factor as f64,
            max_volumetric_mm3_s: p.max_volumetric_mm3_s as f64,
            filament_diameter_mm: firmware::config::MachineConfig::ENDER3.filament_diameter_mm
                as f64,
        }
    }
}

/// The pause sequence sent after the last move of the layer; `m` is the modal state there.
pub fn pause_sequence(m: &Modal, p: &HostPause) -> Vec<String> {
    let mut out = vec![
        "M83".to_string(),
        format!(
            "G1 E-{} F{}",
            fmt_mm(p.retract_mm),
            fmt_mm(p.retract_feed_mm_min)
        ),
        "M82".to_string(),
        "G90".to_string(),
    ];
    if p.lift_mm > 0.0 {
        out.push(format!("G0 Z{} F600", fmt_mm(m.pos_mm[Z] + p.lift_mm)));
    }
    out.push(format!(
        "G0 X{} Y{} F{}",
        fmt_mm(p.park_xy_mm.0),
        fmt_mm(p.park_xy_mm.1),
        fmt_mm(p.park_feed_mm_min)
    ));
    out
}

/// The resume sequence: back to the recorded XY, then Z, un-retract, restore the logical E, the
/// E and positioning modes and the feed rate of the job (`m`: the modal state at the pause).
pub fn resume_sequence(m: &Modal, p: &HostPause) -> Vec<String> {
    let mut out = vec![
        "G90".to_string(),
        format!(
            "G0 X{} Y{} F{}",
            fmt_mm(m.pos_mm[X]),
            fmt_mm(m.pos_mm[Y]),
            fmt_mm(p.park_feed_mm_min)
        ),
        format!("G0 Z{} F600", fmt_mm(m.pos_mm[Z])),
        "M83".to_string(),
        format!(
            "G1 E{} F{}",
            fmt_mm(p.retract_mm),
            fmt_mm(p.retract_feed_mm_min)
        ),
    ];
    out.extend(m.restore_lines());
    out
}

/// The feed, mm/min, of move `mv` in the rest of a layer after a layer pause request: its feed
/// × [`HostPause::speedup_factor`], bounded by the per-axis feed limits and, for extruding moves,
/// by [`HostPause::max_volumetric_mm3_s`] of filament of [`HostPause::filament_diameter_mm`] —
/// the firmware's own formula (`firmware::planner::sped_up_mm_s`, with the axis limits of
/// `MachineConfig::ENDER3`), and never slower than the move's own feed. Moves without XYZ
/// travel (retracts) keep their feed. `None` when the job has set no feed yet.
pub fn sped_up_feed_mm_min(mv: &Move, p: &HostPause) -> Option<f64> {
    let feed = mv.feed_mm_min?;
    let sped = p.speedup_factor > 1.0 && feed > 0.0 && feed.is_finite();
    if !sped || mv.xyz_len_mm() <= 1e-9 {
        return Some(feed);
    }
    let cfg = firmware::config::MachineConfig::ENDER3;
    let mut delta = [0i32; 4];
    for (k, d) in delta.iter_mut().enumerate() {
        let steps = (mv.to_mm[k] - mv.from_mm[k]) * f64::from(cfg.axes[k].steps_per_mm);
        *d = steps.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32;
    }
    let Some(kin) = firmware::planner::kinematics(&cfg, &delta, (feed / 60.0) as f32) else {
        return Some(feed);
    };
    let v_mm_s = firmware::planner::sped_up_mm_s(
        &kin,
        p.speedup_factor as f32,
        p.max_volumetric_mm3_s as f32,
        p.filament_diameter_mm as f32,
    );
    Some((f64::from(v_mm_s) * 60.0).max(feed))
}

/// Splits a `G0`/`G1` move into pieces no longer than `max_mm` (XYZ length), written in the
/// modes of `before` (the modal state before the move). Returns `None` when the command is not a
/// linear move or is short enough to send as it is. Only the axes the command names are written;
/// the last piece ends exactly at the commanded target; relative E pieces are rounded so they
/// add up to the rounded total.
pub fn split_move(cmd: &Command, before: &Modal, max_mm: f64) -> Option<Vec<String>> {
    if cmd.number > 1 {
        return None;
    }
    rewrite_move(cmd, before, max_mm, None)
}

/// Rewrites one move of the current layer for the host-side method:
///
/// - `G0`/`G1`: split into pieces no longer than `max_mm` (XYZ length); only the axes the
///   command names are written;
/// - `G2`/`G3`: cut into the straight chords our firmware would cut the arc into
///   ([`gcode::arc_points`]: I/J or R, CW/CCW, Z and E linear along the arc, within 5 µm of the
///   arc), each chord then split to at most `max_mm`, written as `G1` with X, Y, and Z and E
///   when the arc names them;
/// - `feed_mm_min`: an F written on the first piece (the speed-up; the sender then gives every
///   move of the layer its own F); otherwise the command's own F, if any.
///
/// Pieces are written in the modes of `before` (the modal state before the move); the last one
/// ends exactly at the commanded target; relative pieces are rounded so they add up to the
/// rounded total. `None` when the command is not a move, `max_mm` is 0 (no splitting) and no
/// feed is given, the move is short enough to send unchanged, the job is in inches, or the arc
/// is one the firmware refuses (sent as it is: the printer reports it).
pub fn rewrite_move(
    cmd: &Command,
    before: &Modal,
    max_mm: f64,
    feed_mm_min: Option<f64>,
) -> Option<Vec<String>> {
    if cmd.letter != 'G' || cmd.number > 3 || before.inches {
        return None;
    }
    let arc = cmd.number >= 2;
    if max_mm <= 0.0 && feed_mm_min.is_none() {
        return None;
    }
    let mut after = before.clone();
    let mv = after.apply(cmd)?;
    let points = if arc {
        gcode::arc_points(cmd, mv.from_mm, mv.to_mm).ok()?
    } else {
        vec![mv.to_mm]
    };
    // Subdivide every segment (previous point -> point) to at most max_mm.
    let mut targets: Vec<[f64; 4]> = Vec::new();
    let mut prev = mv.from_mm;
    for p in &points {
        let d2: f64 = (0..3).map(|k| (p[k] - prev[k]).powi(2)).sum();
        let len = d2.sqrt();
        let n = if max_mm > 0.0 {
            (len / max_mm).ceil().max(1.0)
        } else {
            1.0
        };
        if targets.len() as f64 + n > 100_000.0 {
            return None;
        }
        let n = n as usize;
        for i in 1..=n {
            let t = i as f64 / n as f64;
            if i == n {
                targets.push(*p);
            } else {
                let mut q = [0.0; 4];
                for k in 0..4 {
                    q[k] = prev[k] + (p[k] - prev[k]) * t;
                }
                targets.push(q);
            }
        }
        prev = *p;
    }
    if targets.len() <= 1 && !arc && feed_mm_min.is_none() {
        return None;
    }
    let axes: Vec<(usize, char)> = [(X, 'X'), (Y, 'Y'), (Z, 'Z'), (E, 'E')]
        .into_iter()
        .filter(|(ax, c)| cmd.has(*c) || (arc && (*ax == X || *ax == Y)))
        .collect();
    let word = if arc { 1 } else { cmd.number };
    let n = targets.len();
    let mut out = Vec::with_capacity(n);
    let mut prev_rounded = [0.0f64; 4];
    for (i, q) in targets.iter().enumerate() {
        let last = i + 1 == n;
        let mut s = format!("G{word}");
        for &(ax, c) in &axes {
            let abs = if ax == E {
                before.abs_e
            } else {
                before.abs_xyz
            };
            let v = if abs {
                if last {
                    mv.to_mm[ax]
                } else {
                    q[ax]
                }
            } else {
                let total = if last {
                    mv.to_mm[ax] - mv.from_mm[ax]
                } else {
                    q[ax] - mv.from_mm[ax]
                };
                let cum = round5(total);
                let piece = cum - prev_rounded[ax];
                prev_rounded[ax] = cum;
                piece
            };
            s.push_str(&format!(" {c}{}", fmt_mm(v)));
        }
        if i == 0 {
            if let Some(f) = feed_mm_min.or_else(|| cmd.get('F')) {
                s.push_str(&format!(" F{}", fmt_mm(f)));
            }
        }
        out.push(s);
    }
    Some(out)
}

fn round5(v: f64) -> f64 {
    (v * 1e5).round() / 1e5
}
