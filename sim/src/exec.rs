//! [`Executive`] for the real firmware executive, `firmware::printer::Printer`, and the
//! [`Factory`] that configures it per policy (the conventional policies are the same code with
//! segmentation off, the pause queued at the tail, and 16 queued moves).

use crate::port::{ExecStatus, Executive, FirmwareKnobs, StepEvent};
use crate::run::Factory;
use firmware::config::MachineConfig;
use firmware::homing::HomingConfig;
use firmware::motion::Axis;
use firmware::motion::Realtime;
use firmware::planner::BlockKind;
use firmware::printer::{Policy, Printer, Record};
use firmware::thermal::HeaterId;

/// A notable record from the firmware (speed-up, brake, stop, layer), kept for timelines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noted {
    /// The record.
    pub record: Record,
}

/// Minimum endstops at the machine's minimum: the sim knows where each axis really is (moved by
/// the step events; the firmware only counts), and reports each switch to the firmware after
/// every step, as the board does from its pins. Power-on: every axis really at `start_steps`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimEndstops {
    /// True position of X Y Z, steps from the machine's minimum (where the switch closes).
    pub real_steps: [i32; 3],
}

impl SimEndstops {
    fn step(&mut self, axis_mask: u8, dir_mask: u8) {
        for (i, r) in self.real_steps.iter_mut().enumerate() {
            if axis_mask & (1 << i) != 0 {
                *r += if dir_mask & (1 << i) != 0 { 1 } else { -1 };
            }
        }
    }

    fn report(&self, p: &mut Printer) {
        for (axis, r) in [Axis::X, Axis::Y, Axis::Z].into_iter().zip(self.real_steps) {
            p.set_endstop(axis, r <= 0);
        }
    }
}

/// The firmware executive behind the sim's [`Executive`] trait.
pub struct PrinterExec {
    /// The firmware.
    pub printer: Printer,
    /// Records other than `Executed` (speed-up, brake, stopped, layer, state), in order.
    pub notes: Vec<Record>,
    /// Keep [`Self::notes`].
    pub keep_notes: bool,
    /// Executed job segments (seq, segment, segments of the move), when `keep_executed`.
    pub executed: Vec<(u32, u32, u32)>,
    /// Keep [`Self::executed`].
    pub keep_executed: bool,
    /// Endstops (None: no switches; G28 then moves to the minimum).
    pub endstops: Option<SimEndstops>,
    /// Job moves whose E part the firmware dropped (`Record::ColdRefused`), by sequence number.
    pub cold_refused: Vec<u32>,
}

impl PrinterExec {
    /// Wrap a printer.
    pub fn new(printer: Printer) -> Self {
        Self {
            printer,
            notes: Vec::new(),
            keep_notes: true,
            executed: Vec::new(),
            keep_executed: false,
            endstops: None,
            cold_refused: Vec::new(),
        }
    }

    /// Give the printer minimum endstops at the machine's minimum, the axes really at
    /// `real_steps` (steps from the switches) at power-on: G28 then homes through them.
    pub fn with_endstops(mut self, real_steps: [i32; 3]) -> Self {
        self.printer.enable_endstops(HomingConfig::ENDER3);
        let e = SimEndstops { real_steps };
        e.report(&mut self.printer);
        self.endstops = Some(e);
        self
    }

    /// Host bytes in on one port (see [`Printer::receive_on`]); returns how many were taken.
    pub fn receive_on(&mut self, port: firmware::link::PortId, bytes: &[u8], now_us: u64) -> usize {
        let n = self.printer.receive_on(port, bytes, now_us);
        self.drain_records();
        n
    }

    /// The host on `port` came or went (see [`Printer::port_session`]).
    pub fn port_session(&mut self, port: firmware::link::PortId, open: bool, now_us: u64) {
        self.printer.port_session(port, open, now_us);
        self.drain_records();
    }

    /// The pending output of one port.
    pub fn take_output_on(&mut self, port: firmware::link::PortId, out: &mut String) {
        let _ = self.printer.write_output_on(port, out);
    }

    fn drain_records(&mut self) {
        while let Some(r) = self.printer.pop_record() {
            match r {
                Record::Executed {
                    seq,
                    seg,
                    segs,
                    kind: BlockKind::Job,
                    ..
                } => {
                    if self.keep_executed {
                        self.executed.push((seq, seg, segs));
                    }
                }
                Record::Executed { .. } => {}
                Record::ColdRefused { seq, .. } => {
                    self.cold_refused.push(seq);
                    if self.keep_notes {
                        self.notes.push(r);
                    }
                }
                _ => {
                    if self.keep_notes {
                        self.notes.push(r);
                    }
                }
            }
        }
    }
}

