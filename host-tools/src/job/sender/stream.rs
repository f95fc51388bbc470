//! Writing to the printer: numbering and framing lines, keeping the resend history, and choosing
//! the next line to send (a resend, a temperature query, a host line, or the next job line at
//! the cursor, with the pause gate, the host-side move splitting and the line-length cap).

use std::io::{Read, Write};
use std::time::Duration;

use super::fallback;
use super::protocol::{frame, strip_comment};
use super::{
    Event, Out, PauseMethod, Pending, Session, State, Sync, HISTORY_LINES, LINE_CAP_FIRMWARE,
    LINE_CAP_STOCK,
};
use crate::job::gcode;
use crate::job::ops::PROMPT_PREFIX;
use crate::job::Section;

impl<P: Read + Write> Session<P> {
    /// Writes a realtime request at once, unnumbered, ahead of everything queued. Our firmware
    /// (and Marlin's emergency parser for M108/M410) still answers it with an `ok`, which is
    /// counted so it is not taken for the `ok` of a numbered line.
    pub(super) fn write_realtime(&mut self, line: &str, answered: bool) -> std::io::Result<()> {
        if answered {
            self.rt_oks += 1;
        }
        self.write_raw(&format!("{line}\n"))
    }

    pub(super) fn write_raw(&mut self, s: &str) -> std::io::Result<()> {
        self.port.write_all(s.as_bytes())?;
        self.port.flush()
    }

    pub(super) fn send_numbered(
        &mut self,
        line: String,
        sync: Option<Sync>,
    ) -> std::io::Result<()> {
        let no = self.next_no;
        let framed = frame(no, &line);
        self.next_no += 1;
        self.history.push_back((no, framed.clone()));
        while self.history.len() > HISTORY_LINES {
            self.history.pop_front();
        }
        self.outstanding += 1;
        self.last_ack = self.now;
        self.last_written = no;
        self.rejected = false;
        self.progress.lines_written += 1;
        if let Some(k) = sync {
            self.sync = Some((no, k));
        }
        self.write_raw(&format!("{framed}\n"))
    }

    pub(super) fn send_next(&mut self, now: Duration) -> std::io::Result<()> {
        if self.outstanding > 0 {
            return Ok(());
        }
        if let Some(n) = self.resend_from {
            let framed = self
                .history
                .iter()
                .find(|(no, _)| *no == n)
                .map(|(_, f)| f.clone());
            let Some(framed) = framed else {
                self.fail(format!("line {n} is not in the history"));
                return Ok(());
            };
            self.resend_from = (n + 1 < self.next_no).then_some(n + 1);
            self.outstanding += 1;
            self.last_ack = self.now;
            self.last_written = n;
            self.rejected = false;
            return self.write_raw(&format!("{framed}\n"));
        }
        if self.sync.is_some() {
            return Ok(());
        }
        let streaming = matches!(self.state, State::Printing | State::Pausing);
        if streaming
            && !self.caps.has("AUTOREPORT_TEMP")
            && now.saturating_sub(self.last_temp_req) >= self.opts.temp_every
        {
            self.last_temp_req = now;
            return self.send_numbered("M105".into(), None);
        }
        if let Some(out) = self.queue.pop_front() {
            if out.tracked {
                self.track(&out.line);
            }
            return self.send_numbered(out.line, out.sync);
        }
        if !streaming {
            return Ok(());
        }
        // Pause gating.
        self.normalize_cursor();
        match self.pending.clone() {
            Some(Pending::Now) => {
                if self.state == State::Pausing {
                    if self.method == Some(PauseMethod::HostSide) {
                        self.pending = None;
                        return self.send_numbered("M400".into(), Some(Sync::HostDrain));
                    }
                    // Firmware: wait for //action:paused.
                    return Ok(());
                }
            }
            Some(Pending::AtLayer { .. }) => {
                if self.at_gate() {
                    self.pending = None;
                    if self.state == State::Printing {
                        self.state = State::Pausing;
                        self.pause_requested_at = Some(now);
                        self.events.push(Event::Pausing);
                    }
                    return match self.method {
                        Some(PauseMethod::Firmware) => {
                            // The layer's marker comments are sent; the firmware places the
                            // mark before the next command. A harmless command delivers it, so
                            // the firmware stops at this boundary without any line of the next
                            // layer (which may still be edited).
                            self.send_numbered("M400".into(), Some(Sync::Trigger))
                        }
                        _ => {
                            self.queue_host_park();
                            self.send_next(now)
                        }
                    };
                }
            }
            None => {
                if self.state == State::Pausing {
                    return Ok(());
                }
            }
        }
        // Next job line.
        loop {
            if self.at_gate() {
                // Skipped lines brought the cursor to the gate: gate on the next poll.
                return Ok(());
            }
            let Some(raw) = self.next_job_line() else {
                return self.send_numbered("M400".into(), Some(Sync::Finish));
            };
            let trimmed = raw.trim();
            if let Some(text) = trimmed.strip_prefix(PROMPT_PREFIX) {
                self.state = State::Pausing;
                self.pending = None;
                return self.send_numbered("M400".into(), Some(Sync::Prompt(text.trim().into())));
            }
            if trimmed.starts_with('@') {
                continue;
            }
            let code = strip_comment(trimmed);
            let cap = match self.method {
                Some(PauseMethod::Firmware) => LINE_CAP_FIRMWARE,
                _ => LINE_CAP_STOCK,
            };
            if code.is_empty() {
                // Our firmware's layer detector reads slicer comments: send comment-only lines
                // (layer markers are short; long comments such as the slicer's settings dump
                // are skipped, and so are comments with a `*`, which the link would take for
                // a merged checksum and refuse).
                if self.method == Some(PauseMethod::Firmware)
                    && trimmed.starts_with(';')
                    && !trimmed.contains('*')
                    && frame(self.next_no, trimmed).len() < cap
                {
                    let line = trimmed.to_string();
                    return self.send_numbered(line, None);
                }
                continue;
            }
            if frame(self.next_no, code).len() >= cap {
                self.fail(format!(
                    "job line {code:?} is longer than the printer accepts ({cap} bytes with line number and checksum)"
                ));
                return Ok(());
            }
            let code = code.to_string();
            if self.method == Some(PauseMethod::HostSide) && matches!(self.sec, Section::Layer(_)) {
                if let Ok(Some(cmd)) = gcode::parse(&code) {
                    let hp = &self.opts.host_pause;
                    // After a layer pause request every move of the rest of the layer carries
                    // its own (sped-up) feed.
                    let feed = if self.speeding_up() {
                        let mut after = self.modal.clone();
                        after
                            .apply(&cmd)
                            .and_then(|mv| fallback::sped_up_feed_mm_min(&mv, hp))
                    } else {
                        None
                    };
                    if let Some(pieces) =
                        fallback::rewrite_move(&cmd, &self.modal, hp.split_mm, feed)
                    {
                        let mut it = pieces.into_iter();
                        if let Some(first) = it.next() {
                            self.queue.extend(it.map(Out::piece));
                            self.track(&code);
                            return self.send_numbered(first, None);
                        }
                    }
                }
            }
            self.track(&code);
            return self.send_numbered(code, None);
        }
    }

