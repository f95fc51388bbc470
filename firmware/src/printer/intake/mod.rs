//! The intake: what the executive has taken from the host and the card, and where it goes —
//! queued for the job (the command queue), held (a line waiting for room, the parked intake's
//! RAM slots and its spill to the card), taken as a manual command while parked, or discarded
//! as the tail of a cancelled job — and why. It owns the command queue, the job's modal state
//! and layer detector ([`Interpreter`]), the manual lines' copy of it while parked, an arc
//! being cut, the host-line rules' state and the spill (docs/frontend.md, "Host rules").
//!
//! Files: this one (the queue, room, routes, numbering), `cancel` (the cancelled stream's
//! tail), `interpret` (a line into commands), `sync` (M400's owed `ok`), `spill` (the parked intake's card file).

mod cancel;
mod interpret;
pub(super) mod spill;
mod sync;

pub(super) use cancel::TailLine;
pub(super) use interpret::{Interpreted, LineOutcome};

use super::pause::Pause;
pub use super::types::CMD_CAPACITY;
use super::types::{Command, PausedLines, Policy};
use crate::config::MachineConfig;
use crate::layer::LayerDetector;
use crate::link::{PortId, ReceivedLine};
use crate::machine::{ArcMoves, Interpreter, MachineState};
use crate::motion::{LayerMark, StepPos};
use heapless::Deque;
use spill::Spill;

/// Job lines a parked printer takes into RAM beyond the running queue limit
/// ([`CMD_CAPACITY`]), one per pace period, so that a host that keeps streaming one numbered
/// line per `ok` into a parked printer (printcore: it ignores `//action:paused`) keeps getting
/// `ok`s, and with each `ok` its priority queue (`send_now`: M602, M524, M105, jogs) gets out.
/// Beyond them the lines go to the SD card when one is mounted (`spill.rs`), for as long as
/// the pause lasts; without a card the intake ends here (docs/frontend.md, "Host rules").
pub const PARKED_EXTRA: usize = 96;

/// Physical slots of the command queue: [`CMD_CAPACITY`] for the running job plus the parked
/// intake ([`PARKED_EXTRA`]).
pub const CMD_SLOTS: usize = CMD_CAPACITY + PARKED_EXTRA;

/// Pace of the parked intake: a job line that has waited this long while parked is taken
/// (and its `ok` sent). With a card to spill to the pace stays at this, so a console line
/// queued at any moment gets out within it; without one it grows by this much for every 32
/// lines taken, so the RAM slots last 32 × (1 + 2 + 3) s = 192 s of pause with `ok`s at most
/// 3 s apart.
pub const PARKED_PACE_US: u64 = 1_000_000;

/// A `layer` pause waiting for a boundary treats the end of the known job as the boundary once
/// the printer has had nothing to do for this long (job ended before any layer boundary); the
/// same silence ends the discarding of a cancelled job's tail and the "in a job" window.
pub const LAYER_PAUSE_IDLE_US: u64 = 2_000_000;

/// Where a host line goes (see [`Intake::route`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Route {
    /// Into the command queue (within the running limit, or into the RAM extra slots).
    Queue,
    /// Into the spill on the SD card.
    Spill,
}

