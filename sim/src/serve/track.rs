//! Following the session as it runs: realtime requests sniffed from the host's bytes, and each
//! pause tracked through the firmware's records from request to resume.

use crate::exec::PrinterExec;
use crate::port::{Executive, Lane, State};
use crate::recorder::Recorder;
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::Record;

/// One pause as the session saw it.
#[derive(Clone, Debug, Default)]
pub(super) struct PauseTrack {
    pub(super) mode: Option<PauseMode>,
    pub(super) t_req_us: u64,
    pub(super) pos_req: [i32; 4],
    pub(super) rec_idx_req: usize,
    pub(super) reaction_us: Option<u64>,
    pub(super) stopped: Option<(u64, [i32; 4], Option<u32>, bool)>,
    pub(super) parked_us: Option<u64>,
    pub(super) resume_req_us: Option<u64>,
    pub(super) rec_idx_resume: usize,
    pub(super) resumed: Option<(u64, [i32; 4])>,
    /// The firmware cancelled the job before this pause reached Paused: a cancel, not a pause.
    pub(super) cancelled: bool,
    /// The job was cancelled during this pause (or this was the cancel's own stop): a later
    /// pause request is a new pause.
    pub(super) ended: bool,
}

impl PauseTrack {
    /// Still in progress: neither resumed, nor asked to resume, nor ended by a cancel.
    fn active(&self) -> bool {
        self.resumed.is_none() && self.resume_req_us.is_none() && !self.ended
    }
}

/// Lines from the host, assembled to find realtime requests (for the record only: the
/// firmware's own link acts on them).
#[derive(Default)]
pub(super) struct Sniffer {
    pub(super) buf: Vec<u8>,
    /// Single control bytes are requests on this port (as the firmware was told).
    pub(super) control_bytes: bool,
    /// Complete non-empty lines seen, and of those the numbered ones.
    pub(super) lines: u64,
    pub(super) numbered: u64,
    /// When the line being assembled was read from the device, virtual µs.
    line_read_us: u64,
    /// Lines taken and not yet answered by an `ok`, oldest first: when each was read from the
    /// device (virtual µs) and whether the printer was parked when it was taken. A host
    /// answered line by line (printcore, OctoPrint) has one or a few in flight; at most
    /// [`UNANSWERED_CAP`] are kept (lines a firmware never answers, M112, cannot make it grow).
    unanswered: std::collections::VecDeque<Taken>,
    /// The answer being read (the output since the last `ok`) refused its line, and whether
    /// it asked for the line again (`Resend:`: not lost, the host sends it again).
    answer: Answer,
    /// Numbered lines (a host's job lines) the firmware refused — `echo:refused: …`,
    /// `echo:Line too long …` or an `Error:` without a `Resend:` — read from what the host
    /// was told, not from the firmware's bookkeeping: each is lost from the job.
    pub(super) refused_numbered: u64,
    /// The longest virtual time from a line taken while parked to the `ok` that answers it
    /// (see [`super::report::PortReport`]), and how many such waits were seen.
    pub(super) parked_wait_max_us: u64,
    pub(super) parked_waits: u64,
}

/// See [`Sniffer::unanswered`].
const UNANSWERED_CAP: usize = 64;

/// A line taken and not yet answered.
#[derive(Clone, Copy, Debug)]
struct Taken {
    /// Read from the device at, virtual µs.
    read_us: u64,
    /// The printer was parked when it was taken.
    parked: bool,
    /// It carried a line number (a job line of printcore's or OctoPrint's stream).
    numbered: bool,
}

/// What the answer read so far says of its line.
#[derive(Clone, Copy, Debug, Default)]
struct Answer {
    refused: bool,
    resend: bool,
}

impl Answer {
    /// Note one line of the firmware's output.
    fn note(&mut self, line: &str) {
        let l = line.trim_start();
        if l.starts_with("Resend:") || l.starts_with("rs ") {
            self.resend = true;
        } else if l.starts_with("echo:refused")
            || l.starts_with("echo:Line too long")
            || l.starts_with("Error:")
        {
            self.refused = true;
        }
    }
}

