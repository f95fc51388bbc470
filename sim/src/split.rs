//! The `host-split` policy's host side (the paper's method): every straight move is cut into
//! pieces no longer than `piece_mm` before it is sent, and on a pause request the host appends a
//! pause sequence (retract, lift, park) after the current layer (or at once in `now` mode), then
//! stops sending; on resume it sends the way back and restores the modes.
//!
//! Lines are read with the firmware's parser and written with its emitter, so the host writes
//! exactly what the printer reads.

use crate::job::{HostState, JobInfo};
use firmware::config::MachineConfig;
use firmware::gcode::MotionCommand;
use firmware::gcode::{parse_line, AxisWords, Command};

/// A split job: the new lines and, for each, the original line it came from.
#[derive(Clone, Debug, Default)]
pub struct SplitJob {
    /// The lines to send.
    pub lines: Vec<String>,
    /// Original line index of each new line.
    pub source: Vec<usize>,
}

fn fmt_cmd(c: &Command) -> String {
    format!("{c}")
}

/// Cut every G0/G1 with XY or Z motion into pieces of at most `piece_mm` (equal pieces).
/// Arcs and every other line are copied unchanged (comments too, so layer markers stay).
pub fn split_job(lines: &[String], piece_mm: f64) -> SplitJob {
    let info = JobInfo::parse(lines);
    let mut out = SplitJob::default();
    let piece_mm = piece_mm.max(0.01);
    for (i, line) in lines.iter().enumerate() {
        let li = info.lines.get(i).copied();
        let parsed = parse_line(line.as_bytes()).ok().and_then(|l| l.command);
        let (Some(li), Some(Command::Motion(MotionCommand::Move { rapid, axes, feed }))) =
            (li, parsed)
        else {
            out.lines.push(line.clone());
            out.source.push(i);
            continue;
        };
        let st_before: HostState = info.state_before(i);
        let start = li.start_mm;
        let end = li.after.pos_mm;
        let len = ((0..3).map(|k| (end[k] - start[k]).powi(2)).sum::<f64>()).sqrt();
        let n = (len / piece_mm - 1e-9).ceil() as usize;
        if n <= 1 || st_before.inches {
            out.lines.push(line.clone());
            out.source.push(i);
            continue;
        }
        for p in 1..=n {
            let f = p as f64 / n as f64;
            let mut words = [None; 4];
            for k in 0..4 {
                if axes.0[k].is_none() {
                    continue;
                }
                let abs = if k == 3 {
                    st_before.abs_e
                } else {
                    st_before.abs_xyz
                };
                words[k] = Some(if p == n && abs {
                    // The last piece ends exactly where the original line ends.
                    axes.0[k].unwrap_or(0.0)
                } else if abs {
                    (start[k] + (end[k] - start[k]) * f) as f32
                } else {
                    // Relative: each piece is its share of the increment.
                    ((end[k] - start[k]) / n as f64) as f32
                });
            }
            let cmd = Command::Motion(MotionCommand::Move {
                rapid,
                axes: AxisWords(words),
                feed: if p == 1 { feed } else { None },
            });
            out.lines.push(fmt_cmd(&cmd));
            out.source.push(i);
        }
    }
    out
}

/// The host's pause sequence after a line with state `st` (paper: `M83`, `G1 E-2`, `M82`,
/// `G0 X200 Y200 F3600`; here with the machine's park corner and a Z lift, as the firmware's
/// own pause does).
pub fn pause_sequence(st: &HostState, cfg: &MachineConfig) -> Vec<String> {
    let p = &cfg.pause;
    let z_max = f64::from(cfg.axes[2].max_mm);
    let lift_to = (st.pos_mm[2] + f64::from(p.lift_z_mm)).min(z_max);
    vec![
        "M83".into(),
        format!(
            "G1 E-{:.3} F{:.0}",
            p.retract_mm,
            p.retract_feed_mm_s * 60.0
        ),
        "G90".into(),
        format!("G1 Z{lift_to:.3} F600"),
        format!(
            "G0 X{:.3} Y{:.3} F{:.0}",
            p.park_x_mm,
            p.park_y_mm,
            p.park_feed_mm_s * 60.0
        ),
    ]
}

