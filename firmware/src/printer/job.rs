//! The paused-job record in the executive: when a layer pause has parked at a boundary, the
//! job's position and state there are kept in flash ([`crate::storage::PausedJob`]), and
//! forgotten when the job resumes or is cancelled. The driver's store carries both out
//! ([`Printer::service_store`]).
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

use super::state::Pause;
use super::Printer;
use crate::machine::MachineState;
use crate::motion::{Axis, PauseMode};
use crate::storage::{JobSource, PausedJob};
use crate::thermal::HeaterId;
use heapless::Deque;

/// Boundaries remembered (the planner holds few marks at once; older ones have executed).
pub const BOUNDARY_NOTES: usize = 8;

/// What the executive knows about a boundary in the host's stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BoundaryNote {
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

/// The executive's paused-job state.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct JobLink {
    notes: Deque<BoundaryNote, BOUNDARY_NOTES>,
    pub(super) request: Option<JobRequest>,
    /// A record was asked to be saved (so resuming or cancelling must clear it).
    pub(super) saved: bool,
    /// A driver with a store has booted the printer (`Printer::load_settings`): records are
    /// kept only then, so a driver without a store never waits for one.
    pub(super) attached: bool,
    /// The record found at power-up, until M1000 resumes it or it is discarded.
    pub(super) kept: Option<PausedJob>,
    /// M1000 is under way (its heater waits and homing are queued).
    pub(super) recovering: bool,
    /// M1000 continues a job from the start of this layer: the next job start (the host's
    /// `M110`, the SD file's start) numbers its layers from here (`layers.rs`).
    pub(super) continue_at: Option<u32>,
}

impl JobLink {
    pub(super) const fn new() -> Self {
        Self {
            notes: Deque::new(),
            request: None,
            saved: false,
            attached: false,
            kept: None,
            recovering: false,
            continue_at: None,
        }
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
                self.link.respond(crate::link::Response::Action(
                    crate::link::HostAction::Notification,
                    &t,
                ));
                // M1000 resumes it; M1000 C, a new job's first move, the next layer pause of a
                // new job or a cancel forgets it.
                self.job.saved = true;
                self.job.kept = Some(j);
            }
            Ok(None) => {}
            Err(e) => self.say(format_args!("power-cut resume record unusable: {e}")),
        }
    }

    /// Note a layer boundary produced by the host line numbered `line` (hook in `host.rs`).
    pub(super) fn note_boundary(
        &mut self,
        mark: &crate::motion::LayerMark,
        line: Option<u32>,
        modal: &MachineState,
    ) {
        let sd_offset = self.sd_line_offset();
        let n = &mut self.job.notes;
        if n.is_full() {
            let _ = n.pop_front();
        }
        let _ = n.push_back(BoundaryNote {
            layer: mark.layer,
            z_um: mark.z_um,
            line,
            sd_offset,
            modal: *modal,
        });
    }

    /// The record for the job parked now, if it stopped at a noted boundary of a numbered
    /// host stream or of the SD file printing.
    pub fn paused_job(&self) -> Option<PausedJob> {
        if !matches!(self.pause, Pause::Parked { .. })
            || self.pause.mode() != Some(PauseMode::Layer)
        {
            return None;
        }
        let held = *self.pause.held()?;
        // The barrier stood at the first queued mark: the boundary before that layer.
        let (_, mark) = self.planner.first_mark()?;
        let layer = mark.layer;
        let note = self.job.notes.iter().rev().find(|n| n.layer == layer)?;
        let source = match (note.sd_offset, note.line) {
            (Some(offset), _) => JobSource::Sd {
                path: heapless::String::try_from(self.sd_file_path()?).ok()?,
                offset,
                size: self.sd_progress()?.1,
            },
            (None, Some(line)) => JobSource::Host { line },
            (None, None) => return None,
        };
        let spm = |a: Axis| self.cfg.axis(a).steps_per_mm;
        let z_um = note.z_um.unwrap_or_else(|| {
            let z = held.pos[Axis::Z.index()] as f32 / spm(Axis::Z) * 1000.0;
            libm::roundf(z) as i32
        });
        Some(PausedJob {
            source,
            layer,
            boundary_z_um: z_um,
            boundary_steps: held.pos,
            park_steps: self.stepgen.position(),
            modal: note.modal.modal(),
            retract_mm: held.retracted_steps as f32 / spm(Axis::E),
            hotend_c: self.thermal.target_c(HeaterId::Hotend),
            bed_c: self.thermal.target_c(HeaterId::Bed),
            fan_pwm: self.fan_pwm,
        })
    }

    /// A pause has parked (hook in `pause.rs`): keep the job's record for a power-cut resume.
    pub(super) fn on_parked(&mut self) {
        if self.pause.mode() != Some(PauseMode::Layer) || !self.job.attached {
            return;
        }
        match self.paused_job() {
            Some(j) => {
                // Announced once it is in flash (`job_saved`).
                self.job.request = Some(JobRequest::Save(j));
                self.job.saved = true;
            }
            None => self.say(format_args!(
                "power-cut resume: not kept (no numbered host line or SD file at this boundary)"
            )),
        }
    }

    /// The driver's store has written `j` (or failed to): say which (`service_store`). Only
    /// a record in flash is announced as kept.
    pub(super) fn job_saved(
        &mut self,
        j: &PausedJob,
        saved: Result<crate::storage::Saved, crate::storage::StoreError>,
    ) {
        let mut t = PlaceText::new();
        let _ = match saved {
            Ok(how) => core::fmt::Write::write_fmt(
                &mut t,
                format_args!(
                    "power-cut resume: keeping job at layer {}, {}{}",
                    j.layer,
                    Where(&j.source),
                    how.note()
                ),
            ),
            Err(e) => core::fmt::Write::write_fmt(
                &mut t,
                format_args!("power-cut resume: job at layer {} not kept: {e}", j.layer),
            ),
        };
        self.link.respond(crate::link::Response::Echo(&t));
    }

    /// The job continues or ends (resume, cancel; hook in `pause.rs`): forget its record.
    pub(super) fn on_job_continues(&mut self) {
        if core::mem::take(&mut self.job.saved) {
            self.job.request = Some(JobRequest::Clear);
        }
    }

    /// The head waits at the park position until the record is cleared (hook in `mod.rs`):
    /// a power cut after the return started must not offer to resume a job that moved on.
    pub(super) fn job_clear_waits(&self) -> bool {
        matches!(self.pause, Pause::Returning { .. }) && self.job.request == Some(JobRequest::Clear)
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
