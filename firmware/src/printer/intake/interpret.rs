//! A host or card line into commands: parsed, applied to the job's modal state (or, for a
//! manual line while parked, to the manual copy), checked against the extrusion guard, fed to
//! the layer detector, and queued — moves, layer marks, homing, dwells — or handed back for the
//! executive to carry out (temperatures, reports, pause requests, settings...). A refused line
//! changes nothing: the modal state is as before it.

use super::Intake;
use crate::config::MachineConfig;
use crate::gcode;
use crate::gcode::MotionCommand;
use crate::layer::MoveFacts;
use crate::link::ReceivedLine;
use crate::machine::{Action, MachineState};
use crate::motion::{Axis, LayerMark};
use crate::printer::heat::Heat;
use crate::printer::host::Host;
use crate::printer::motion::service::ServiceMove;
use crate::printer::pause::Pause;
use crate::printer::types::{Command, JobSetting};

/// What the rest of the executive does with a line (see [`Interpreted`]).
#[derive(Clone, Debug, PartialEq)]
pub(in crate::printer) enum LineOutcome {
    /// Refused with its reason (or not parsed), `ok` sent: nothing changed.
    Refused,
    /// Queued (or nothing to do): the `ok` is the caller's to send.
    Done,
    /// The executive carries the command out (and sends the `ok` unless its answer is one).
    Execute(gcode::Command),
    /// An arc is being cut into the queue: its `ok` comes with its last move.
    ArcPending,
    /// A manual move for the service lane (then `ok`).
    ManualMove(ServiceMove),
}

/// A line interpreted: what is left to do, and what the job record notes of it.
#[derive(Clone, Debug, PartialEq)]
pub(in crate::printer) struct Interpreted {
    /// What is left to do.
    pub(in crate::printer) outcome: LineOutcome,
    /// Layer boundaries the line produced (at most the line's own and an M400's).
    pub(in crate::printer) marks: heapless::Vec<LayerMark, 2>,
    /// The job's modal state before the line (the boundary's, for a power-cut resume).
    pub(in crate::printer) modal_before: MachineState,
    /// A job line was interpreted (not a manual one).
    pub(in crate::printer) job_line: bool,
    /// A job move was queued.
    pub(in crate::printer) job_move: bool,
}

