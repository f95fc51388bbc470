//! Recovery from a lossy link: resending a line whose `ok` never came, and serving `Resend:`
//! requests (and line errors) without running an acknowledged line twice, setting the printer's
//! line counter back (M110) when it is out of step.

use std::io::{Read, Write};
use std::time::Duration;

use super::protocol::frame;
use super::{Event, Session, State, ACK_DOUBT, MAX_NUDGES, MAX_RESENDS, RESYNC_AFTER};

impl<P: Read + Write> Session<P> {
    /// No `ok` for the oldest unacknowledged line within
    /// [`Options::ok_timeout`](super::Options::ok_timeout): the line or its `ok` was lost.
    /// Resend it: a printer that never got it runs it now; one that did refuses the repeat by
    /// its line number (Marlin asks for the next line, ours acknowledges the duplicate), so it
    /// never runs twice. Every `ok` still owed is written off.
    pub(super) fn nudge(&mut self) -> std::io::Result<()> {
        self.nudges += 1;
        let line = self.acked + 1;
        if self.nudges > MAX_NUDGES {
            self.fail(format!(
                "no ok from the printer for line {line}, sent {} times",
                MAX_NUDGES + 1
            ));
            return Ok(());
        }
        self.events.push(Event::Note(format!(
            "no ok for line {line} within {} s: resending it",
            self.opts.ok_timeout.as_secs()
        )));
        self.outstanding = 0;
        self.rt_oks = 0;
        self.rejected = true;
        self.last_ack = self.now;
        self.resend_from = (line < self.next_no).then_some(line);
        if self.resend_from.is_none() {
            // Every line is known taken (the printer said so in a `Resend:`); only the `ok`
            // was lost.
            self.settled(self.now)?;
        }
        Ok(())
    }

    /// A resend request for line `n` (from `Resend:` or a line error): counted, then
    /// [`Session::on_resend`].
    pub(super) fn resend_request(&mut self, n: u32, now: Duration) -> std::io::Result<()> {
        self.progress.resends += 1;
        if self.last_resend.0 == n {
            self.last_resend.1 += 1;
        } else {
            self.last_resend = (n, 1);
        }
        if self.last_resend.1 > MAX_RESENDS {
            self.fail(format!(
                "the printer rejected line {n} {MAX_RESENDS} times in a row"
            ));
            return Ok(());
        }
        self.events.push(Event::Resend(n));
        self.last_ack = now;
        self.on_resend(n)
    }

    /// `Resend: n`. The printer's line counter says it accepted every line up to `n - 1`:
    ///
    /// - `acked < n < next_no`, a line sent but not known accepted: the usual case (checksum
    ///   error, lost line) — resend from `n`;
    /// - `n == next_no`: the printer has every line sent (it refused a repeat) — nothing to
    ///   resend;
    /// - `acked - n < ACK_DOUBT` (`n` one of the last lines taken as acknowledged): an `ok`
    ///   was not that line's (a doubled `ok`, or the `Error:`/`Resend:` of its refusal lost on
    ///   the wire so only the `ok` arrived) — resend from `n`; the printer's counter refuses
    ///   anything it already has;
    /// - anything else — a line acknowledged earlier (its counter went back: a reset that printed
    ///   no `start`, an `M110` from elsewhere, `Resend: 0`), or a line never sent (its counter is
    ///   ahead): resending from `n` would run acknowledged lines a second time, and sending on
    ///   would be refused line after line. The first time, the sender resends from the first
    ///   line not acknowledged (the number may have been garbled on the wire; a repeat is
    ///   refused by a printer whose counter is right); when the printer asks for the same line
    ///   [`RESYNC_AFTER`] times in a row, it sets the printer's counter to the last line it acknowledged (`N<acked>
    ///   M110*cs`), resends from the first line not acknowledged, and says so in a message.
    ///
    /// Before the printer has answered the connection probe there is nothing to resend: ignored.
    fn on_resend(&mut self, n: u32) -> std::io::Result<()> {
        if self.state == State::Connecting {
            self.events.push(Event::Note(format!(
                "Resend: {n} before the connection was made: ignored"
            )));
            return Ok(());
        }
        self.rejected = true;
        if n > self.acked && n < self.next_no {
            self.resend_from = Some(n);
            return Ok(());
        }
        if n == self.next_no && self.suspect.is_none() {
            self.acked = n - 1;
            self.resend_from = None;
            self.events.push(Event::Note(format!(
                "the printer asked for line {n}, which is not sent yet: nothing to resend"
            )));
            return Ok(());
        }
        if n > 0 && n <= self.acked && self.acked - n < ACK_DOUBT {
            self.acked = n - 1;
            self.resend_from = Some(n);
            self.events.push(Event::Note(format!(
                "the printer asked again for line {n}, taken as acknowledged (a doubled ok, or \
                 a refusal garbled on the wire?): resending from it"
            )));
            return Ok(());
        }
        let k = self.acked;
        let seen = match self.suspect {
            Some((m, c)) if m == n => c + 1,
            _ => 1,
        };
        if seen < RESYNC_AFTER {
            // Could be a line number garbled on the wire: resend the first line not
            // acknowledged (a repeat is refused by the printer's counter if it is right) and
            // set the counter only if the printer keeps asking for the same line.
            self.suspect = Some((n, seen));
            self.resend_from = (k + 1 < self.next_no).then_some(k + 1);
            self.events.push(Event::Note(format!(
                "the printer asked for line {n}, but it had acknowledged every line up to {k}: \
                 resending from line {}",
                k + 1
            )));
            return Ok(());
        }
        self.suspect = None;
        self.events.push(Event::Note(format!(
            "the printer asked for line {n}, but it had acknowledged every line up to {k}: \
             asked {RESYNC_AFTER} times: its line counter is out of step (reset or M110?); setting it back \
             with N{k} M110 and resending from line {}",
            k + 1
        )));
        // Checksummed, like the connection probe: a garbled one is refused, not obeyed.
        self.write_realtime(&frame(k, "M110"), true)?;
        self.resend_from = (k + 1 < self.next_no).then_some(k + 1);
        Ok(())
    }
}