impl Executive for PrinterExec {
    fn receive(&mut self, bytes: &[u8], now_us: u64) -> usize {
        let n = self.printer.receive(bytes, now_us);
        self.drain_records();
        n
    }

    fn request(&mut self, req: Realtime, now_us: u64) {
        self.printer.request(req, now_us);
        self.drain_records();
    }

    fn poll(&mut self, now_us: u64) {
        self.printer.poll(now_us);
        self.drain_records();
    }

    #[inline]
    fn next_step_us(&mut self, _now_us: u64) -> Option<u64> {
        self.printer.next_step_us()
    }

    #[inline]
    fn pop_step(&mut self, _now_us: u64) -> Option<StepEvent> {
        let ev = self.printer.next_step()?;
        if let Some(e) = self.endstops.as_mut() {
            e.step(ev.axis_mask, ev.dir_mask);
            e.report(&mut self.printer);
        }
        Some(ev)
    }

    fn take_output(&mut self, out: &mut String) {
        let _ = self.printer.write_output(out);
    }

    fn status(&self) -> ExecStatus {
        let s = self.printer.status();
        ExecStatus {
            state: s.state,
            pos_steps: s.position,
            layer: s.layer,
            queue_depth: s.queue_depth,
        }
    }

    fn next_seq(&self) -> Option<u32> {
        Some(self.printer.machine().next_seq())
    }

    fn cold_refused(&self) -> usize {
        self.cold_refused.len()
    }

    fn thermal(&mut self, bed: bool, measured_c: f32, now_us: u64) -> f32 {
        let id = if bed { HeaterId::Bed } else { HeaterId::Hotend };
        self.printer.thermal_sample(id, measured_c, now_us)
    }
}

/// Makes [`PrinterExec`]s for the policies.
#[derive(Clone, Copy, Debug, Default)]
pub struct PrinterFactory;

impl PrinterFactory {
    /// The firmware policy for a set of knobs.
    pub fn policy(knobs: &FirmwareKnobs) -> Policy {
        let mut p = if knobs.pause_at_tail {
            Policy::FIFO
        } else {
            Policy::FIRMWARE
        };
        p.segment = knobs.segment_len_mm.is_some();
        if let Some(n) = knobs.queue_limit {
            p = p.with_queue_limit(n);
        }
        p
    }
}

impl Factory for PrinterFactory {
    type Exec = PrinterExec;

    fn make(&self, machine: &MachineConfig, knobs: &FirmwareKnobs) -> PrinterExec {
        let mut cfg = *machine;
        if let Some(l) = knobs.segment_len_mm {
            cfg.pause.segment_len_mm = l;
        }
        if let Some(s) = knobs.speedup {
            cfg.pause.speedup_factor = s;
        }
        let mut printer = Printer::with_policy(cfg, Self::policy(knobs));
        // The guard stays on (as on the board) unless asked for, as M302 P1 would.
        printer.extrusion_guard_mut().allow_cold = knobs.allow_cold;
        PrinterExec::new(printer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::port::State;

    /// G28 in the sim with endstops: every axis ends exactly at its switch, whatever the
    /// firmware believed at power-on.
    #[test]
    fn g28_homes_to_the_sim_switches() {
        let p = Printer::new(MachineConfig::ENDER3);
        let mut e = PrinterExec::new(p).with_endstops([4_000, 123, 800]);
        e.receive(b"G28\n", 0);
        let mut now = 0u64;
        let mut out = String::new();
        while now < 120_000_000 {
            e.poll(now);
            while let Some(t) = e.next_step_us(now) {
                if t > now + 1000 {
                    break;
                }
                e.pop_step(now);
            }
            e.take_output(&mut out);
            now += 1000;
            if now > 1_000_000 && e.status().state == State::Idle {
                break;
            }
        }
        e.receive(b"M119\n", now);
        e.poll(now);
        e.take_output(&mut out);
        assert_eq!(e.endstops.map(|s| s.real_steps), Some([0, 0, 0]), "{out}");
        assert_eq!(e.status().pos_steps[..3], [0, 0, 0]);
        assert!(out.contains("x_min: TRIGGERED"), "{out}");
    }
}