impl Intake {
    /// Interpret `line`; `manual`: a manual command while parked.
    pub(in crate::printer) fn interpret(
        &mut self,
        line: &ReceivedLine,
        manual: bool,
        cfg: &MachineConfig,
        heat: &Heat,
        pause: &Pause,
        host: &mut Host,
    ) -> Interpreted {
        let modal_before = self.interp.machine;
        let parked = matches!(pause, Pause::Parked { .. });
        let mut out = Interpreted {
            outcome: LineOutcome::Refused,
            marks: heapless::Vec::new(),
            modal_before,
            job_line: false,
            job_move: false,
        };
        let parsed = match line.parse() {
            Ok(l) => l,
            Err(e) => {
                host.warn(format_args!("{e}"));
                host.ok();
                return out;
            }
        };
        if parsed.ignored != 0 {
            host.note_ignored(parsed.ignored);
        }
        // Console lines run in the console copy of the modal state (the job's is untouched):
        // the parked one, or, while the job runs, one taken from the job's now — except the
        // feed and flow overrides while the job runs, which act on the job's, as Marlin's
        // M220/M221 do.
        let overrides = matches!(
            parsed.command,
            Some(gcode::Command::Motion(
                gcode::MotionCommand::FeedOverride(Some(_))
                    | gcode::MotionCommand::FlowOverride(Some(_))
            ))
        );
        let job_machine = self.interp.machine;
        let console = manual && (parked || !overrides);
        let machine = match (console, &mut self.manual) {
            (true, copy) => copy.get_or_insert(job_machine),
            (false, _) => &mut self.interp.machine,
        };
        let saved = *machine;
        let action = match &parsed.command {
            Some(cmd) => match machine.apply(cmd, cfg) {
                Ok(a) => a,
                Err(e) => {
                    host.warn(format_args!("{e}"));
                    host.ok();
                    return out;
                }
            },
            None => Action::None,
        };
        if let Err(r) = check_extrusion(&action, &saved, machine, cfg, heat) {
            // Refused (over-long extrusion, whatever the state it would run in): as if the
            // line had not come. A cold nozzle is judged when the move enters the planner.
            *machine = saved;
            host.warn(format_args!("{r}"));
            host.ok();
            return out;
        }
        if !manual {
            out.job_line = true;
            let facts = MoveFacts::of(&saved, &self.interp.machine, cfg);
            if let Some(mark) = self.interp.layers.feed(&parsed, facts) {
                let _ = self.cmds.push_back(Command::Layer(mark));
                let _ = out.marks.push(mark);
            }
            // M400 after a layer's marker comments: the boundary is here (a host that drains
            // the queue at a boundary, then pauses, stops at this layer, not the next).
            if matches!(
                parsed.command,
                Some(gcode::Command::Motion(MotionCommand::WaitMoves))
            ) {
                if let Some(mark) = self.interp.layers.finish() {
                    let _ = self.cmds.push_back(Command::Layer(mark));
                    let _ = out.marks.push(mark);
                }
            }
        }
        out.outcome = match action {
            Action::None => LineOutcome::Done,
            Action::Move(_) | Action::Arc(_) | Action::Home(_) if manual && !parked => {
                // A console move while the job runs or is on its way to or from the park
                // would run inside the job (or fight the park): refused, as Marlin cannot.
                if let Some(m) = self.manual.as_mut() {
                    *m = saved;
                }
                host.warn(format_args!(
                    "console move while printing (pause first: M601)"
                ));
                LineOutcome::Done
            }
            Action::Move(m) => {
                if manual {
                    LineOutcome::ManualMove(ServiceMove {
                        target: m.target,
                        feed_mm_s: m.feed_mm_s,
                    })
                } else {
                    out.job_move = true;
                    let _ = self.cmds.push_back(Command::Move(m));
                    LineOutcome::Done
                }
            }
            Action::Arc(a) => {
                if manual {
                    host.warn(format_args!("arcs are not taken while paused"));
                    LineOutcome::Done
                } else {
                    self.arc = Some(a);
                    if self.push_arc(pause) {
                        LineOutcome::Done
                    } else {
                        LineOutcome::ArcPending
                    }
                }
            }
            Action::Home(flags) => {
                if manual {
                    host.warn(format_args!("homing is not allowed while paused"));
                } else {
                    let mask = flags
                        .0
                        .iter()
                        .enumerate()
                        .filter(|(_, on)| **on)
                        .fold(0u8, |m, (i, _)| m | 1 << i);
                    let _ = self.cmds.push_back(Command::Home { mask });
                }
                LineOutcome::Done
            }
            Action::Dwell { ms } => {
                if !manual {
                    let _ = self.cmds.push_back(Command::Dwell { ms });
                }
                LineOutcome::Done
            }
            Action::Executive => match parsed.command {
                // A job's state command waits its turn in the queue (a held job's end code
                // acts after the held layer, never during the pause); a manual one acts now.
                Some(cmd) => match JobSetting::of(&cmd).filter(|_| !manual) {
                    Some(s) => {
                        let _ = self.cmds.push_back(Command::Setting(s));
                        LineOutcome::Done
                    }
                    None => LineOutcome::Execute(cmd),
                },
                None => LineOutcome::Done,
            },
        };
        out
    }

    /// Whether a line carries a layer marker of any family (it must enter the queue at its
    /// place, so it waits for room like a move).
    pub(in crate::printer) fn is_marker(&self, line: &ReceivedLine) -> bool {
        line.parse().is_ok_and(|l| self.interp.layers.is_marker(&l))
    }

    /// A report or message line answered while the queue is full: it is the next line of the
    /// stream (every line before it was taken), it queues nothing and changes nothing a later
    /// job line is interpreted in; the layer detector still sees it, in order (it carries no
    /// marker: see [`Intake::is_marker`]). The command, for the executive to answer.
    pub(in crate::printer) fn report_line(
        &mut self,
        line: &ReceivedLine,
        cfg: &MachineConfig,
        host: &mut Host,
    ) -> Option<gcode::Command> {
        match line.parse() {
            Ok(parsed) => {
                let here = MoveFacts::of(&self.interp.machine, &self.interp.machine, cfg);
                let mark = self.interp.layers.feed(&parsed, here);
                debug_assert!(mark.is_none(), "a marker line answered without room");
                parsed.command
            }
            Err(e) => {
                host.warn(format_args!("{e}"));
                None
            }
        }
    }
}

/// The extrusion guard's length limit on the action a line produced; `before` is the modal
/// state before the line, `after` after it.
fn check_extrusion(
    action: &Action,
    before: &MachineState,
    after: &MachineState,
    cfg: &MachineConfig,
    heat: &Heat,
) -> Result<(), crate::printer::guards::Refusal> {
    let e = Axis::E.index();
    let from = before.position_steps(cfg)[e];
    let to = match action {
        Action::Move(m) => m.target[e],
        Action::Arc(_) => after.position_steps(cfg)[e],
        _ => return Ok(()),
    };
    let spm = cfg.axis(Axis::E).steps_per_mm;
    let de_mm = (i64::from(to) - i64::from(from)) as f32 / spm;
    heat.check_length(de_mm)
}