/// The intake part (see the module documentation).
#[derive(Clone, Debug)]
pub(super) struct Intake {
    cmds: Deque<Command, CMD_SLOTS>,
    /// The job's modal state and layer detector.
    interp: Interpreter,
    /// The modal state manual lines are interpreted in while parked: a copy of the job's at
    /// the parked position, dropped on resume (`None` when every line is a job line).
    manual: Option<MachineState>,
    /// An arc being cut into moves (its line's `ok` waits for the last one).
    arc: Option<ArcMoves>,
    /// A line taken from the link that waits for queue room, when it started waiting, and
    /// the port it came from.
    held_line: Option<ReceivedLine>,
    held_since_us: u64,
    held_port: Option<PortId>,
    /// The host has sent numbered lines (it numbers its job): with [`PausedLines::Auto`],
    /// unnumbered lines while paused are manual commands.
    host_numbers: bool,
    /// Number of the last numbered line taken.
    last_line_no: Option<u32>,
    /// The job was cancelled: the rest of the host's stream is discarded until it starts anew.
    after_cancel: Option<cancel::AfterCancel>,
    /// An M400 waits for the motion to end: its `ok` is owed, and no further line is taken
    /// (`sync.rs`).
    sync: sync::SyncOk,
    /// The port of the last job line taken (whose host streams the job).
    job_port: Option<PortId>,
    /// The host reset its line numbers (`M110`): a job starts at its next job line taken.
    job_start_due: bool,
    /// The job's host went away while the job ran or was paused: it can only be cancelled.
    orphaned: bool,
    /// When a host line was last taken or a block last ended, µs ("in a job").
    last_activity_us: u64,
    /// Job lines of a parked printer kept on the card.
    spill: Spill,
    /// The policy's limit on waiting commands, and what lines mean while paused.
    cmd_limit: usize,
    paused_lines: PausedLines,
}

impl Intake {
    /// Builds the intake in `slot` field by field (its queue is 4 KiB: never on the stack).
    ///
    /// # Safety
    /// `slot` must be valid for writes of an `Intake`; whatever it held is overwritten, not
    /// dropped.
    pub(super) unsafe fn init_in_place(slot: *mut Intake, cfg: &MachineConfig) {
        use core::ptr::addr_of_mut;
        // SAFETY: the caller's slot; every field written once through `addr_of_mut!`.
        unsafe {
            addr_of_mut!((*slot).cmds).write(Deque::new());
            addr_of_mut!((*slot).interp).write(Interpreter {
                machine: MachineState::new(cfg),
                layers: LayerDetector::new().with_end_mark(),
            });
            addr_of_mut!((*slot).manual).write(None);
            addr_of_mut!((*slot).arc).write(None);
            addr_of_mut!((*slot).held_line).write(None);
            addr_of_mut!((*slot).held_since_us).write(0);
            addr_of_mut!((*slot).held_port).write(None);
            addr_of_mut!((*slot).host_numbers).write(false);
            addr_of_mut!((*slot).last_line_no).write(None);
            addr_of_mut!((*slot).after_cancel).write(None);
            addr_of_mut!((*slot).sync).write(sync::SyncOk::NONE);
            addr_of_mut!((*slot).job_port).write(None);
            addr_of_mut!((*slot).job_start_due).write(false);
            addr_of_mut!((*slot).orphaned).write(false);
            addr_of_mut!((*slot).last_activity_us).write(0);
            addr_of_mut!((*slot).spill).write(Spill::new());
            addr_of_mut!((*slot).cmd_limit).write(CMD_CAPACITY);
            addr_of_mut!((*slot).paused_lines).write(PausedLines::Auto);
        }
    }

    /// Names every field (never called): a field added to [`Intake`] and not written by
    /// [`Intake::init_in_place`] fails to compile here.
    #[allow(dead_code)]
    fn fields_listed(i: &Intake) {
        let Intake {
            cmds: _,
            interp: _,
            manual: _,
            arc: _,
            held_line: _,
            held_since_us: _,
            held_port: _,
            host_numbers: _,
            last_line_no: _,
            after_cancel: _,
            sync: _,
            job_port: _,
            job_start_due: _,
            orphaned: _,
            last_activity_us: _,
            spill: _,
            cmd_limit: _,
            paused_lines: _,
        } = i;
    }

    /// The policy's queue limit and meaning of lines while paused.
    pub(super) fn set_policy(&mut self, p: &Policy) {
        self.cmd_limit = p.cmd_limit.clamp(1, CMD_CAPACITY);
        self.paused_lines = p.paused_lines;
    }

    // ---- the job's modal state ----

    /// The job's modal state.
    pub(super) fn machine(&self) -> &MachineState {
        &self.interp.machine
    }

    /// The job's modal state is at the head's position (a cancel, a quick stop, settings).
    pub(super) fn machine_at(&mut self, pos: &StepPos, cfg: &MachineConfig) {
        self.interp.machine.set_position_steps(pos, cfg);
    }

