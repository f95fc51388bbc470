//! Reading the printer: splitting the received bytes into lines and reacting to each reply
//! (`ok`, `Resend:`, `busy:`, `echo:`, `Error:`, temperatures, `//action:`, the M115 report), and
//! choosing the pause method once M115 is answered.

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use super::protocol::{self, Action, Response};
use super::{Capabilities, Event, Out, PauseMethod, Pending, Request, Session, State};

impl<P: Read + Write> Session<P> {
    pub(super) fn read_port(&mut self, now: Duration) -> std::io::Result<()> {
        let mut buf = [0u8; 1024];
        match self.port.read(&mut buf) {
            Ok(0) => {}
            Ok(n) => {
                self.last_rx = now;
                self.rx.extend_from_slice(&buf[..n]);
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
        while let Some(pos) = self.rx.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.rx.drain(..=pos).collect();
            let text = String::from_utf8_lossy(&line).trim().to_string();
            if !text.is_empty() {
                if self.log_rx {
                    self.rx_log.push(text.clone());
                }
                self.handle_line(&text, now)?;
            }
        }
        if self.rx.len() > 4096 {
            self.rx.clear();
        }
        Ok(())
    }

    fn handle_line(&mut self, line: &str, now: Duration) -> std::io::Result<()> {
        if self.finished() {
            // Done, cancelled or failed: nothing the printer says changes that.
            return Ok(());
        }
        match Response::parse(line) {
            Response::Ok { temps, .. } => {
                if let Some(t) = temps {
                    self.progress.temps = t;
                }
                if self.state == State::Connecting {
                    if self.last_probe.is_none() {
                        // Left over from before this session (no probe written yet).
                        return Ok(());
                    }
                    self.state = State::Identifying;
                    self.next_no = 1;
                    self.acked = 0;
                    self.identify_sent_at = Some(now);
                    self.send_numbered("M115".to_string(), None)?;
                    return Ok(());
                }
                self.last_ack = now;
                self.error_resend = None;
                if self.rt_oks > 0 {
                    self.rt_oks -= 1;
                    return Ok(());
                }
                if self.outstanding > 0 {
                    self.nudges = 0;
                }
                self.outstanding = self.outstanding.saturating_sub(1);
                if self.outstanding == 0 && !self.rejected && self.last_written > self.acked {
                    self.acked = self.last_written;
                    self.suspect = None;
                    // Progress: "rejected N times in a row" counts from here.
                    self.last_resend = (0, 0);
                }
                self.settled(now)?;
            }
            Response::Resend(n) => {
                if self.error_resend.take() == Some(n) {
                    // Already handled from the `Error:…, Last Line: n-1` before it.
                    return Ok(());
                }
                self.resend_request(n, now)?;
            }
            Response::Busy(_) => self.last_ack = now,
            Response::Echo(e) => {
                if e.contains("nothing to pause") && self.state == State::Pausing {
                    // The firmware had already finished every queued move (the head waits at
                    // the boundary): park from the host.
                    self.queue_host_park();
                }
                self.events.push(Event::Message(e));
            }
            Response::Error(e) => {
                let fatal = e.contains("halted") || e.contains("kill") || e.contains("Killed");
                self.events.push(Event::PrinterError(e.clone()));
                if fatal {
                    self.fail(format!("printer error: {e}"));
                    return Ok(());
                }
                // A line error (`Error:checksum mismatch, Last Line: L`, Marlin's and ours) is
                // followed by `Resend: L+1`; act on the error already, so a `Resend:` line lost
                // on the wire cannot make its `ok` look like an acceptance.
                if self.state == State::Connecting {
                    return Ok(());
                }
                if let Some(l) = protocol::last_line(&e) {
                    let n = l.saturating_add(1);
                    self.error_resend = Some(n);
                    self.resend_request(n, now)?;
                } else if protocol::is_link_error(&e) && self.acked < self.last_written {
                    // A checksum error without a line number: our line arrived with its `N`
                    // garbled, and no `Resend:` can follow. Resend the oldest line not
                    // acknowledged (a repeat is refused by the printer's counter).
                    let n = self.acked + 1;
                    self.resend_request(n, now)?;
                }
            }
            Response::Temperature(t) => self.progress.temps = t,
            Response::Action(a) => {
                self.events.push(Event::Action(a.clone()));
                match a {
                    Action::Paused => self.on_firmware_paused(),
                    Action::Resumed if self.state == State::Resuming => {
                        self.state = State::Printing;
                        self.resume_requested_at = None;
                    }
                    // Before the job has started there is nothing of ours to cancel (the printer
                    // may be asking an earlier host to stop).
                    Action::Cancel
                        if !self.finished()
                            && !matches!(self.state, State::Connecting | State::Identifying) =>
                    {
                        self.state = State::Cancelled;
                        self.events.push(Event::Cancelled);
                    }
                    Action::Pause => self.request(Request::PauseAtLayer, now)?,
                    // The printer asks to resume (its button) or announces its own return.
                    Action::Resume if matches!(self.state, State::Paused { .. }) => {
                        self.request(Request::Resume, now)?
                    }
                    Action::Notification(t) => self.events.push(Event::Message(t)),
                    _ => {}
                }
            }
            Response::FirmwareInfo(f) => self.caps.firmware = Some(f),
            Response::Capability { name, enabled } => self.caps.caps.push((name, enabled)),
            Response::Start => match self.state {
                State::Connecting => {}
                State::Identifying => {
                    // The board rebooted after the M115 query: connect again.
                    self.state = State::Connecting;
                    self.last_probe = None;
                    self.connecting_since = None;
                    self.identify_sent_at = None;
                    self.outstanding = 0;
                    self.rt_oks = 0;
                    self.resend_from = None;
                    self.history.clear();
                    self.caps = Capabilities::default();
                    self.events.push(Event::Note(
                        "the printer restarted while connecting: connecting again".into(),
                    ));
                }
                _ => self.fail("the printer restarted during the job"),
            },
            Response::Other(_) => {}
        }
        Ok(())
    }

    /// Every line written is answered and none waits to be resent: finish identifying, or act
    /// on the synchronising line (the last one written) now that it is taken.
    pub(super) fn settled(&mut self, now: Duration) -> std::io::Result<()> {
        if self.outstanding > 0 || self.resend_from.is_some() {
            return Ok(());
        }
        if self.state == State::Identifying {
            self.identified(now);
            return Ok(());
        }
        if let Some((no, _)) = &self.sync {
            if no + 1 == self.next_no {
                if let Some((_, kind)) = self.sync.take() {
                    self.on_synced(kind)?;
                }
            }
        }
        Ok(())
    }

    /// M115 answered (its `ok`): choose the pause method and start streaming.
    fn identified(&mut self, now: Duration) {
        self.identify_sent_at = None;
        let method = self.opts.method.unwrap_or(if self.caps.layer_pause() {
            PauseMethod::Firmware
        } else {
            PauseMethod::HostSide
        });
        self.method = Some(method);
        self.state = if matches!(self.pending, Some(Pending::Now)) {
            State::Pausing
        } else {
            State::Printing
        };
        self.started = Some(now);
        self.last_temp_req = now;
        if self.caps.has("AUTOREPORT_TEMP") {
            self.queue.push_back(Out::plain("M155 S2"));
        }
        if method == PauseMethod::Firmware {
            let setup = self.opts.firmware_setup.clone();
            self.queue.extend(setup.into_iter().map(Out::plain));
        }
        if let (PauseMethod::Firmware, Some(Pending::AtLayer { gate })) = (method, &self.pending) {
            // The firmware counts layers with the same detector over the same stream: schedule
            // the pause there too (M761), so it holds at the mark however fast it drains its
            // queue.
            if let Some(l) = self.job.layers.get(*gate) {
                let line = format!("M761 L{}", l.number);
                self.queue.push_back(Out::plain(line));
                self.scheduled = true;
            }
        }
        self.events.push(Event::Connected(method));
    }
}
