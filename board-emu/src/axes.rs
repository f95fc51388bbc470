//! The printer's mechanics as the pins see them: each axis turns its driver's STEP/DIR edges
//! into a position, and the X/Y/Z minimum switches (PC1/PC3/PC0) close when the carriage
//! reaches them. Also the step-timing figures the report needs, all from pin edges.
//!
//! Pins (docs/board.md, from Marlin's `pins_BTT_SKR_V2_0_common.h`): STEP X PE2, Y PD5, Z PA15,
//! E0 PD15; DIR X PE1, Y PD4, Z PA8, E0 PD14; EN X PE3, Y PD6, Z PD1, E0 PC7 (active low).
//! The machine (steps/mm, which DIR level is positive, which switch level means pressed) is
//! the Ender-3 the image is built for (`firmware::config::MachineConfig::ENDER3`). A step is
//! a rising STEP edge (TMC2209 datasheet §1.3 "Step/Dir interface": "step on rising edge").
//!
//! Counting: `net_steps` counts every rising STEP edge, signed by the DIR level at that edge,
//! from power-on — the pins' truth, whether or not the driver was enabled. The carriage
//! (`position`, which closes the switches) moves only while its driver is enabled (EN low) and
//! powered (SAFE_POWER PC13 high). The switches are Ender-3 normally-closed switches to ground
//! on pulled-up inputs: open (pressed) reads high. Each switch closes at carriage position 0
//! (steps); the carriage starts where [`Axes::new`] puts it.

use crate::gpio::Pin;
use crate::time::{ns_from_cyc, Cyc};
use firmware::config::MachineConfig;
use firmware::motion::Axis;

/// STEP pins X, Y, Z, E0.
pub const STEP: [Pin; 4] = [
    Pin::new('E', 2),
    Pin::new('D', 5),
    Pin::new('A', 15),
    Pin::new('D', 15),
];
/// DIR pins.
pub const DIR: [Pin; 4] = [
    Pin::new('E', 1),
    Pin::new('D', 4),
    Pin::new('A', 8),
    Pin::new('D', 14),
];
/// EN pins (active low).
pub const EN: [Pin; 4] = [
    Pin::new('E', 3),
    Pin::new('D', 6),
    Pin::new('D', 1),
    Pin::new('C', 7),
];
/// Endstops X, Y, Z.
pub const ENDSTOP: [Pin; 3] = [Pin::new('C', 1), Pin::new('C', 3), Pin::new('C', 0)];
/// SAFE_POWER.
pub const SAFE_POWER: Pin = Pin::new('C', 13);

/// A run of steps in one direction, for checking a homing sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Run {
    /// +1 or -1.
    pub dir: i8,
    /// Steps in the run.
    pub steps: u64,
    /// First and last step, cycles.
    pub t_first: Cyc,
    /// Last step.
    pub t_last: Cyc,
    /// Shortest interval between two steps of the run, cycles (0: one step).
    pub min_interval: Cyc,
    /// The switch was pressed at the run's last step.
    pub ended_pressed: bool,
}

/// One axis.
#[derive(Clone, Debug, Default)]
pub struct AxisState {
    /// Signed pin steps since power-on.
    pub net_steps: i64,
    /// Rising STEP edges since power-on.
    pub edges: u64,
    /// Carriage position, steps (0 = the switch).
    pub position: i64,
    /// Steps made while the driver was disabled or unpowered (the carriage did not move).
    pub steps_unpowered: u64,
    dir_level: bool,
    dir_changed_at: Option<Cyc>,
    step_high_at: Option<Cyc>,
    last_rise: Option<Cyc>,
    /// Shortest STEP high time, cycles.
    pub min_high: Option<Cyc>,
    /// Shortest DIR change → STEP rise, cycles.
    pub min_dir_setup: Option<Cyc>,
    /// Shortest interval between rising edges, cycles.
    pub min_interval: Option<Cyc>,
    /// Every step's time (when recording), with its direction.
    pub rises: Vec<(Cyc, i8)>,
    /// Runs of steps in one direction.
    pub runs: Vec<Run>,
}

/// The four axes and the switches.
#[derive(Clone, Debug)]
pub struct Axes {
    /// X, Y, Z, E0.
    pub axis: [AxisState; 4],
    dir_positive_high: u8,
    hit_high: u8,
    /// Record every step's time (for the schedule comparison).
    pub record: bool,
    /// A pause point mark: positions (net steps) at given moments, by label.
    pub marks: Vec<(String, Cyc, [i64; 4])>,
}

impl Axes {
    /// The Ender-3's axes with the carriage at `start_mm` (X, Y, Z) from each switch.
    pub fn new(cfg: &MachineConfig, start_mm: [f32; 3]) -> Self {
        let mut axis: [AxisState; 4] = Default::default();
        for (i, a) in [Axis::X, Axis::Y, Axis::Z].into_iter().enumerate() {
            axis[i].position = (start_mm[i] * cfg.axis(a).steps_per_mm).round() as i64;
        }
        Axes {
            axis,
            dir_positive_high: cfg.dir_high_positive_mask(),
            hit_high: cfg.endstop_hit_high_mask(),
            record: true,
            marks: Vec::new(),
        }
    }