impl Sniffer {
    /// A sniffer for a port where single control bytes are requests, or not.
    pub(super) fn with_control_bytes(control_bytes: bool) -> Self {
        Self {
            control_bytes,
            ..Self::default()
        }
    }

    /// Bytes the firmware took at `now_us`, read from the device at `read_us`; `parked`: the
    /// printer is parked.
    pub(super) fn feed(
        &mut self,
        bytes: &[u8],
        out: &mut Vec<Realtime>,
        read_us: u64,
        parked: bool,
    ) {
        for &b in bytes {
            if let Some(r) = firmware::link::control_byte(b) {
                if self.control_bytes {
                    out.push(r);
                }
                continue;
            }
            if b == b'\n' || b == b'\r' {
                let line = std::mem::take(&mut self.buf);
                let text = String::from_utf8_lossy(&line);
                let body = text.trim();
                if body.is_empty() {
                    continue;
                }
                self.lines += 1;
                let numbered = body.starts_with('N');
                self.numbered += u64::from(numbered);
                if self.unanswered.len() == UNANSWERED_CAP {
                    self.unanswered.pop_front();
                }
                self.unanswered.push_back(Taken {
                    read_us: self.line_read_us,
                    parked,
                    numbered,
                });
                let body = match body.strip_prefix('N') {
                    Some(rest) => rest.split_once(' ').map_or("", |x| x.1),
                    None => body,
                };
                let body = body.split('*').next().unwrap_or("");
                if let Ok(l) = firmware::gcode::parse_line(body.as_bytes()) {
                    if let Some(r) = l.command.as_ref().and_then(firmware::link::realtime_of) {
                        out.push(r);
                    }
                }
            } else {
                if self.buf.is_empty() {
                    self.line_read_us = read_us;
                }
                if self.buf.len() < 256 {
                    self.buf.push(b);
                }
            }
        }
    }
}

impl Sniffer {
    /// The firmware's output `out` went to this port's host at `now_us`: each `ok` answers
    /// the oldest line waiting for one (the firmware answers a port's lines in order), and
    /// what came before it says whether that line was refused.
    pub(super) fn answered(&mut self, out: &str, now_us: u64) {
        for line in out.lines() {
            if !line.starts_with("ok") {
                self.answer.note(line);
                continue;
            }
            let answer = std::mem::take(&mut self.answer);
            let Some(t) = self.unanswered.pop_front() else {
                continue;
            };
            if t.numbered && answer.refused && !answer.resend {
                self.refused_numbered += 1;
            }
            if t.parked {
                self.parked_wait_max_us = self
                    .parked_wait_max_us
                    .max(now_us.saturating_sub(t.read_us));
                self.parked_waits += 1;
            }
        }
    }

    /// A session started or ended on the port: its lines in flight are gone.
    pub(super) fn new_session(&mut self) {
        self.buf.clear();
        self.unanswered.clear();
        self.answer = Answer::default();
    }
}

pub(super) fn note_request(
    pauses: &mut Vec<PauseTrack>,
    r: Realtime,
    now_us: u64,
    rec: &Recorder,
    fw: &PrinterExec,
) {
    match r {
        Realtime::Pause(mode) => {
            // (A cancel's brake shows as Pausing too: a cancelled track is over.)
            let active = pauses.last().is_some_and(|p| p.active() && !p.cancelled);
            // Called after the firmware took the bytes: a pause it accepted shows as Pausing
            // (also from an idle printer inside a streamed job, e.g. at a boundary the host
            // drained with M400); a refused one leaves it as it was.
            let state = fw.status().state;
            if !active && matches!(state, State::Pausing | State::Paused) {
                pauses.push(PauseTrack {
                    mode: Some(mode),
                    t_req_us: now_us,
                    pos_req: rec.pos,
                    rec_idx_req: rec.records.len(),
                    ..PauseTrack::default()
                });
            }
        }
        Realtime::Resume => {
            if let Some(p) = pauses.last_mut() {
                if p.resume_req_us.is_none() && p.stopped.is_some() {
                    p.resume_req_us = Some(now_us);
                    p.rec_idx_resume = rec.records.len().saturating_sub(1);
                }
            }
        }
        _ => {}
    }
}

