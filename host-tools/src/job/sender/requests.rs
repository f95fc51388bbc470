//! The session's reactions to requests (pause at layer, pause now, resume, cancel, emergency
//! stop, from the user or the printer's `//action:`) and the pause transitions they lead to:
//! entering [`State::Paused`] and acting on a synchronising line once the printer took it.

use std::io::{Read, Write};
use std::time::Duration;

use super::fallback;
use super::{Event, Out, PauseMethod, Pending, Request, Session, State, Sync};
use crate::job::Section;

impl<P: Read + Write> Session<P> {
    /// Handles a request now. Realtime requests are written at once, ahead of queued lines.
    pub fn request(&mut self, r: Request, now: Duration) -> std::io::Result<()> {
        match r {
            Request::EmergencyStop => {
                self.write_realtime("M112", false)?;
                self.fail("emergency stop (M112) sent");
            }
            Request::Cancel => {
                if self.finished() {
                    return Ok(());
                }
                match self.method {
                    Some(PauseMethod::Firmware) => self.write_realtime("M524", true)?,
                    _ => self.write_realtime("M410", true)?,
                }
                self.queue.clear();
                self.state = State::Cancelled;
                self.events.push(Event::Cancelled);
            }
            Request::PauseAtLayer | Request::PauseNow => {
                if !matches!(self.state, State::Printing) {
                    self.events
                        .push(Event::Note("pause ignored: not printing".to_string()));
                    return Ok(());
                }
                self.pause_requested_at = Some(now);
                self.pause_now = r == Request::PauseNow;
                if r == Request::PauseNow {
                    self.pending = Some(Pending::Now);
                    if self.method == Some(PauseMethod::Firmware) {
                        self.write_realtime("M25 S1", true)?;
                    }
                } else {
                    self.normalize_cursor();
                    let gate = self.first_unsent_layer();
                    self.pending = Some(Pending::AtLayer { gate });
                    if self.method == Some(PauseMethod::Firmware) {
                        // React at once: the firmware speeds the layer up and stops at its next
                        // boundary; the host stops sending at the same layer end.
                        self.write_realtime("M25", true)?;
                    } else if self.opts.host_pause.speedup_factor > 1.0 {
                        let hp = &self.opts.host_pause;
                        self.events.push(Event::Note(format!(
                            "the rest of the layer runs up to ×{} (extrusion up to {} mm³/s)",
                            hp.speedup_factor, hp.max_volumetric_mm3_s
                        )));
                    }
                }
                self.state = State::Pausing;
                self.events.push(Event::Pausing);
            }
            Request::Resume => {
                let State::Paused { prompt, .. } = &self.state else {
                    self.events
                        .push(Event::Note("resume ignored: not paused".to_string()));
                    return Ok(());
                };
                let mut next = State::Printing;
                if prompt.is_none() {
                    if self.paused_by_firmware {
                        self.write_realtime("M24", true)?;
                        if std::mem::take(&mut self.scheduled) {
                            // A schedule hit while a pause was already in progress stays set
                            // in the firmware: clear it before the next layer arrives.
                            self.queue.push_back(Out::plain("M761 C"));
                        }
                        // Job lines wait until the firmware reports it is back at the pause
                        // point, so none is interpreted while it is still returning.
                        next = State::Resuming;
                        self.resume_requested_at = Some(now);
                    } else if let Some(m) = self.paused_modal.take() {
                        let seq = fallback::resume_sequence(&m, &self.opts.host_pause);
                        self.queue.extend(seq.into_iter().map(Out::plain));
                    }
                }
                self.paused_by_firmware = false;
                self.pending = None;
                self.state = next;
                self.events.push(Event::Resumed);
            }
        }
        Ok(())
    }

    fn at_boundary(&self) -> Option<usize> {
        match (self.sec, self.idx) {
            (Section::Layer(i), 0) => Some(i),
            (Section::End, 0) => Some(self.job.layers.len()),
            _ => None,
        }
    }

    pub(super) fn on_firmware_paused(&mut self) {
        if !matches!(self.state, State::Pausing | State::Printing) {
            return;
        }
        self.paused_by_firmware = true;
        let b = self.first_unsent_layer();
        self.enter_paused(Some(b), None);
    }

    fn enter_paused(&mut self, boundary: Option<usize>, prompt: Option<String>) {
        self.state = State::Paused { boundary, prompt };
        self.pause_requested_at = None;
        self.events.push(Event::Paused(boundary));
    }

    pub(super) fn on_synced(&mut self, kind: Sync) -> std::io::Result<()> {
        if self.finished() {
            return Ok(());
        }
        match kind {
            Sync::Trigger => {
                if self.state == State::Pausing {
                    self.write_realtime("M25", true)?;
                }
            }
            Sync::HostDrain => {
                self.queue_host_park();
            }
            Sync::HostParked => {
                let b = self.first_unsent_layer();
                self.enter_paused(Some(b), None);
            }
            Sync::Prompt(text) => {
                let b = self.at_boundary();
                self.enter_paused(b, Some(text));
            }
            Sync::Finish => {
                self.state = State::Done;
                self.events.push(Event::Done);
            }
        }
        Ok(())
    }

    /// Queues the host-side pause sequence for the current modal state (kept for the resume
    /// sequence) and an `M400` after it: paused once that is acknowledged.
    pub(super) fn queue_host_park(&mut self) {
        let m = self.modal.clone();
        let seq = fallback::pause_sequence(&m, &self.opts.host_pause);
        self.paused_modal = Some(m);
        self.queue.extend(seq.into_iter().map(Out::plain));
        self.queue.push_back(Out {
            line: "M400".into(),
            sync: Some(Sync::HostParked),
            tracked: true,
        });
    }
}