    /// True while the rest of a layer runs faster on the host side: a layer pause was requested
    /// (interactively: a pause scheduled with [`Session::pause_before_layer`] keeps the job's
    /// speeds) and the layer has not ended yet.
    fn speeding_up(&self) -> bool {
        self.method == Some(PauseMethod::HostSide)
            && self.state == State::Pausing
            && matches!(self.pending, Some(Pending::AtLayer { .. }))
            && self.opts.host_pause.speedup_factor > 1.0
    }

    /// Updates the modal state and the time estimate with a line about to be sent.
    fn track(&mut self, line: &str) {
        if let Ok(Some(cmd)) = gcode::parse(line) {
            if let Some(mv) = self.modal.apply(&cmd) {
                self.progress.est_done_s += mv.est_time_s();
            }
        }
    }

    /// True when a layer pause is pending and the (normalized) cursor has reached its gate.
    fn at_gate(&mut self) -> bool {
        let Some(Pending::AtLayer { gate }) = self.pending else {
            return false;
        };
        self.normalize_cursor();
        match self.sec {
            Section::Layer(i) => i > gate || (i == gate && self.idx == 0),
            Section::End => true,
            Section::Start => false,
        }
    }

    /// Moves the cursor past exhausted sections (without taking a line).
    pub(super) fn normalize_cursor(&mut self) {
        while self.idx >= self.job.section(self.sec).len() {
            let next = match self.sec {
                Section::Start if self.job.layers.is_empty() => Section::End,
                Section::Start => Section::Layer(0),
                Section::Layer(i) if i + 1 < self.job.layers.len() => Section::Layer(i + 1),
                Section::Layer(_) => Section::End,
                Section::End => return,
            };
            self.sec = next;
            self.idx = 0;
        }
    }

    /// Takes the next raw job line at the (normalized) cursor; `None` at the end of the job.
    fn next_job_line(&mut self) -> Option<String> {
        self.normalize_cursor();
        let l = self.job.section(self.sec).get(self.idx)?.clone();
        if self.idx == 0 {
            if let Section::Layer(i) = self.sec {
                self.progress.layer = Some(i);
                self.events.push(Event::Layer(i));
            }
        }
        self.idx += 1;
        self.progress.lines_sent += 1;
        Some(l)
    }
}
