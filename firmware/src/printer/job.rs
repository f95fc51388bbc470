//! The job's record in the executive: its layer counter (M27's layer, the layer the head last
//! crossed), the layer boundaries of the host's or the card's stream, and the paused-job
//! record — when a layer pause has parked at a boundary, the job's position and state there
//! are kept in flash ([`crate::storage::PausedJob`]), and forgotten when the job resumes or is
//! cancelled. The driver's store carries the requests out ([`Printer::service_store`]).
//!
//! Where the boundary is in the host's stream: when the layer detector marks a boundary, the
//! line that produced the mark (its `N` number) and the modal state before that line are noted
//! here, per layer. Lines after the boundary keep arriving while the printer parks (they queue
//! behind the barrier), so neither the link's last line nor the current modal state is the
//! boundary's: the note is. A host that does not number its lines gets no record (said so).
//!
//! A job read from the SD card is noted the same way, by the byte offset of that line in the
//! file ([`Printer::sd_line_offset`]): the lines read ahead into the queue are after it, so
//! continuing the file from that offset runs every line after the boundary once.

use super::pause::Pause;
use super::Printer;
use crate::machine::MachineState;
use crate::motion::{Axis, LayerMark, LayerSource, PauseMode};
use crate::storage::{JobSource, PausedJob};
use crate::thermal::HeaterId;
use heapless::Deque;

/// Boundaries remembered (the planner holds few marks at once; older ones have executed).
pub const BOUNDARY_NOTES: usize = 8;

/// What the executive knows about a boundary in the host's stream.
#[derive(Clone, Copy, Debug, PartialEq)]
struct BoundaryNote {
    layer: u32,
    z_um: Option<i32>,
    /// `N` of the line that produced the mark (the first line of the new layer).
    line: Option<u32>,
    /// Byte offset of that line in the SD file, when it was read from the card.
    sd_offset: Option<u32>,
    /// The modal state before that line.
    modal: MachineState,
}

/// A request for the driver's store about the paused job.
// One instance lives in the Printer and there is no heap to box the record: the size is paid
// once either way.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub(super) enum JobRequest {
    /// Keep this record.
    Save(PausedJob),
    /// Forget the record.
    Clear,
}

/// The job part (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct JobLink {
    /// M27's layer: the last layer the head crossed in this job.
    layer: Option<u32>,
    notes: Deque<BoundaryNote, BOUNDARY_NOTES>,
    request: Option<JobRequest>,
    /// A record was asked to be saved (so resuming or cancelling must clear it).
    saved: bool,
    /// A driver with a store has booted the printer (`Printer::load_settings`): records are
    /// kept only then, so a driver without a store never waits for one.
    attached: bool,
    /// The record found at power-up, until M1000 resumes it or it is discarded.
    kept: Option<PausedJob>,
    /// M1000 is under way (its heater waits and homing are queued).
    recovering: bool,
    /// M1000 continues a job from the start of this layer: the next job start (the host's
    /// `M110`, the SD file's start) numbers its layers from here (`layers.rs`).
    continue_at: Option<u32>,
}

impl JobLink {
    pub(super) const fn new() -> Self {
        Self {
            layer: None,
            notes: Deque::new(),
            request: None,
            saved: false,
            attached: false,
            kept: None,
            recovering: false,
            continue_at: None,
        }
    }

    /// M27's layer.
    pub(super) fn layer(&self) -> Option<u32> {
        self.layer
    }

    /// The head crossed `mark`: M27's layer. The end mark is no layer (the job has ended).
    pub(super) fn layer_crossed(&mut self, mark: &LayerMark) {
        self.layer = (mark.source != LayerSource::End).then_some(mark.layer);
    }

    /// A job starts: the layer it numbers from (1, or the kept layer after M1000); `ended`:
    /// nothing of an earlier job is still to print, so M27 has no layer until this one's
    /// first mark runs.
    pub(super) fn start(&mut self, ended: bool) -> u32 {
        if ended {
            self.layer = None;
        }
        self.continue_at.take().unwrap_or(1)
    }