pub(super) fn track(
    pauses: &mut Vec<PauseTrack>,
    fw: &PrinterExec,
    rec: &Recorder,
    seen: &mut usize,
    cancel_marks: &mut Vec<usize>,
) {
    for r in fw.notes.iter().skip(*seen) {
        if let Record::State {
            state: firmware::printer::State::Cancelled,
            ..
        } = *r
        {
            cancel_marks.push(fw.executed.len());
            if let Some(p) = pauses.last_mut() {
                if p.parked_us.is_none() {
                    p.cancelled = true;
                }
                // Before this, a cancel left its track (or the paused job's) active, and the
                // next job's pause went unrecorded.
                p.ended = true;
            }
        }
        // A pause the firmware started by itself (M761 schedule, M600/M0, M25 in the job):
        // tracked from the moment it began.
        if let Record::State {
            state: firmware::printer::State::Pausing,
            t_us,
        } = *r
        {
            // (A cancel's brake shows as Pausing too: a cancelled track is over.)
            let active = pauses.last().is_some_and(|p| p.active() && !p.cancelled);
            if !active {
                pauses.push(PauseTrack {
                    mode: Some(PauseMode::Layer),
                    t_req_us: t_us,
                    pos_req: rec.pos,
                    rec_idx_req: rec.records.len(),
                    ..PauseTrack::default()
                });
            }
        }
        let Some(p) = pauses.last_mut() else {
            continue;
        };
        match *r {
            Record::SpeedUp { t_us } | Record::Brake { t_us, .. }
                if t_us >= p.t_req_us && p.reaction_us.is_none() =>
            {
                p.reaction_us = Some(t_us);
            }
            Record::Stopped {
                pos,
                layer,
                mid_block,
                t_us,
            } if p.stopped.is_none() => {
                p.stopped = Some((t_us, pos, layer, mid_block));
            }
            Record::State { state, t_us }
                if state == firmware::printer::State::Paused && p.parked_us.is_none() =>
            {
                p.parked_us = Some(t_us);
            }
            _ => {}
        }
    }
    *seen = fw.notes.len();
    // A resume is found in the executed blocks (the first job block after the request); a
    // host may already have asked for the next pause by then, so every pause is looked at.
    for p in pauses
        .iter_mut()
        .filter(|p| p.resume_req_us.is_some() && p.resumed.is_none())
    {
        let t_res = p.resume_req_us.unwrap_or(0);
        if let Some(r) = rec
            .records
            .iter()
            .skip(p.rec_idx_resume)
            .find(|r| r.tag.lane == Lane::Job && r.t_start_us >= t_res)
        {
            p.resumed = Some((r.t_start_us, r.start));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Sniffer;

    fn take(s: &mut Sniffer, line: &str) {
        let mut reqs = Vec::new();
        s.feed(format!("{line}\n").as_bytes(), &mut reqs, 0, false);
    }

    #[test]
    fn a_refused_job_line_is_counted_and_a_resent_or_console_one_is_not() {
        let mut s = Sniffer::default();
        // A job line refused: lost.
        take(&mut s, "N10 G1 X1e39*1");
        s.answered("echo:refused: X out of range\n", 1);
        s.answered("ok\n", 2);
        assert_eq!(s.refused_numbered, 1);
        // A checksum error asks for the line again: not lost.
        take(&mut s, "N11 G1 X2*0");
        s.answered(
            "Error:checksum mismatch, Last Line: 10\nResend: 11\nok\n",
            3,
        );
        // Accepted, with an unrelated temperature report before its ok.
        take(&mut s, "N11 G1 X2*99");
        s.answered(" T:200.0 /200.0 B:60.0 /60.0\nok\n", 4);
        // A console line refused (unnumbered): the job lost nothing.
        take(&mut s, "M602");
        s.answered("echo:refused: nothing to resume\nok\n", 5);
        assert_eq!(s.refused_numbered, 1);
        // Each line answered once, in order: nothing left waiting.
        assert!(s.unanswered.is_empty());
    }
}
