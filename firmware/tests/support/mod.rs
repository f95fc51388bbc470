//! Shared test driver: runs a `Printer` on virtual time with a scripted job and requests.
#![allow(dead_code)]

use firmware::config::MachineConfig;
use firmware::motion::{LayerMark, LayerSource, MoveRequest, Realtime, StepPos};
use firmware::planner::BlockKind;
use firmware::printer::{Command, Policy, Printer, Record, State};

/// A job entry.
#[derive(Clone, Copy, Debug)]
pub enum Item {
    /// Move to (mm x, y, z, e absolute) at feed mm/s.
    Move([f32; 4], f32),
    /// Layer mark.
    Layer(u32),
    /// G4: dwell this many ms once the moves before it have run.
    Dwell(u32),
    /// M400: wait for the moves before it.
    Sync,
    /// G28 of the axes in the mask (bit 0 X, 1 Y, 2 Z).
    Home(u8),
}

/// What a run produced.
#[derive(Default, Debug)]
pub struct Run {
    /// (seq, seg) of executed job blocks, in order.
    pub executed: Vec<(u32, u32)>,
    /// Position after each job block.
    pub job_pos: Vec<StepPos>,
    /// All records.
    pub records: Vec<Record>,
    /// Step positions sampled at each event: (t_ns, pos).
    pub trace: Vec<(u64, StepPos)>,
    /// Final position.
    pub end: StepPos,
    /// Final time, µs.
    pub end_us: u64,
    /// Output text.
    pub out: String,
    /// When each request was handed to the printer, µs.
    pub req_times: Vec<u64>,
}

/// A stop the printer recorded for a pause.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stop {
    /// Where the head stopped, steps.
    pub pos: StepPos,
    /// The layer whose boundary it stopped at (None: mid-layer, now mode or job end).
    pub layer: Option<u32>,
    /// Stopped inside a block (feed hold).
    pub mid_block: bool,
}

impl Run {
    /// Every pause stop of the run, in order.
    pub fn stops(&self) -> Vec<Stop> {
        self.records
            .iter()
            .filter_map(|x| match *x {
                Record::Stopped {
                    pos,
                    layer,
                    mid_block,
                    ..
                } => Some(Stop {
                    pos,
                    layer,
                    mid_block,
                }),
                _ => None,
            })
            .collect()
    }

    /// The first pause stop.
    pub fn stop(&self) -> Option<Stop> {
        self.stops().first().copied()
    }

    /// The speed (mm/s) and deceleration (mm/s²) of the first braking (a `now` pause's feed
    /// hold).
    pub fn brake(&self) -> Option<(f32, f32)> {
        self.records.iter().find_map(|x| match *x {
            Record::Brake {
                v_mm_s,
                accel_mm_s2,
                ..
            } => Some((v_mm_s, accel_mm_s2)),
            _ => None,
        })
    }
}

/// `layers` layers 0.2 mm apart, each its layer mark, a travel to (10, 10) at 30 mm/s, and a
/// square perimeter to (`far_mm`, `far_mm`) and back at 40 mm/s feeding `e_per_side_mm` a
/// side (E absolute).
pub fn square_layers(layers: u32, far_mm: f32, e_per_side_mm: f32) -> Vec<Item> {
    let mut v = Vec::new();
    let mut e = 0.0;
    for l in 0..layers {
        v.push(Item::Layer(l));
        let z = 0.2 * (l + 1) as f32;
        v.push(Item::Move([10.0, 10.0, z, e], 30.0));
        for (x, y) in [
            (far_mm, 10.0),
            (far_mm, far_mm),
            (10.0, far_mm),
            (10.0, 10.0),
        ] {
            e += e_per_side_mm;
            v.push(Item::Move([x, y, z, e], 40.0));
        }
    }
    v
}

/// Convert mm to steps with the Ender-3 scale.
pub fn to_steps(cfg: &MachineConfig, mm: [f32; 4]) -> StepPos {
    let mut s = [0i32; 4];
    for i in 0..4 {
        s[i] = (mm[i] * cfg.axes[i].steps_per_mm).round() as i32;
    }
    s
}

/// Turn items into commands with increasing seq.
pub fn commands(cfg: &MachineConfig, items: &[Item]) -> Vec<Command> {
    let mut seq = 0;
    items
        .iter()
        .map(|it| match *it {
            Item::Move(p, f) => {
                seq += 1;
                Command::Move(MoveRequest {
                    target: to_steps(cfg, p),
                    feed_mm_s: f,
                    seq,
                })
            }
            Item::Layer(l) => Command::Layer(LayerMark {
                layer: l,
                z_um: None,
                source: LayerSource::Comment,
            }),
            Item::Dwell(ms) => Command::Dwell { ms },
            Item::Sync => Command::Sync,
            Item::Home(mask) => Command::Home { mask },
        })
        .collect()
}