    /// M1000 continues a kept job from the start of `layer`.
    pub(super) fn continue_at(&mut self, layer: u32) {
        self.continue_at = Some(layer);
    }

    /// A job line after M1000 without the host's M110: the continuation has begun.
    pub(super) fn continuation_begun(&mut self) {
        self.continue_at = None;
    }

    /// Note a layer boundary produced by the host line numbered `line` (or the card's line at
    /// `sd_offset`), with the modal state before it.
    pub(super) fn note_boundary(
        &mut self,
        mark: &LayerMark,
        line: Option<u32>,
        modal: &MachineState,
        sd_offset: Option<u32>,
    ) {
        if self.notes.is_full() {
            let _ = self.notes.pop_front();
        }
        let _ = self.notes.push_back(BoundaryNote {
            layer: mark.layer,
            z_um: mark.z_um,
            line,
            sd_offset,
            modal: *modal,
        });
    }

    /// The store's request, taken by its service.
    pub(super) fn take_request(&mut self) -> Option<JobRequest> {
        self.request.take()
    }

    /// A request waits for the store.
    pub(super) fn request_pending(&self) -> bool {
        self.request.is_some()
    }

    /// A driver with a store booted the printer: records are kept from now on.
    pub(super) fn attach(&mut self) {
        self.attached = true;
    }

    /// The record found at power-up, announced: kept until resumed or discarded.
    pub(super) fn keep(&mut self, j: PausedJob) {
        self.saved = true;
        self.kept = Some(j);
    }

    /// The kept record.
    pub(super) fn kept(&self) -> Option<&PausedJob> {
        self.kept.as_ref()
    }

    /// Take the kept record (M1000's last step resumes it).
    pub(super) fn take_kept(&mut self) -> Option<PausedJob> {
        self.kept.take()
    }

    /// M1000 is under way.
    pub(super) fn recovering(&self) -> bool {
        self.recovering
    }

    /// M1000 began (`true`) or reached its last step.
    pub(super) fn set_recovering(&mut self, on: bool) {
        self.recovering = on;
    }

    /// The job continues or ends (resume, cancel): forget its record.
    pub(super) fn continues(&mut self) {
        if core::mem::take(&mut self.saved) {
            self.request = Some(JobRequest::Clear);
        }
    }

    /// Forget the kept record in flash (M1000 C, a new job).
    pub(super) fn forget_kept(&mut self) {
        self.kept = None;
        self.saved = false;
        self.request = Some(JobRequest::Clear);
    }

    /// The resume of a kept record clears it before the head leaves.
    pub(super) fn resumed_from_kept(&mut self) {
        self.saved = true;
    }

    /// A job move is queued: while a kept record waits and no M1000 is under way, this is
    /// another job and the record goes; whether it did.
    pub(super) fn superseded(&mut self) -> bool {
        if self.kept.is_some() && !self.recovering {
            self.forget_kept();
            return true;
        }
        false
    }

    /// The head waits at the park position until the record is cleared: a power cut after the
    /// return started must not offer to resume a job that moved on.
    pub(super) fn clear_waits(&self, pause: &Pause) -> bool {
        matches!(pause, Pause::Returning { .. }) && self.request == Some(JobRequest::Clear)
    }

    /// Keep `j` (a layer pause parked at a noted boundary), if a store is attached.
    fn save(&mut self, j: PausedJob) {
        self.request = Some(JobRequest::Save(j));
        self.saved = true;
    }

    /// The note of the boundary before `layer`.
    fn note(&self, layer: u32) -> Option<&BoundaryNote> {
        self.notes.iter().rev().find(|n| n.layer == layer)
    }
}

