//! What a part of the executive is handed when it acts on the others' behalf (as smoltcp
//! hands its sockets a context): the clock, the configuration, the host side to answer on,
//! the record, and the motion and heat parts the pause drives. Built by the [`super::Printer`]
//! from its own parts for one call; the parts it lends stay the owners of their state.

use super::heat::Heat;
use super::host::Host;
use super::motion::Motion;
use super::records::Records;
use super::types::Record;
use crate::config::MachineConfig;

/// One call's context (see the module documentation).
pub(super) struct Cx<'a> {
    /// The executive's clock, µs.
    pub(super) now_us: u64,
    /// The machine's configuration.
    pub(super) cfg: &'a MachineConfig,
    /// Answers and notices.
    pub(super) host: &'a mut Host,
    /// The execution record.
    pub(super) records: &'a mut Records,
    /// Planner, step generator, service lane.
    pub(super) motion: &'a mut Motion,
    /// Heaters and fan.
    pub(super) heat: &'a mut Heat,
}

impl Cx<'_> {
    /// The clock, ns.
    pub(super) fn now_ns(&self) -> u64 {
        self.now_us.saturating_mul(1000)
    }

    /// Now on the motion timeline: the clock, or the last step when motion runs ahead of it.
    pub(super) fn t_us(&self) -> u64 {
        self.now_us.max(self.motion.last_step_us())
    }

    /// Keep an execution record.
    pub(super) fn record(&mut self, r: Record) {
        self.records.push(r);
    }
}
