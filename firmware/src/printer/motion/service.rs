//! The service lane: the pause and resume moves (retract, lift, park, return, un-retract) and
//! manual moves while paused. They are planned one at a time, from standstill to standstill,
//! outside the planner ring, so they can never overwrite or reorder held job blocks.

use crate::config::MachineConfig;
use crate::motion::{StepPos, AXES};
use crate::planner::{kinematics, Block, BlockKind, PlannedBlock};

/// Service moves that can wait at once (retract, lift, park + manual moves).
pub const SERVICE_CAPACITY: usize = 8;

/// A move of the service lane: an absolute target in steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServiceMove {
    /// Absolute target, steps.
    pub target: StepPos,
    /// Speed, mm/s (limited per axis).
    pub feed_mm_s: f32,
}

/// The block for a service move from `from` (standstill to standstill); `None` without steps.
pub fn block(cfg: &MachineConfig, from: StepPos, m: ServiceMove) -> Option<PlannedBlock> {
    let mut delta = [0i32; AXES];
    for (i, d) in delta.iter_mut().enumerate() {
        *d = m.target[i].wrapping_sub(from[i]);
    }
    let kin = kinematics(cfg, &delta, m.feed_mm_s)?;
    let v2 = kin.nominal_mm_s * kin.nominal_mm_s;
    Some(PlannedBlock {
        block: Block {
            id: 0,
            seq: u32::MAX,
            seg: 0,
            segs: 1,
            kind: BlockKind::Service,
            delta,
            len_mm: kin.len_mm,
            accel_mm_s2: kin.accel_mm_s2,
            nominal_v2: v2,
            base_v2: v2,
            fast_v2: v2,
            junction_v2: 0.0,
            entry_max_v2: 0.0,
            entry_v2: 0.0,
        },
        entry_v2: 0.0,
        exit_v2: 0.0,
    })
}
