//! The paper's host-side pause for stock firmware without a layer-aware pause (SPEC §1): moves
//! are split into 0.1–0.2 mm pieces just before sending, so a 16-command firmware buffer holds at
//! most 1.6–3.2 mm of travel; the host stops sending at the layer end and sends the pause
//! sequence (relative E, retract, absolute E, lift, park at the back corner); on resume it
//! returns XY then Z, un-retracts, and restores E, the E mode and the feed rate.

use crate::job::gcode::Command;
use crate::job::modal::{fmt_mm, Modal, E, X, Y, Z};

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

/// Splits a `G0`/`G1` move into pieces no longer than `max_mm` (XYZ length), written in the
/// modes of `before` (the modal state before the move). Returns `None` when the command is not a
/// linear move or is short enough to send as it is. Only the axes the command names are written;
/// the last piece ends exactly at the commanded target; relative E pieces are rounded so they
/// add up to the rounded total.
pub fn split_move(cmd: &Command, before: &Modal, max_mm: f64) -> Option<Vec<String>> {
    if cmd.letter != 'G' || cmd.number > 1 || max_mm <= 0.0 || before.inches {
        return None;
    }
    let mut after = before.clone();
    let mv = after.apply(cmd)?;
    let len = mv.xyz_len_mm();
    if len <= max_mm {
        return None;
    }
    let n = (len / max_mm).ceil() as usize;
    if n > 100_000 {
        return None;
    }
    let axes: Vec<(usize, char)> = [(X, 'X'), (Y, 'Y'), (Z, 'Z'), (E, 'E')]
        .into_iter()
        .filter(|(_, c)| cmd.has(*c))
        .collect();
    let mut out = Vec::with_capacity(n);
    let mut prev_rounded = [0.0f64; 4];
    for i in 1..=n {
        let t = i as f64 / n as f64;
        let mut s = format!("G{}", cmd.number);
        for &(ax, c) in &axes {
            let abs = if ax == E {
                before.abs_e
            } else {
                before.abs_xyz
            };
            let v = if abs {
                if i == n {
                    mv.to_mm[ax]
                } else {
                    mv.from_mm[ax] + (mv.to_mm[ax] - mv.from_mm[ax]) * t
                }
            } else {
                let total = mv.to_mm[ax] - mv.from_mm[ax];
                let cum = round5(total * t);
                let piece = cum - prev_rounded[ax];
                prev_rounded[ax] = cum;
                piece
            };
            s.push_str(&format!(" {c}{}", fmt_mm(v)));
        }
        if i == 1 {
            if let Some(f) = cmd.get('F') {
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