/// A timed request.
#[derive(Clone, Copy, Debug)]
pub struct Req {
    /// When, µs.
    pub t_us: u64,
    /// What.
    pub req: Realtime,
}

/// One main-loop tick of `tick_us` from `now`: poll, take the step events due (tracing the
/// position), collect the records into `r`; returns the host-link output of the tick.
fn tick_once(p: &mut Printer, now: u64, tick_us: u64, r: &mut Run) -> String {
    p.poll(now);
    let until_ns = (now + tick_us) * 1000;
    while let Some(t) = p.next_step_ns() {
        if t > until_ns {
            break;
        }
        let Some(_ev) = p.next_step() else { break };
        r.trace.push((t, p.status().position));
    }
    while let Some(rec) = p.pop_record() {
        if let Record::Executed {
            seq,
            seg,
            kind,
            pos,
            ..
        } = rec
        {
            if kind == BlockKind::Job {
                r.executed.push((seq, seg));
                r.job_pos.push(pos);
            }
        }
        r.records.push(rec);
    }
    let mut s = String::new();
    let _ = p.write_output(&mut s);
    s
}

/// Drive a printer through `cmds`, issuing `reqs` at their times; poll every `tick_us`.
pub fn run(p: &mut Printer, cmds: &[Command], reqs: &[Req], limit_us: u64) -> Run {
    let mut r = Run::default();
    let mut now = 0u64;
    let tick = 1000u64;
    let mut next_cmd = 0usize;
    let mut next_req = 0usize;
    loop {
        // Feed commands while there is room (ok flow).
        while next_cmd < cmds.len() {
            if p.push_command(cmds[next_cmd], now).is_err() {
                break;
            }
            next_cmd += 1;
        }
        while next_req < reqs.len() && reqs[next_req].t_us <= now {
            p.request(reqs[next_req].req, now);
            r.req_times.push(now);
            next_req += 1;
        }
        let s = tick_once(p, now, tick, &mut r);
        r.out.push_str(&s);
        now += tick;
        let st = p.status().state;
        if next_cmd >= cmds.len()
            && next_req >= reqs.len()
            && matches!(
                st,
                State::Idle | State::Cancelled | State::Paused | State::Halted
            )
            && p.next_step_ns().is_none()
        {
            break;
        }
        if now > limit_us {
            break;
        }
    }
    r.end = p.status().position;
    r.end_us = now;
    r
}

/// Default printer. These tests model motion, not heaters: cold extrusion is allowed (as
/// M302 P1); `tests/guards.rs` tests the protection with its own printers.
pub fn printer() -> Printer {
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    p.extrusion_guard_mut().allow_cold = true;
    p
}

/// Stream G-code lines with ok flow control (next line only after an `ok`); at each
/// `(t_us, bytes)` send those bytes at once (realtime requests). Returns the run and the
/// number of `ok`s seen.
pub fn run_gcode(p: &mut Printer, lines: &[&str], sends: &[(u64, &str)], limit_us: u64) -> Run {
    let mut r = Run::default();
    let mut now = 0u64;
    let tick = 1000u64;
    let mut next_line = 0usize;
    let mut next_send = 0usize;
    let mut waiting_ok = false;
    let mut oks_pending = 0usize;
    loop {
        if !waiting_ok && next_line < lines.len() {
            let l = format!("{}\n", lines[next_line]);
            // One line per `ok`: always taken whole (flow control never holds it back).
            assert_eq!(
                p.receive(l.as_bytes(), now),
                l.len(),
                "line not taken: {l:?}"
            );
            next_line += 1;
            waiting_ok = true;
        }
        while next_send < sends.len() && sends[next_send].0 <= now {
            let b = sends[next_send].1.as_bytes();
            assert_eq!(p.receive(b, now), b.len(), "realtime line not taken");
            r.req_times.push(now);
            // A realtime line is answered `ok` too, but the host does not wait for it.
            oks_pending += 1;
            next_send += 1;
        }
        let s = tick_once(p, now, tick, &mut r);
        for l in s.lines() {
            if l.starts_with("ok") {
                if oks_pending > 0 {
                    oks_pending -= 1;
                } else {
                    waiting_ok = false;
                }
            }
        }
        r.out.push_str(&s);
        now += tick;
        let st = p.status().state;
        if next_line >= lines.len()
            && !waiting_ok
            && next_send >= sends.len()
            && matches!(
                st,
                State::Idle | State::Cancelled | State::Paused | State::Halted
            )
            && p.next_step_ns().is_none()
        {
            break;
        }
        if now > limit_us {
            break;
        }
    }
    r.end = p.status().position;
    r.end_us = now;
    r
}
