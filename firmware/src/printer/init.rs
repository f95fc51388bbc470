//! Building a [`Printer`]: [`Printer::with_policy`] returns one; [`Printer::init_in_place`]
//! builds it directly in caller-provided memory (the board's `static`), because Rust has no
//! placement construction: `static.write(Printer::new(..))` builds the 35 KiB value on the
//! stack first and copies it (the SKR 2 image's start-up frame was 72 KiB, over half its RAM).
//! Here each part is written through a raw pointer into the slot; the parts' values are small
//! or `const` (the big rings are `heapless::Deque::new()`, uninitialised storage), and the
//! intake, which is neither, writes its own fields in place, so nothing large passes through
//! the stack.
//!
//! The one list of parts is [`Printer::init_in_place`]; [`fields_listed`] destructures a
//! `Printer` exhaustively, so adding a part without writing it here fails to compile.

use super::*;
use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

impl Printer {
    /// A printer with a policy (use [`Policy::FIFO`] to model conventional firmware).
    pub fn with_policy(cfg: MachineConfig, policy: Policy) -> Self {
        let mut slot = MaybeUninit::uninit();
        Self::init_in_place(&mut slot, cfg, policy);
        // SAFETY: `init_in_place` wrote every field of the slot.
        unsafe { slot.assume_init() }
    }

    /// Builds in `slot` the printer [`Printer::with_policy`] returns, without a `Printer`
    /// value on the stack; returns it. Whatever `slot` held is overwritten, not dropped.
    pub fn init_in_place(
        slot: &mut MaybeUninit<Printer>,
        cfg: MachineConfig,
        policy: Policy,
    ) -> &mut Printer {
        let p = slot.as_mut_ptr();
        // SAFETY: `p` points to memory valid for writes of a `Printer` (the slot); each field
        // is written exactly once, through `addr_of_mut!` (no reference to uninitialised
        // memory is made), and every field is written (checked by `fields_listed`) before the
        // slot is used as a `Printer`.
        unsafe {
            addr_of_mut!((*p).policy).write(policy);
            addr_of_mut!((*p).now_us).write(0);
            addr_of_mut!((*p).host).write(Host::new());
            Intake::init_in_place(addr_of_mut!((*p).intake), &cfg);
            addr_of_mut!((*p).motion).write(Motion::new());
            addr_of_mut!((*p).pause).write(PauseCtl::new());
            addr_of_mut!((*p).heat).write(Heat::new());
            addr_of_mut!((*p).records).write(Records::new());
            addr_of_mut!((*p).settings).write(settings::SettingsLink::new(cfg));
            addr_of_mut!((*p).job).write(job::JobLink::new());
            addr_of_mut!((*p).sd).write(sd::SdLink::new());
            addr_of_mut!((*p).board).write(board::BoardLink::new());
            let me = &mut *p;
            me.set_policy(policy);
            me.set_factory_settings();
            me
        }
    }
}

/// Names every field of [`Printer`] (never called): a field added to the struct and not to
/// this pattern fails to compile, a reminder to write it in [`Printer::init_in_place`].
#[allow(dead_code)]
fn fields_listed(p: &Printer) {
    let Printer {
        policy: _,
        now_us: _,
        host: _,
        intake: _,
        motion: _,
        pause: _,
        heat: _,
        records: _,
        settings: _,
        job: _,
        sd: _,
        board: _,
    } = p;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In place or by value, the same printer: it answers the same way to the same lines.
    #[test]
    fn in_place_equals_by_value() {
        let mut slot = Box::new(MaybeUninit::<Printer>::uninit());
        // Garbage in the slot first: nothing of it may survive.
        unsafe {
            core::ptr::write_bytes(slot.as_mut_ptr().cast::<u8>(), 0xA5, size_of::<Printer>())
        };
        let a = Printer::init_in_place(&mut slot, MachineConfig::ENDER3, Policy::FIRMWARE);
        let mut b = Printer::new(MachineConfig::ENDER3);
        let script = b"M115\nG28\nG1 X10 Y10 F3000\nM114\nM503\nM400\nM114\n";
        let mut out = [std::string::String::new(), std::string::String::new()];
        for (i, p) in [a, &mut b].into_iter().enumerate() {
            assert_eq!(p.receive(script, 0), script.len());
            for t in 0..3_000u64 {
                p.poll(t * 1000);
                while p.next_step_ns().is_some_and(|ns| ns <= t * 1_000_000) {
                    let _ = p.next_step();
                }
            }
            let _ = p.write_output(&mut out[i]);
        }
        assert!(
            out[0].contains("FIRMWARE_NAME") && out[0].contains("X:10.00"),
            "{}",
            out[0]
        );
        assert_eq!(out[0], out[1]);
        assert_eq!(a_status(&slot), b.status().position);
    }

    fn a_status(slot: &MaybeUninit<Printer>) -> crate::motion::StepPos {
        // SAFETY: initialised above.
        unsafe { slot.assume_init_ref() }.status().position
    }
}