    /// Is axis `i`'s switch pressed.
    pub fn pressed(&self, i: usize) -> bool {
        self.axis[i].position <= 0
    }

    /// The level of endstop `i`'s pin (from outside).
    pub fn endstop_level(&self, i: usize) -> bool {
        self.pressed(i) == (self.hit_high & (1 << i) != 0)
    }

    /// Net steps X, Y, Z, E.
    pub fn net(&self) -> [i64; 4] {
        [0, 1, 2, 3].map(|i| self.axis[i].net_steps)
    }

    /// An edge on a DIR pin.
    pub fn dir_edge(&mut self, i: usize, t: Cyc, high: bool) {
        let a = &mut self.axis[i];
        a.dir_level = high;
        a.dir_changed_at = Some(t);
    }

    /// An edge on a STEP pin; `moving`: the driver is enabled and powered.
    pub fn step_edge(&mut self, i: usize, t: Cyc, high: bool, moving: bool) {
        let positive = self.axis[i].dir_level == (self.dir_positive_high & (1 << i) != 0);
        let pressed_before = i < 3 && self.pressed(i);
        let record = self.record;
        let a = &mut self.axis[i];
        if !high {
            if let Some(h) = a.step_high_at.take() {
                let w = t - h;
                a.min_high = Some(a.min_high.map_or(w, |m| m.min(w)));
            }
            return;
        }
        a.step_high_at = Some(t);
        let d: i8 = if positive { 1 } else { -1 };
        a.net_steps += i64::from(d);
        a.edges += 1;
        if let Some(c) = a.dir_changed_at.take() {
            let s = t - c;
            a.min_dir_setup = Some(a.min_dir_setup.map_or(s, |m| m.min(s)));
        }
        let interval = a.last_rise.map(|l| t - l);
        if let Some(iv) = interval {
            a.min_interval = Some(a.min_interval.map_or(iv, |m| m.min(iv)));
        }
        a.last_rise = Some(t);
        if moving {
            a.position += i64::from(d);
        } else {
            a.steps_unpowered += 1;
        }
        if record {
            a.rises.push((t, d));
        }
        let _ = record;
        let pressed = i < 3 && a.position <= 0;
        let _ = pressed_before;
        match a.runs.last_mut() {
            Some(r) if r.dir == d => {
                r.steps += 1;
                r.min_interval = match (r.min_interval, interval) {
                    (0, Some(iv)) => iv,
                    (m, Some(iv)) => m.min(iv),
                    (m, None) => m,
                };
                r.t_last = t;
                r.ended_pressed = pressed;
            }
            _ => a.runs.push(Run {
                dir: d,
                steps: 1,
                t_first: t,
                t_last: t,
                min_interval: 0,
                ended_pressed: pressed,
            }),
        }
    }

    /// Marks the current positions.
    pub fn mark(&mut self, label: &str, t: Cyc) {
        // The steps up to `t` (a mark may be put after the fact: `--serve` marks the park
        // when it ends).
        let net = [0, 1, 2, 3].map(|i| {
            self.axis[i]
                .rises
                .iter()
                .take_while(|(r, _)| *r <= t)
                .map(|(_, d)| i64::from(*d))
                .sum()
        });
        self.marks.push((label.to_string(), t, net));
    }

    /// Per-axis figures for the report: shortest STEP high, DIR setup (ns) and highest step
    /// rate (Hz).
    pub fn timing(&self) -> [(Option<u64>, Option<u64>, Option<f64>); 4] {
        [0, 1, 2, 3].map(|i| {
            let a = &self.axis[i];
            (
                a.min_high.map(ns_from_cyc),
                a.min_dir_setup.map(ns_from_cyc),
                a.min_interval
                    .filter(|&iv| iv > 0)
                    .map(|iv| crate::time::CPU_HZ as f64 / iv as f64),
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_move_the_carriage_onto_the_switch() {
        let cfg = MachineConfig::ENDER3;
        let mut a = Axes::new(&cfg, [0.05, 10.0, 10.0]);
        assert!(!a.pressed(0));
        let toward_switch_high = cfg.dir_high_positive_mask() & 1 == 0;
        a.dir_edge(0, 0, toward_switch_high);
        let mut t = 1000;
        for _ in 0..10 {
            a.step_edge(0, t, true, true);
            a.step_edge(0, t + 168, false, true);
            t += 1000;
        }
        assert!(a.pressed(0));
        assert_eq!(a.net()[0], -10);
        assert_eq!(a.axis[0].min_high, Some(168));
        assert_eq!(a.axis[0].min_dir_setup, Some(1000));
        assert_eq!(a.axis[0].runs.len(), 1);
        assert!(a.axis[0].runs[0].ended_pressed);
    }
}