    /// The job's modal state is `m` (M1000 restores the kept job's).
    pub(super) fn restore_machine(&mut self, m: MachineState) {
        self.interp.machine = m;
    }

    /// Parked: manual lines are interpreted from here on in a copy of the job's modal state
    /// at the parked position (unless every line is a job line).
    pub(super) fn parked(&mut self, here: &StepPos, cfg: &MachineConfig) {
        self.manual = (self.paused_lines != PausedLines::Queue).then(|| {
            let mut m = self.interp.machine;
            m.set_position_steps(here, cfg);
            m
        });
    }

    /// The pause ended: the manual copy goes.
    pub(super) fn unparked(&mut self) {
        self.manual = None;
    }

    /// The layer detector: a job starts here, numbering its layers from `first`.
    pub(super) fn restart_layers(&mut self, first: u32) {
        self.interp.layers.restart(first);
    }

    /// A marker comment seen with no motion after it, as a boundary (the end of a stream).
    pub(super) fn finish_layer(&mut self) -> Option<LayerMark> {
        self.interp.layers.finish()
    }

    // ---- the command queue ----

    /// The command at the front of the queue.
    pub(super) fn front(&self) -> Option<&Command> {
        self.cmds.front()
    }

    /// The front command was carried out.
    pub(super) fn pop_front(&mut self) {
        let _ = self.cmds.pop_front();
    }

    /// The front command becomes `c` (an M109's setting done, its wait follows in its place).
    pub(super) fn replace_front(&mut self, c: Command) {
        if let Some(f) = self.cmds.front_mut() {
            *f = c;
        }
    }

    /// Queue a command (the caller checked the room).
    pub(super) fn push(&mut self, c: Command) {
        let _ = self.cmds.push_back(c);
    }

    /// Commands waiting.
    pub(super) fn len(&self) -> usize {
        self.cmds.len()
    }

    /// Nothing waiting.
    pub(super) fn is_empty(&self) -> bool {
        self.cmds.is_empty()
    }

    /// A layer mark of a job is still in the queue.
    pub(super) fn marks_queued(&self) -> bool {
        self.cmds.iter().any(|c| matches!(c, Command::Layer(_)))
    }

    /// Room in the command queue under the policy's limit (a driver's own commands).
    pub(super) fn command_room(&self) -> usize {
        self.cmd_limit.saturating_sub(self.cmds.len())
    }

    fn queued_moves(&self) -> usize {
        self.cmds
            .iter()
            .filter(|c| !matches!(c, Command::Layer(_)))
            .count()
    }

    /// Room for one more host line: the policy's limit on waiting commands (layer marks do not
    /// count) less the pause's reserve — a slot kept free while a pause is on its way, so the
    /// line the host has in flight when the printer announces `//action:paused` always fits
    /// and its `ok` follows the announcement — and physical room for a mark plus a command.
    pub(super) fn line_room(&self, pause: &Pause) -> bool {
        let reserve = usize::from(matches!(
            pause,
            Pause::Stopping { .. } | Pause::Parking { .. }
        ));
        self.queued_moves() + reserve < self.cmd_limit
            && self.cmds.len() + 2 + reserve <= CMD_CAPACITY
    }

    /// Commands queued beyond the running limit (lines the parked intake took).
    pub(super) fn parked_excess(&self) -> usize {
        self.queued_moves().saturating_sub(self.cmd_limit)
    }

    /// A job line may go straight into the queue: room, and no spilled line ahead of it.
    pub(super) fn job_line_fits(&self, pause: &Pause) -> bool {
        self.line_room(pause) && self.spill.pending() == 0
    }