impl Printer {
    /// Power-up (from `load_settings`): a job kept by a layer pause before the power went is
    /// announced to the host (`//action:notification`), with the line to restart from. The
    /// record stays until a job is paused and resumed again, or cancelled (M524).
    pub(super) fn announce_kept_job(&mut self, store: &mut dyn crate::storage::RecordStore) {
        match store.load_job() {
            Ok(Some(j)) => {
                let mut t = PlaceText::new();
                let _ = core::fmt::Write::write_fmt(
                    &mut t,
                    format_args!(
                        "Paused job kept: layer {} at Z{:.3}, continue from {} (M1000 resumes, M1000 C discards)",
                        j.layer,
                        j.boundary_z_um as f32 / 1000.0,
                        Where(&j.source)
                    ),
                );
                self.host.respond(crate::link::Response::Action(
                    crate::link::HostAction::Notification,
                    &t,
                ));
                // M1000 resumes it; M1000 C, a new job's first move, the next layer pause of a
                // new job or a cancel forgets it.
                self.job.keep(j);
            }
            Ok(None) => {}
            Err(e) => self
                .host
                .say(format_args!("power-cut resume record unusable: {e}")),
        }
    }

    /// The record for the job parked now, if it stopped at a noted boundary of a numbered
    /// host stream or of the SD file printing.
    pub fn paused_job(&self) -> Option<PausedJob> {
        let pause = self.pause.state();
        if !matches!(pause, Pause::Parked { .. }) || pause.mode() != Some(PauseMode::Layer) {
            return None;
        }
        let held = *pause.held()?;
        // The barrier stood at the first queued mark: the boundary before that layer.
        let layer = self.motion.first_mark()?.layer;
        let note = self.job.note(layer)?;
        let source = match (note.sd_offset, note.line) {
            (Some(offset), _) => JobSource::Sd {
                path: heapless::String::try_from(self.sd_file_path()?).ok()?,
                offset,
                size: self.sd_progress()?.1,
            },
            (None, Some(line)) => JobSource::Host { line },
            (None, None) => return None,
        };
        let cfg = self.settings.cfg();
        let spm = |a: Axis| cfg.axis(a).steps_per_mm;
        let z_um = note.z_um.unwrap_or_else(|| {
            let z = held.pos[Axis::Z.index()] as f32 / spm(Axis::Z) * 1000.0;
            libm::roundf(z) as i32
        });
        let t = self.heat.thermal();
        Some(PausedJob {
            source,
            layer,
            boundary_z_um: z_um,
            boundary_steps: held.pos,
            park_steps: self.motion.position(),
            modal: note.modal.modal(),
            retract_mm: held.retracted_steps as f32 / spm(Axis::E),
            hotend_c: t.target_c(HeaterId::Hotend),
            bed_c: t.target_c(HeaterId::Bed),
            fan_pwm: self.heat.fan_pwm(),
        })
    }

    /// A layer pause has parked: keep the job's record for a power-cut resume.
    pub(super) fn on_parked(&mut self) {
        if !self.job.attached {
            return;
        }
        match self.paused_job() {
            // Announced once it is in flash (`job_saved`).
            Some(j) => self.job.save(j),
            None => self.host.say(format_args!(
                "power-cut resume: not kept (no numbered host line or SD file at this boundary)"
            )),
        }
    }

    /// The job continues or ends (resume, cancel): forget its record.
    pub(super) fn on_job_continues(&mut self) {
        self.job.continues();
    }
}

/// A message that names where a kept job continues: a line's room, an SD path's, and room for
/// the widest numbers.
pub(super) type PlaceText =
    heapless::String<{ super::LINE_LEN + crate::storage::JOB_PATH_CAP + 96 }>;

/// Where a kept job continues, as the messages say it: `host line N` or `SD file NAME byte N`.
pub(super) struct Where<'a>(pub(super) &'a JobSource);

impl core::fmt::Display for Where<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            JobSource::Host { line } => write!(f, "host line {line}"),
            JobSource::Sd { path, offset, .. } => write!(f, "SD file {path} byte {offset}"),
        }
    }
}
