//! The job's layers in the executive: one numbering for every report (docs/frontend.md,
//! "Numbering"). Layer n is the n-th layer the printer prints in the job, from 1 — the number
//! the slicers' previews show — whatever the source of the marks; the count restarts when a
//! job starts: the host resets its line numbers (`M110`, sent by OctoPrint and printcore at
//! every print), an SD file starts printing, or something extrudes after a job's end code (the
//! detector sees that by itself). `M27`, `M761 L<n>`, the pause's `echo:` messages and the
//! power-cut record all name this number.

use super::Printer;

impl Printer {
    /// A job starts here in the host's stream (the line after an `M110`) or the card's (an SD
    /// file starts): the layer count restarts, from the kept layer when M1000 continues a job
    /// after a power cut.
    pub(super) fn job_start(&mut self) {
        // Nothing of an earlier job still to print: M27 has no layer until this job's first
        // mark runs.
        let ended = self.motion.first_mark().is_none() && !self.intake.marks_queued();
        let first = self.job.start(ended);
        self.intake.restart_layers(first);
    }

    /// M1000 continues a kept job from the start of layer `layer`: the job start that follows
    /// (the host's `M110`, or the SD file's start) numbers from there.
    pub(super) fn continue_job_at(&mut self, layer: u32) {
        self.job.continue_at(layer);
        self.intake.restart_layers(layer);
    }
}