    /// Whether `line`, the job line that waited in the held slot, is due for the paced intake,
    /// and where it goes: parked or returning (or, after the resume, while what the intake
    /// took still runs), and it has
    /// waited the pace ([`PARKED_PACE_US`]; longer as the RAM slots fill when no card can
    /// take the spill). `card`: a card can take spilled lines now.
    pub(super) fn intake_due(
        &self,
        line: &ReceivedLine,
        pause: &Pause,
        card: bool,
        now_us: u64,
    ) -> Option<Route> {
        let backlog = self.parked_excess() > 0 || self.spill.pending() > 0;
        let on = match pause {
            // A job whose host went away takes no new session's lines behind it. The return
            // (and the re-heat it waits for) keeps the pace: a console line queued behind a
            // job line gets out within it.
            Pause::Parked { .. } | Pause::Returning { .. } => !self.orphaned,
            Pause::Run => backlog,
            _ => false,
        };
        if !on {
            return None;
        }
        let spill_possible = card && !self.spill.failed();
        let pace_us = if spill_possible {
            PARKED_PACE_US
        } else {
            PARKED_PACE_US * (1 + (self.parked_excess() / 32) as u64)
        };
        if now_us.saturating_sub(self.held_since_us) < pace_us {
            return None;
        }
        if self.spill.pending() == 0 && self.cmds.len() + 2 <= CMD_SLOTS {
            return Some(Route::Queue);
        }
        (spill_possible && self.spill.has_room(line)).then_some(Route::Spill)
    }

    /// Whether a host line waiting for room should get `busy:` keep-alives: while a pause
    /// holds the queue, and while the lines the parked intake took run after the resume.
    pub(super) fn host_kept_waiting(&self, pause: &Pause) -> bool {
        !matches!(pause, Pause::Run) || self.parked_excess() > 0 || self.spill.pending() > 0
    }

    /// Whether a host line taken now from `port` is a console (manual) command rather than a
    /// job line (see [`PausedLines`]; docs/frontend.md, "What lines mean"): while parked by
    /// the policy's rule; with [`PausedLines::Auto`] also, while a job runs or is held
    /// (`in_job`, not a cancelled one), an unnumbered line from the port whose host streams
    /// the numbered job (printcore's `send_now`), so that a jog that waited in the host's
    /// queue never runs inside the job. `in_job` is asked last, only for an unnumbered line
    /// of the job's port while not parked (it looks at the whole executive, and a line waiting
    /// for room is asked about at every poll).
    pub(super) fn is_manual(
        &self,
        line: &ReceivedLine,
        port: PortId,
        pause: &Pause,
        in_job: impl FnOnce() -> bool,
    ) -> bool {
        let parked = matches!(pause, Pause::Parked { .. });
        match self.paused_lines {
            PausedLines::Queue => false,
            PausedLines::Manual => parked,
            PausedLines::Auto => {
                if !self.host_numbers || line.number().is_some() {
                    return false;
                }
                parked || (self.job_port == Some(port) && !self.cancelled() && in_job())
            }
        }
    }

    /// The port of the line waiting for room.
    pub(super) fn held_port(&self) -> Option<PortId> {
        self.held_port
    }

    // ---- the line waiting for room ----

    /// A line waits for room.
    pub(super) fn has_held_line(&self) -> bool {
        self.held_line.is_some()
    }

    /// The waiting line, to look at.
    pub(super) fn held_line(&self) -> Option<&ReceivedLine> {
        self.held_line.as_ref()
    }

    /// Take the waiting line (it fits now).
    pub(super) fn take_held_line(&mut self) -> Option<ReceivedLine> {
        self.held_line.take()
    }

    /// `line` from `port` waits for room from `now_us` on.
    pub(super) fn hold_line(&mut self, line: ReceivedLine, port: PortId, now_us: u64) {
        self.held_line = Some(line);
        self.held_since_us = now_us;
        self.held_port = Some(port);
    }

    // ---- numbering, activity, sessions ----

    /// A line was taken: its number (the host numbers its job), its port for a job line.
    pub(super) fn took_line(&mut self, number: Option<u32>, job_port: Option<PortId>, now_us: u64) {
        if number.is_some() {
            self.host_numbers = true;
            self.last_line_no = number;
        }
        if job_port.is_some() {
            self.job_port = job_port;
        }
        self.last_activity_us = now_us;
    }

    /// A line was handled now (a card's or the spill's).
    pub(super) fn touch(&mut self, now_us: u64) {
        self.last_activity_us = now_us;
    }

