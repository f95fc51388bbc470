//! [`Executive`] for the real firmware executive, `firmware::printer::Printer`, and the
//! [`Factory`] that configures it per policy (the conventional policies are the same code with
//! segmentation off, the pause queued at the tail, and 16 queued moves).

use crate::port::{BlockTag, ExecStatus, Executive, FirmwareKnobs, Lane, RunState, StepEvent};
use crate::run::Factory;
use firmware::config::MachineConfig;
use firmware::motion::Realtime;
use firmware::planner::BlockKind;
use firmware::printer::{Policy, Printer, Record, State};

/// A notable record from the firmware (speed-up, brake, stop, layer), kept for timelines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noted {
    /// The record.
    pub record: Record,
}

/// The firmware executive behind the sim's [`Executive`] trait.
pub struct PrinterExec {
    /// The firmware.
    pub printer: Printer,
    /// Records other than `Executed` (speed-up, brake, stopped, layer, state), in order.
    pub notes: Vec<Record>,
    /// Keep [`Self::notes`].
    pub keep_notes: bool,
    /// Stand-in front end while `Printer::receive` is not built (see [`DirectFeed`]).
    pub direct: Option<DirectFeed>,
}

impl PrinterExec {
    /// Wrap a printer.
    pub fn new(printer: Printer) -> Self {
        Self {
            printer,
            notes: Vec::new(),
            keep_notes: true,
            direct: None,
        }
    }

    fn drain_records(&mut self) {
        while let Some(r) = self.printer.pop_record() {
            if self.keep_notes && !matches!(r, Record::Executed { .. }) {
                self.notes.push(r);
            }
        }
    }
}

fn state_of(s: State) -> RunState {
    match s {
        State::Idle => RunState::Idle,
        State::Printing => RunState::Printing,
        State::Pausing => RunState::Pausing,
        State::Paused => RunState::Paused,
        State::Resuming => RunState::Resuming,
        State::Cancelled => RunState::Cancelled,
        State::Halted => RunState::Halted,
    }
}

impl Executive for PrinterExec {
    fn receive(&mut self, bytes: &[u8], now_us: u64) {
        if let Some(d) = self.direct.as_mut() {
            d.receive(&mut self.printer, bytes, now_us);
        } else {
            self.printer.receive(bytes, now_us);
        }
        self.drain_records();
    }

    fn request(&mut self, req: Realtime, now_us: u64) {
        self.printer.request(req, now_us);
        self.drain_records();
    }

    fn poll(&mut self, now_us: u64) {
        self.printer.poll(now_us);
        if let Some(d) = self.direct.as_mut() {
            d.flush(&mut self.printer, now_us);
        }
        self.drain_records();
    }

    #[inline]
    fn next_step_us(&mut self, _now_us: u64) -> Option<u64> {
        self.printer.next_step_us()
    }

    #[inline]
    fn pop_step(&mut self, _now_us: u64) -> Option<StepEvent> {
        let ev = self.printer.next_step()?;
        Some(StepEvent {
            t_us: ev.t_us,
            t_ns: ev.t_ns,
            axis_mask: ev.axis_mask,
            dir_mask: ev.dir_mask,
            tag: BlockTag {
                seq: ev.seq,
                segment: ev.seg,
                lane: match ev.kind {
                    BlockKind::Service => Lane::Service,
                    BlockKind::Job | BlockKind::Homing => Lane::Job,
                },
            },
        })
    }

    fn take_output(&mut self, out: &mut String) {
        let _ = self.printer.write_output(out);
        if let Some(d) = self.direct.as_mut() {
            out.push_str(&d.out);
            d.out.clear();
        }
    }

    fn status(&self) -> ExecStatus {
        let s = self.printer.status();
        ExecStatus {
            state: state_of(s.state),
            pos_steps: s.position,
            layer: s.layer,
            queue_depth: s.queue_depth,
        }
    }

    fn thermal(&mut self, bed: bool, measured_c: f32, now_us: u64) -> f32 {
        self.printer.thermal_sample(bed, measured_c, now_us)
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
        let mut e = PrinterExec::new(Printer::with_policy(cfg, Self::policy(knobs)));
        if std::env::var("SIM_DIRECT_FEED").is_ok_and(|v| v == "1") {
            e.direct = Some(DirectFeed::new(&cfg));
        }
        e
    }
}

/// Stand-in for the firmware's front end (`link` + `machine` + `layer`, fw-front) while
/// `Printer::receive` is not built: reads numbered lines, answers `ok` once the command is
/// queued (no `ok` while the queue is full), turns moves into `MoveRequest`s (seq = line number)
/// and slicer layer comments into layer marks, and hands `M25`/`M24` to `Printer::request`.
/// Used only when `SIM_DIRECT_FEED=1`; remove once the front end lands.
#[derive(Clone, Debug)]
pub struct DirectFeed {
    buf: Vec<u8>,
    st: crate::job::HostState,
    phys_mm: [f64; 4],
    spm: [f64; 4],
    pending: std::collections::VecDeque<firmware::printer::Command>,
    layer: u32,
    out: String,
}