/// The host's way back after its pause: XY first, then Z, un-retract, restore the logical E,
/// the E mode, the positioning mode and the feed.
pub fn resume_sequence(st: &HostState, cfg: &MachineConfig) -> Vec<String> {
    let p = &cfg.pause;
    let [x, y, z, e] = st.pos_mm;
    vec![
        "G90".into(),
        format!("G0 X{x:.4} Y{y:.4} F{:.0}", p.park_feed_mm_s * 60.0),
        format!("G1 Z{z:.4} F600"),
        "M83".into(),
        format!("G1 E{:.3} F{:.0}", p.retract_mm, p.retract_feed_mm_s * 60.0),
        format!("G92 E{e:.5}"),
        if st.abs_e { "M82" } else { "M83" }.into(),
        if st.abs_xyz { "G90" } else { "G91" }.into(),
        format!("G1 F{:.0}", st.feed_mm_min),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(s: &[&str]) -> Vec<String> {
        s.iter().map(|l| l.to_string()).collect()
    }

    #[test]
    fn splits_absolute_moves_into_equal_pieces() {
        let job = lines(&["G90", "M82", "G92 X0 Y0 E0", "G1 X1 Y0 E1 F1800", ";c"]);
        let s = split_job(&job, 0.2);
        // 1 mm → 5 pieces of 0.2 mm.
        let moves: Vec<&String> = s.lines.iter().filter(|l| l.starts_with("G1")).collect();
        assert_eq!(moves.len(), 5);
        assert!(moves[0].contains("F1800"));
        assert!(!moves[1].contains('F'));
        assert!(moves[4].contains("X1") && moves[4].contains("E1"));
        assert_eq!(s.source.iter().filter(|&&i| i == 3).count(), 5);
        // Parse the result back: same end point, pieces no longer than 0.2 mm.
        let info = JobInfo::parse(&s.lines);
        let last = info.lines.last().unwrap().after.pos_mm;
        assert!((last[0] - 1.0).abs() < 1e-6 && (last[3] - 1.0).abs() < 1e-6);
        for l in &info.lines {
            let d = ((l.after.pos_mm[0] - l.start_mm[0]).powi(2)
                + (l.after.pos_mm[1] - l.start_mm[1]).powi(2))
            .sqrt();
            assert!(d <= 0.2 + 1e-6);
        }
    }

    #[test]
    fn splits_relative_moves() {
        let job = lines(&["G91", "M83", "G1 X0.5 E0.5"]);
        let s = split_job(&job, 0.2);
        let info = JobInfo::parse(&s.lines);
        let last = info.lines.last().unwrap().after.pos_mm;
        assert!((last[0] - 0.5).abs() < 1e-6, "{last:?}");
        assert!((last[3] - 0.5).abs() < 1e-6);
        assert_eq!(s.lines.len(), 2 + 3);
    }

    #[test]
    fn pause_and_resume_sequences_restore_state() {
        let cfg = MachineConfig::ENDER3;
        let st = HostState {
            abs_xyz: true,
            abs_e: true,
            pos_mm: [10.0, 20.0, 0.4, 123.5],
            feed_mm_min: 1800.0,
            inches: false,
        };
        let mut all = vec!["G92 X10 Y20 Z0.4 E123.5".to_string()];
        all.extend(pause_sequence(&st, &cfg));
        all.extend(resume_sequence(&st, &cfg));
        let info = JobInfo::parse(&all);
        let end = info.lines.last().unwrap().after;
        for k in 0..4 {
            assert!(
                (end.pos_mm[k] - st.pos_mm[k]).abs() < 1e-5,
                "{:?}",
                end.pos_mm
            );
        }
        assert!(end.abs_e && end.abs_xyz);
        assert_eq!(end.feed_mm_min, 1800.0);
    }
}