    /// Something happened that counts as job activity (a line, a block ended).
    pub(super) fn active(&mut self, t_us: u64) {
        self.last_activity_us = self.last_activity_us.max(t_us);
    }

    /// How long the job's host and motion have been quiet.
    pub(super) fn idle_us(&self, now_us: u64) -> u64 {
        now_us.saturating_sub(self.last_activity_us)
    }

    /// A host line was taken or a block ended within [`LAYER_PAUSE_IDLE_US`] (and ever).
    pub(super) fn recently_active(&self, now_us: u64) -> bool {
        self.last_activity_us != 0 && self.idle_us(now_us) < LAYER_PAUSE_IDLE_US
    }

    /// The host reset its line numbers before this line: a job starts with the next job line.
    pub(super) fn note_reset(&mut self, reset: bool) {
        self.job_start_due |= reset;
    }

    /// The job start a line-number reset announced is due now (no line of the job before is
    /// left in the spill): taken (the caller restarts the layer count).
    pub(super) fn take_due_start(&mut self) -> bool {
        if self.job_start_due && self.spill.pending() == 0 {
            self.job_start_due = false;
            return true;
        }
        false
    }

    /// The reset travels with a line into the spill (the job starts when it is fed back).
    pub(super) fn take_start_for_spill(&mut self) -> bool {
        core::mem::take(&mut self.job_start_due)
    }

    /// The port whose host streams the job.
    pub(super) fn job_port(&self) -> Option<PortId> {
        self.job_port
    }

    /// The job's host went away.
    pub(super) fn orphaned(&self) -> bool {
        self.orphaned
    }

    /// The host on `port` went away: a line of it that waited is forgotten (never
    /// acknowledged); `orphan`: the job it streamed is left without its host.
    pub(super) fn session_ended(&mut self, port: PortId, orphan: bool) {
        if self.held_port == Some(port) {
            self.held_line = None;
            self.held_port = None;
        }
        self.orphaned |= orphan;
    }

    // ---- arcs ----

    /// An arc is being cut (its line's `ok` waits).
    pub(super) fn cutting_arc(&self) -> bool {
        self.arc.is_some()
    }

    /// Queue the arc's moves while there is room; true when the whole arc is queued.
    pub(super) fn push_arc(&mut self, pause: &Pause) -> bool {
        while self.arc.is_some() {
            if !self.line_room(pause) {
                return false;
            }
            match self.arc.as_mut().and_then(|a| a.next()) {
                Some(m) => {
                    let _ = self.cmds.push_back(Command::Move(m));
                }
                None => self.arc = None,
            }
        }
        true
    }

    // ---- stops ----

    /// A cancel dropped the job: the queue, the arc, the spill go; the stream's tail is
    /// discarded from here. Returns (commands dropped, spilled lines dropped).
    pub(super) fn drop_job(&mut self) -> (usize, u32) {
        let cmds = self.cmds.len();
        self.cmds.clear();
        let spilled = self.spill.drop_all();
        self.orphaned = false;
        self.arc = None;
        self.after_cancel = Some(cancel::AfterCancel::new(self.last_line_no));
        (cmds, spilled)
    }

    /// M410: the arc goes and the job is no longer orphaned (it was dropped).
    pub(super) fn quick_stop(&mut self) {
        self.orphaned = false;
        self.arc = None;
    }

    /// M112: nothing queued, nothing owed.
    pub(super) fn halt(&mut self) {
        self.arc = None;
        self.cmds.clear();
        self.sync = sync::SyncOk::NONE;
    }

    /// A homing in progress was aborted: its G28 leaves the queue's front.
    pub(super) fn drop_front_home(&mut self) {
        if let Some(Command::Home { .. }) = self.cmds.front() {
            let _ = self.cmds.pop_front();
        }
    }

    /// An SD job began or M24 started one: the host's stream is not cancelled any more.
    pub(super) fn forget_cancel(&mut self) {
        self.after_cancel = None;
    }

    /// The rest of a cancelled job is being discarded (the printer reports `Cancelled`).
    pub(super) fn cancelled(&self) -> bool {
        self.after_cancel.is_some()
    }
}