impl DirectFeed {
    /// A feed for this machine.
    pub fn new(cfg: &MachineConfig) -> Self {
        let mut spm = [0.0; 4];
        for (s, a) in spm.iter_mut().zip(cfg.axes.iter()) {
            *s = f64::from(a.steps_per_mm);
        }
        Self {
            buf: Vec::new(),
            st: crate::job::HostState::default(),
            phys_mm: [0.0; 4],
            spm,
            pending: Default::default(),
            layer: 0,
            out: String::new(),
        }
    }

    fn flush(&mut self, p: &mut Printer, now_us: u64) {
        while let Some(c) = self.pending.front().copied() {
            if p.push_command(c, now_us).is_err() {
                return;
            }
            self.pending.pop_front();
            if self.pending.is_empty() {
                self.out.push_str("ok\n");
            }
        }
    }

    fn receive(&mut self, p: &mut Printer, bytes: &[u8], now_us: u64) {
        use firmware::gcode::{parse_line, Command as G};
        use firmware::motion::{LayerMark, LayerSource, MoveRequest, PauseMode};
        use firmware::printer::{Command as C, Schedule};
        self.buf.extend_from_slice(bytes);
        while let Some(i) = self.buf.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.buf.drain(..=i).collect();
            let text = String::from_utf8_lossy(&line).trim().to_string();
            let (n, body) = match text.strip_prefix('N') {
                Some(rest) => {
                    let sp = rest.find(' ').unwrap_or(rest.len());
                    let n: i64 = rest[..sp].parse().unwrap_or(0);
                    let body = rest[sp..]
                        .split('*')
                        .next()
                        .unwrap_or("")
                        .trim()
                        .to_string();
                    (Some(n), body)
                }
                None => (None, text.clone()),
            };
            let parsed = parse_line(body.as_bytes()).ok();
            let comment = parsed
                .as_ref()
                .and_then(|l| l.comment)
                .map(|c| String::from_utf8_lossy(c).to_string());
            let cmd = parsed.and_then(|l| l.command);
            if n.is_none() {
                match cmd {
                    Some(G::Pause { now, .. }) => p.request(
                        Realtime::Pause(if now {
                            PauseMode::Now
                        } else {
                            PauseMode::Layer
                        }),
                        now_us,
                    ),
                    Some(G::Resume { .. }) => p.request(Realtime::Resume, now_us),
                    _ => self.out.push_str("ok\n"),
                }
                continue;
            }
            let seq = n.unwrap_or(0).max(0) as u32;
            if let Some(c) = comment {
                if c.starts_with("LAYER_CHANGE") || c.starts_with("LAYER:") {
                    self.pending.push_back(C::Layer(LayerMark {
                        layer: self.layer,
                        z_um: None,
                        source: LayerSource::Comment,
                    }));
                    self.layer += 1;
                }
            }
            match cmd {
                Some(
                    c @ (G::Move { .. }
                    | G::SetPosition(_)
                    | G::Absolute
                    | G::Relative
                    | G::AbsoluteE
                    | G::RelativeE),
                ) => {
                    let before = self.st.pos_mm;
                    let mut st = self.st;
                    crate::job::apply(&mut st, &c);
                    if matches!(c, G::Move { .. }) {
                        for ((p, a), b) in self.phys_mm.iter_mut().zip(st.pos_mm).zip(before) {
                            *p += a - b;
                        }
                        let mut target = [0i32; 4];
                        for ((t, p), s) in target.iter_mut().zip(self.phys_mm).zip(self.spm) {
                            *t = (p * s).round() as i32;
                        }
                        self.pending.push_back(C::Move(MoveRequest {
                            target,
                            feed_mm_s: (st.feed_mm_min / 60.0) as f32,
                            seq,
                        }));
                    }
                    self.st = st;
                }
                Some(G::SchedulePause(firmware::gcode::PauseSchedule::Layer(l))) => {
                    self.pending.push_back(C::SchedulePause(Schedule::Layer(l)));
                }
                Some(G::Pause { now, .. }) => p.request(
                    Realtime::Pause(if now {
                        PauseMode::Now
                    } else {
                        PauseMode::Layer
                    }),
                    now_us,
                ),
                _ => {}
            }
            if self.pending.is_empty() {
                self.out.push_str("ok\n");
            } else {
                self.flush(p, now_us);
            }
        }
    }
}
